"""What the benchmarks time: the full time step of sparsekin and of two baselines.

A `Stepper` runs the time loop of `sparsekin.solve_kinematics` (`KinematicStepper`: Taylor predictor,
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
  refactorization's fill-in is heavy (`MAX_REFACTOR_FILL`, meshes), the refactorization
  (METIS-ordered when pymetis is installed and the model large) reused across samples by
  `ReusingSolver` (GMRES preconditioned by the held factorization): path ``"reuse"``.
  On a large mesh (issue 29), `DissectionSolver` instead, always reused across samples.
* ``sparsekin-refactor`` — ``"auto"`` without `DissectionSolver`: what meshes ran before
  issue 29 (the METIS-ordered refactorization, reused), the baseline of the mesh runs.
* ``superlu`` — the same with a fresh SuperLU factorization (COLAMD, through the CSC
  view) at every Newton iteration, plain Newton: ``linear_solver="superlu"``.
* ``superlu-metis`` — on meshes (issue 29): SuperLU in METIS's order
  (`SuperLUSolver(ordering="metis")`), chord Newton, its factorization always reused across
  samples by `ReusingSolver`: on the lattice a first sample 3–3.5 times as fast as
  ``sparsekin``'s, steps within about 15 % either way in runs under load, not shown to be
  no slower (docs/design-notes.md, "Sparse LU on meshes").
* ``supernodal`` — on meshes (issue 29): `SupernodalSolver`, the multifrontal LU in numba
  kernels in the same dissection, chord Newton, reused across samples like ``superlu-metis``.
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

from sparsekin.engine.assembly import Assembler
from sparsekin.engine.discretization import discretize
from sparsekin.engine.krylov import ReusingSolver
from sparsekin.engine.linalg import SuperLUSolver
from sparsekin.engine.supernodal import SupernodalSolver
from sparsekin.model.mechanism import Mechanism
from sparsekin.solve.policy import Thresholds, plan_linear_solver
from sparsekin.solve.stepper import KinematicStepper

__all__ = ["PHASES", "Stepper", "DenseBaseline", "RebuildBaseline", "LINEAR_SOLVERS", "CHORD", "REUSED"]

#: The phases a time step is split into.
PHASES = ("assembly", "factorization", "solves")


class DenseBaseline:
    """The homework method: a dense Jacobian and ``numpy.linalg.solve`` for each system."""

    name = "dense"

    def __init__(self, pattern) -> None:
        self.n_factorizations = 0
        self.n_refactorizations = 0
        self.n_solves = 0
        self._dense = np.zeros((pattern.n_equations, pattern.n_coordinates))

    def factor(self, jacobian) -> None:
        self.n_factorizations += 1
        self._dense[...] = jacobian.toarray()

    def solve(self, rhs: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        self.n_solves += 1
        solution = np.linalg.solve(self._dense, rhs)
        if out is None:
            return solution
        out[...] = solution
        return out


class RebuildBaseline:
    """The straightforward sparse code: COO → CSR at every iteration, `spsolve` per system."""

    name = "coo_spsolve"

    def __init__(self, pattern) -> None:
        self.n_factorizations = 0
        self.n_refactorizations = 0
        self.n_solves = 0
        self._rows = np.repeat(np.arange(pattern.n_equations), np.diff(pattern.indptr))
        self._columns = pattern.indices
        self._shape = (pattern.n_equations, pattern.n_coordinates)
        self._matrix = None

    def factor(self, jacobian) -> None:
        self.n_factorizations += 1
        triplets = (jacobian.data.copy(), (self._rows, self._columns))
        self._matrix = coo_array(triplets, shape=self._shape).tocsr()

    def solve(self, rhs: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        self.n_solves += 1
        solution = spsolve(self._matrix, rhs)
        if out is None:
            return solution
        out[...] = solution
        return out


#: ``linear_solver="auto"``'s thresholds with the compiled loop left out: the plan of a
#: model above `COMPILED_MAX_COORDINATES`, for every size.
ABOVE_COMPILED = Thresholds(compiled_max_coordinates=0)


#: ``"auto"``'s thresholds above the compiled size without `DissectionSolver`.
BEFORE_DISSECTION = Thresholds(compiled_max_coordinates=0, min_dissection_coordinates=2**62)
#: The paths that follow ``"auto"``'s plan, with their thresholds.
PLANNED = {"sparsekin": ABOVE_COMPILED, "sparsekin-refactor": BEFORE_DISSECTION}


def sparsekin_plan(model, path: str = "sparsekin"):
    """What ``"auto"`` plans for `model` on `path` (a key of `PLANNED`, `plan_linear_solver`)."""
    return plan_linear_solver(model, "auto", PLANNED[path])


#: Linear solvers by path name: each is built from the mechanism's arrays (`discretize`).
LINEAR_SOLVERS = {
    "sparsekin": lambda model: sparsekin_plan(model).make_solver(),
    "sparsekin-refactor": lambda model: sparsekin_plan(model, "sparsekin-refactor").make_solver(),
    # meshes (issue 29): SuperLU in METIS's order, reused across samples like "sparsekin"'s
    "superlu-metis": lambda model: SuperLUSolver(ordering="metis"),
    # meshes (issue 29): the supernodal LU in the dissection's order, reused like "superlu-metis"
    "supernodal": lambda model: SupernodalSolver(sparsekin_plan(model).points),
    "superlu": lambda model: SuperLUSolver(),
    "dense": lambda model: DenseBaseline(model.constraints),
    "coo_spsolve": lambda model: RebuildBaseline(model.constraints),
}
#: The paths whose Newton iteration is chord Newton (the others run plain Newton).
CHORD = frozenset({"sparsekin", "sparsekin-refactor", "superlu-metis", "supernodal"})
#: The paths that always reuse their factorization across samples (`ReusingSolver`).
REUSED = frozenset({"superlu-metis", "supernodal"})


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

    A `sparsekin.solve.stepper.KinematicStepper` whose assembler and linear solver are wrapped
    in timers.  The ``sparsekin`` path follows ``linear_solver="auto"``'s rule above
    `COMPILED_MAX_COORDINATES`: a refactorization, reused across samples when its fill-in
    is heavy.

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
        model = discretize(mechanism)
        self.pattern = pattern = model.constraints
        self.step = step
        self.seconds = dict.fromkeys(PHASES, 0.0)
        assembler = _Timed(
            Assembler(model),
            self.seconds,
            {
                "set_time": "assembly",
                "fill_residual_jacobian": "assembly",
                "fill_acceleration_rhs": "assembly",
                "fill_in_order": "factorization",
            },  # fmt: skip
        )
        solver_phases = {
            "factor": "factorization", "factor_ordered": "factorization", "solve": "solves", "solve_held": "solves",
        }  # fmt: skip
        solver = LINEAR_SOLVERS[linear_solver](model)
        self.stepper = KinematicStepper(
            model, linear_solver=_Timed(solver, self.seconds, solver_phases), chord=linear_solver in CHORD,
            assembler=assembler,
        )  # fmt: skip
        self.stepper.start(0.0)
        self.path = linear_solver
        if linear_solver in REUSED or (
            linear_solver in PLANNED and sparsekin_plan(model, linear_solver).reuses(solver, pattern.nnz)
        ):
            # as `start` does under "auto"; a refactorization GMRES finds necessary inside
            # a solve is timed with the solves
            # (`start` again solves from the drawing: the first Jacobian is refactored)
            self.stepper.use_linear_solver(_Timed(ReusingSolver(solver), self.seconds, solver_phases))
            self.stepper.start(0.0)
            self.path = "reuse"
        self._start = (
            self.stepper.time, self.stepper.coordinates.copy(), self.stepper.velocities.copy(),
            self.stepper.accelerations.copy(),
        )  # fmt: skip
        self.reset()

    @property
    def coordinates(self):
        return self.stepper.coordinates

    def reset(self) -> None:
        """Back to the solved first sample, with the timers and counters at zero."""
        t, q, qd, qdd = self._start
        self.stepper.start_from(t, q, qd, qdd, first=(t, q))
        self.time = t
        self.newton_iterations = 0
        for phase in PHASES:
            self.seconds[phase] = 0.0

    def run(self, n_steps: int) -> None:
        """`n_steps` full time steps: positions, velocities and accelerations, each checked by
        the branch guard of the stepper (a step that jumps branch is halved, and counted)."""
        for _ in range(n_steps):
            self.time += self.step
            self.newton_iterations += self.stepper.advance(self.time)
        if self.stepper.n_subdivisions:
            raise RuntimeError(f"the benchmark's steps were halved {self.stepper.n_subdivisions} times; shorten them")
