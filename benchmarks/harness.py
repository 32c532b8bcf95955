"""What the benchmarks time: the full time step of sparsekin and of two baselines.

A `Stepper` runs the time loop of `sparsekin.solve_kinematics` (Taylor predictor,
Newton–Raphson on the positions, the velocity and acceleration solves, the branch guard)
with a given linear solver, and records where the time goes:

* ``assembly`` — driver laws, residual and Jacobian refills, gamma refills;
* ``factorization`` — whatever the linear solver does to a new Jacobian;
* ``solves`` — the solves with it.

The paths compared, measured in the same run:

* ``sparsekin`` — what `solve_kinematics` runs above `COMPILED_MAX_COORDINATES`: the CSR
  pattern is fixed and refilled in place by the numba kernels, `RefactorSolver`
  refactors it numerically on the L and U patterns fixed by a first SuperLU
  factorization, and chord Newton reuses the previous sample's factorization; when the
  refactorization's fill-in is heavy (`MAX_REFACTOR_FILL`, meshes), SuperLU with chord.
* ``superlu`` — the same with a fresh SuperLU factorization (COLAMD, through the CSC
  view) at every Newton iteration, plain Newton: ``linear_solver="superlu"``.
* `DenseBaseline` — the "homework" method: the Jacobian as a dense array and
  ``numpy.linalg.solve`` for every linear system.
* `RebuildBaseline` — the straightforward sparse code: the Jacobian rebuilt from (row,
  column, value) triplets through COO → CSR at every Newton iteration, and
  ``scipy.sparse.linalg.spsolve`` for every linear system.

Both baselines reuse sparsekin's kernels to compute the values, so what they add is the
cost of their linear algebra and matrix construction, nothing else.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.linalg import spsolve

from sparsekin.assembly import Assembler
from sparsekin.linalg import RefactorSolver, SuperLUSolver
from sparsekin.model import Mechanism
from sparsekin.pattern import build_pattern
from sparsekin.solvers import (
    BRANCH_DEFECT_RATIO,
    BRANCH_MIN_CORRECTION,
    BRANCH_MIN_DEFECT,
    DEFAULT_TOLERANCE,
    NEWTON_MAXITER,
    _Factorizer,
    _fill_is_heavy,
    _jumped,
    _solve_positions,
)

__all__ = ["PHASES", "Stepper", "DenseBaseline", "RebuildBaseline", "LINEAR_SOLVERS", "CHORD"]

#: The phases a time step is split into.
PHASES = ("assembly", "factorization", "solves")


class DenseBaseline:
    """The homework method: a dense Jacobian and ``numpy.linalg.solve`` for each system."""

    name = "dense"

    def __init__(self, pattern) -> None:
        self.n_factorizations = 0
        self.n_solves = 0
        self._dense = np.zeros((pattern.n_equations, pattern.n_coordinates))

    def factor(self, jacobian) -> None:
        self.n_factorizations += 1
        self._dense[...] = jacobian.toarray()

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        self.n_solves += 1
        return np.linalg.solve(self._dense, rhs)


class RebuildBaseline:
    """The straightforward sparse code: COO → CSR at every iteration, `spsolve` per system."""

    name = "coo_spsolve"

    def __init__(self, pattern) -> None:
        self.n_factorizations = 0
        self.n_solves = 0
        self._rows = np.repeat(np.arange(pattern.n_equations), np.diff(pattern.indptr))
        self._columns = pattern.indices
        self._shape = (pattern.n_equations, pattern.n_coordinates)
        self._matrix = None

    def factor(self, jacobian) -> None:
        self.n_factorizations += 1
        triplets = (jacobian.data.copy(), (self._rows, self._columns))
        self._matrix = coo_array(triplets, shape=self._shape).tocsr()

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        self.n_solves += 1
        return spsolve(self._matrix, rhs)


#: Linear solvers by path name: each is built from the mechanism's pattern.
LINEAR_SOLVERS = {
    "sparsekin": lambda pattern: RefactorSolver(),
    "superlu": lambda pattern: SuperLUSolver(),
    "dense": DenseBaseline,
    "coo_spsolve": RebuildBaseline,
}
#: The paths whose Newton iteration is chord Newton (the others run plain Newton).
CHORD = frozenset({"sparsekin"})


class _Timed:
    """Forwards calls to `target`, adding the time each named method takes to a phase."""

    def __init__(self, target, seconds: dict[str, float], phase_of: dict[str, str]) -> None:
        self._target = target
        self._seconds = seconds
        self._phase_of = phase_of

    def __getattr__(self, name):
        attribute = getattr(self._target, name)
        phase = self._phase_of.get(name)
        if phase is None:
            return attribute
        seconds = self._seconds

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return attribute(*args, **kwargs)
            finally:
                seconds[phase] += time.perf_counter() - start

        return timed


class Stepper:
    """The time loop of `solve_kinematics`, one step at a time, with phase timers.

    Parameters
    ----------
    mechanism : Mechanism
    linear_solver : str
        A key of `LINEAR_SOLVERS`.
    step : float
        Time step, s.

    The first sample (t = 0, Newton from the model's initial configuration) is solved on
    construction, outside every timer; `reset` returns to it.
    """

    def __init__(self, mechanism: Mechanism, linear_solver: str, step: float) -> None:
        self.pattern = pattern = build_pattern(mechanism)
        self.step = step
        self.seconds = dict.fromkeys(PHASES, 0.0)
        self.assembler = _Timed(
            Assembler(mechanism, pattern),
            self.seconds,
            {
                "set_time": "assembly",
                "fill_residual_jacobian": "assembly",
                "fill_acceleration_rhs": "assembly",
                "fill_in_order": "factorization",
            },  # fmt: skip
        )
        self.solver = _Timed(
            LINEAR_SOLVERS[linear_solver](pattern),
            self.seconds,
            {"factor": "factorization", "factor_ordered": "factorization", "solve": "solves"},
        )
        self.factorizer = _Factorizer(self.assembler, self.solver)
        self.chord = linear_solver in CHORD
        self.weights = np.where(pattern.row_is_angle, 1.0, 1.0 / pattern.length_scale)
        self.coordinate_weights = np.full(pattern.n_coordinates, 1.0 / pattern.length_scale)
        self.coordinate_weights[2::3] = 1.0
        self.coordinates = pattern.initial_coordinates.copy()
        self.velocities = np.zeros(pattern.n_coordinates)
        self.accelerations = np.zeros(pattern.n_coordinates)
        self.newton_iterations = 0
        self.time = 0.0
        self._solve_sample(0.0, self.coordinates)
        if linear_solver == "sparsekin" and _fill_is_heavy(self.solver._target, pattern):
            # as solve_kinematics(linear_solver="auto") does: SuperLU with chord Newton
            self.assembler.fill_in_order(None)
            self.solver = _Timed(SuperLUSolver(), self.seconds, self.solver._phase_of)
            self.factorizer = _Factorizer(self.assembler, self.solver)
            self.coordinates[:] = pattern.initial_coordinates
            self._solve_sample(0.0, self.coordinates)
        self.path = (
            "superlu-chord"
            if isinstance(self.solver._target, SuperLUSolver) and self.chord
            else linear_solver
        )
        self._start = (self.coordinates.copy(), self.velocities.copy(), self.accelerations.copy())
        self.reset()

    def reset(self) -> None:
        """Back to the solved first sample, with the timers and counters at zero."""
        self.coordinates[:], self.velocities[:], self.accelerations[:] = self._start
        self.time = 0.0
        self.newton_iterations = 0
        for phase in PHASES:
            self.seconds[phase] = 0.0

    def run(self, n_steps: int) -> None:
        """`n_steps` full time steps: positions, velocities and accelerations, each checked
        by the branch guard of `solve_kinematics`."""
        h = self.step
        for _ in range(n_steps):
            self.time += h
            previous = (self.coordinates, self.velocities, self.accelerations)
            q = np.multiply(self.velocities, h)  # the Taylor predictor, as solve_kinematics makes it
            q += self.coordinates
            q += (0.5 * h * h) * self.accelerations
            predicted = q.copy()
            self._solve_sample(self.time, q, predicted)
            self.coordinates = q
            if _jumped(
                h, *previous, q, self.velocities, self.accelerations, predicted, self.coordinate_weights,
                BRANCH_DEFECT_RATIO, BRANCH_MIN_DEFECT, BRANCH_MIN_CORRECTION,
            ):  # fmt: skip
                raise RuntimeError(f"the benchmark's step at t = {self.time:g} s jumped branch; shorten it")

    def _solve_sample(self, t: float, q: np.ndarray, predicted: np.ndarray | None = None) -> None:
        assembler, solver = self.assembler, self.solver
        assembler.set_time(t)
        self.newton_iterations += _solve_positions(
            assembler,
            solver,
            q,
            self.weights,
            DEFAULT_TOLERANCE,
            NEWTON_MAXITER,
            self.chord and t > 0.0,
            self.factorizer,
            predicted,
        )
        self.velocities = solver.solve(assembler.velocity_rhs)
        assembler.fill_acceleration_rhs(q, self.velocities)
        self.accelerations = solver.solve(assembler.acceleration_rhs)
