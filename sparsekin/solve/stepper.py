"""The time loop, one sample at a time: `KinematicStepper`.

From the solved sample at time t0 to the next at t1 = t0 + h:

1. the Taylor predictor ``q0 + h qd0 + h²/2 qdd0``;
2. Newton–Raphson on the positions (`sparsekin.engine.newton`; chord Newton on the fast paths);
3. the velocities ``Phi_q qd = -Phi_t`` and accelerations ``Phi_q qdd = gamma`` with the
   factorization at the converged position;
4. the branch guard: the solved step must follow the corrected trapezoidal rule
   (`sparsekin.solve.branch_guard`), or it may have jumped to another assembly branch.

A step on which Newton fails, or which the guard rejects, is halved and its intermediate
samples are solved internally, without being returned (`sparsekin.solve.step_control`).
A step that still fails a million times shorter stops the analysis with the error
`sparsekin.analysis.failures.Diagnosis` writes (a lock-up is a `SingularConfigurationError`).

After each sample the stepper publishes a `Linearization` (`linearization`): what runs
after a sample (the forces) reads that, not the stepper.  It is a `Stepper` of
`sparsekin.solve.steppers`; `sparsekin.solve_kinematics` drives it over its sample times
through the run driver (`sparsekin.solve.run`), and the benchmarks drive one step by step
with timed linear solvers and assemblers.

>>> import numpy as np
>>> from sparsekin.testset import task5
>>> stepper = KinematicStepper(task5(), linear_solver="refactor")
>>> stepper.start(0.0)
0
>>> for t in (0.01, 0.02):
...     corrections = stepper.advance(t)
>>> round(float(stepper.time), 12), stepper.coordinates.shape
(0.02, (30,))
"""

from __future__ import annotations

import numpy as np

from ..analysis.failures import Diagnosis
from ..engine.assembly import Assembler
from ..engine.discretization import Discretization
from ..engine.linalg import SingularMatrix
from ..engine.linearization import Linearization
from ..engine.newton import DEFAULT_TOLERANCE, NEWTON_MAXITER, Factorizer, NoConvergence, solve_positions
from ..engine.ordering import hub_last_ordering, tiled_ordering
from ..engine.pattern import build_pattern
from ..engine.reduced import ReducedSystem, kept_equations
from ..errors import ConvergenceError, ModelError
from ..model.mechanism import Mechanism
from .branch_guard import guard_values, jumped
from .options import TOLERANCE_RANGE, SolveOptions
from .policy import (
    COMPILED_MAX_COORDINATES,
    LINEAR_SOLVERS,
    MAX_REFACTOR_FILL,
    MIN_METIS_COORDINATES,
    plan_linear_solver,
)
from .step_control import StepAbandoned, StepControl, StepRejected, march
from .steppers import StepperStats

__all__ = [
    "KinematicStepper",
    "LINEAR_SOLVERS",
    "COMPILED_MAX_COORDINATES",
    "MAX_REFACTOR_FILL",
    "MIN_METIS_COORDINATES",
    "TOLERANCE_RANGE",
]


class _BranchJump(StepRejected):
    """The solved step breaks the corrected trapezoidal rule: perhaps a jump to another branch."""


class KinematicStepper:
    """Solve a mechanism's motion sample after sample.

    Parameters
    ----------
    mechanism : Mechanism or Discretization
        A mechanism whose equations control every coordinate (redundant but consistent
        equations are left out with a `RedundantConstraintWarning`), or its arrays
        (`sparsekin.engine.discretization.discretize`).
    linear_solver : {"auto", "dense", "refactor", "superlu"} or object
        How the linear systems are solved (see `sparsekin.solve_kinematics`), or a
        linear solver object with ``factor(jacobian)``, ``solve(rhs, out=None, *,
        transposed=False)`` (``transposed=True`` solves with the transposed Jacobian, for
        the forces) and the counters ``n_factorizations``, ``n_refactorizations``,
        ``n_solves`` (`sparsekin.engine.linalg.LinearSolver`).
    tolerance : float
        Largest accepted residual: lengths relative to the model size, angles in rad.
    max_iterations : int
        Most Newton corrections at one time.
    chord : bool, optional
        Chord Newton after the first sample; default: on every path but ``"superlu"``.
    pattern : ConstraintPattern, optional
        ``build_pattern(mechanism)``, if already made (with a Mechanism).
    assembler : Assembler, optional
        The assembler to fill the equations with (for instance one whose calls are timed).
    forces : bool
        Whether the run computes forces from the stepper's factorizations (`linearization`);
        only the warning about redundant equations says more then.
    options : SolveOptions, optional
        The options, checked already (then `tolerance`, `max_iterations` and a
        `linear_solver` name are taken from it): thresholds and branch guard included.

    Attributes
    ----------
    time : float
        The time of the current sample, s (None before `start`).
    coordinates, velocities, accelerations : ndarray, shape (n_coordinates,)
        The current sample: q (m, rad) and its time derivatives.  Valid until the next
        `advance`, which reuses the arrays.
    path : str
        The linear-solver path: ``"dense"``, ``"refactor"``, ``"superlu"``, the name of a
        given solver, or ``"reuse"`` once ``"auto"`` found a refactorization at every
        sample too costly (`sparsekin.solve.policy.SolverPlan.reuses`) and reuses it
        across samples.
    n_subdivisions : int
        How many times a step was halved.
    redundant_rows : ndarray of int
        Equations left out as redundant.
    """

    def __init__(
        self,
        mechanism: Mechanism | Discretization,
        *,
        linear_solver="auto",
        tolerance: float = DEFAULT_TOLERANCE,
        max_iterations: int = NEWTON_MAXITER,
        chord: bool | None = None,
        pattern=None,
        assembler: Assembler | None = None,
        forces: bool = False,
        options: SolveOptions | None = None,
    ) -> None:
        if isinstance(mechanism, Discretization):
            discretization = mechanism
        elif isinstance(mechanism, Mechanism):
            discretization = Discretization(mechanism, build_pattern(mechanism) if pattern is None else pattern)
        else:
            raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
        if options is None:
            name = linear_solver if isinstance(linear_solver, str) else "auto"
            options = SolveOptions(tolerance, max_iterations, name)
        self.options = options
        self.tolerance, self.max_iterations = options.tolerance, options.max_iterations
        self.discretization = discretization
        self.mechanism = mechanism = discretization.mechanism
        self.pattern = pattern = discretization.constraints
        if pattern.n_equations == 0 and pattern.n_coordinates:
            bodies = ", ".join(mechanism.body_names[:4]) + (", …" if mechanism.n_bodies > 4 else "")
            raise ModelError(
                f"{pattern.n_coordinates} coordinates but no equation: every body ({bodies}) moves freely; "
                "expected joints and drivers"
            )
        self.assembler = Assembler(discretization) if assembler is None else assembler
        self.diagnosis = Diagnosis(discretization)
        if isinstance(linear_solver, str):
            self.plan = plan_linear_solver(discretization, options.linear_solver, options.thresholds)
            self.chord = self.plan.chord if chord is None else bool(chord)
            linear_solver = self.plan.make_solver()
        else:
            self.plan = None
            self.chord = True if chord is None else bool(chord)
        self.linear_solver = linear_solver
        self.path = getattr(linear_solver, "name", type(linear_solver).__name__)
        self.system = self.assembler  # or a ReducedSystem without the redundant equations
        self.factorizer = Factorizer(self.system, linear_solver)
        self.redundant_rows = np.zeros(0, dtype=np.int64)
        self._retired = np.zeros(3, dtype=np.int64)  # counts of linear solvers left during the run
        self._factored = False  # whether the linear solver holds a factorization to chord with
        n = pattern.n_coordinates
        self.coordinates, self.velocities, self.accelerations = np.zeros(n), np.zeros(n), np.zeros(n)
        self._next = (np.zeros(n), np.zeros(n), np.zeros(n))
        self._predicted = np.zeros(n)  # the predictor of the current step, for the branch guard
        self._correction = np.zeros(n)  # Newton's corrections
        self._coordinate_weights = pattern.coordinate_weights
        self._guard = guard_values(options.guard)
        self._first: tuple[float, np.ndarray] | None = None  # (t, q) of the first sample
        self.time: float | None = None
        self.n_subdivisions = 0
        self.forces = bool(forces)

    # ------------------------------------------------------------------ counters
    @property
    def n_factorizations(self) -> int:
        return self.linear_solver.n_factorizations + int(self._retired[0])

    @property
    def n_refactorizations(self) -> int:
        return self.linear_solver.n_refactorizations + int(self._retired[1])

    @property
    def n_solves(self) -> int:
        return self.linear_solver.n_solves + int(self._retired[2])

    def stats(self) -> StepperStats:
        """The counts of the run so far, the path and the equations left out."""
        return StepperStats(self.n_factorizations, self.n_solves, self.n_refactorizations, self.n_subdivisions,
                            self.path, tuple(self.diagnosis.label(r) for r in self.redundant_rows))  # fmt: skip

    def linearization(self) -> Linearization:
        """The system at the current sample (valid until the next step): what the forces read."""
        assembler, system = self.assembler, self.system
        return Linearization(
            self.time, self.coordinates, self.velocities, self.accelerations, assembler.filled_motion(),
            assembler.values, assembler.csr_positions, lambda: assembler.jacobian, assembler.velocity_rhs,
            self.linear_solver, None if system is assembler else system.rows, self.redundant_rows,
        )  # fmt: skip

    # ------------------------------------------------------------------ stepping
    def start(self, t: float, coordinates: np.ndarray | None = None) -> int:
        """Solve the first sample at time `t` (s) from `coordinates` (default: the drawing).

        Returns
        -------
        int
            Newton corrections.

        Raises
        ------
        ModelError
            The equations are dependent there, free motions remain, or redundant
            equations contradict each other.
        ConvergenceError
            Newton cannot assemble the model at `t`.
        """
        t = float(t)
        drawn = self.pattern.initial_coordinates if coordinates is None else np.asarray(coordinates, dtype=float)
        if self.pattern.n_equations != self.pattern.n_coordinates:
            self._leave_out_redundant(t, drawn)
        q, velocity, acceleration = self._next
        q[:] = drawn
        self._suggest_ordering(t)
        self.system.set_time(t)
        try:
            corrections = self._solve_positions(q, chord=False)
            self._solve_rates(q, velocity, acceleration)
            if self.plan is not None and self.plan.reuses(self.linear_solver, self.pattern.nnz):
                # The refactorization goes on under a solver that reuses its factorization
                # across samples; it takes the Jacobian at the converged position (the
                # forces of this sample solve with it, the next sample's chord Newton
                # starts from it).
                self.use_linear_solver(self.plan.reusing(self.linear_solver), path="reuse")
                self.factorizer()
                self._factored = True
        except (NoConvergence, SingularMatrix) as failure:
            raise self.diagnosis.cannot_start(self.system, self.assembler, t, drawn, _reason(failure)) from None
        self._check_left_out(t, first=True)
        self._accept(t)
        self._first = (t, self.coordinates.copy())
        return corrections

    def start_from(self, t: float, coordinates, velocities, accelerations, first: tuple[float, np.ndarray]) -> None:
        """Take the sample at time `t`, solved elsewhere (by the compiled loop of a
        `sparsekin.solve.steppers.FallbackStepper`), as the current one; the next step
        starts with plain Newton.  `first` is ``(t, coordinates)`` of the run's first
        sample, the reference of the lock-up diagnosis."""
        self.coordinates[:], self.velocities[:], self.accelerations[:] = coordinates, velocities, accelerations
        self.time = float(t)
        self._first = (float(first[0]), np.array(first[1], dtype=float))
        self._factored = False

    def _suggest_ordering(self, t: float) -> None:
        """The refactorization's first pivot order (`sparsekin.engine.ordering`): a hub's
        coordinates eliminated last when many bodies ride on one; for a chain of many
        repeated units, tiled from a short chain rather than SuperLU's on the whole chain."""
        suggest = getattr(self.linear_solver, "suggest", None)  # a RefactorSolver's
        if suggest is None or self.system is not self.assembler:
            return
        ordering = hub_last_ordering(self.discretization, t)  # many bodies on one: the hub last (issue 27)
        if (ordering is None and self.mechanism.copies
                and self.pattern.n_coordinates >= self.options.thresholds.min_tiled_coordinates):  # fmt: skip
            ordering = tiled_ordering(self.discretization, t)
        if ordering is not None:
            suggest(*ordering)

    def advance(self, t: float) -> int:
        """Solve the sample at time `t` (s, after the current one) from the current sample.

        Returns
        -------
        int
            Newton corrections (over all sub-steps when the step was subdivided).

        Raises
        ------
        SingularConfigurationError, ConvergenceError
            The step failed on the shortest subdivision.
        ModelError
            The equations were dependent from the first sample on.
        """
        if self.time is None:
            raise RuntimeError("no sample yet: call `start` first.")
        t = float(t)
        current = (self.coordinates, self.velocities, self.accelerations)
        try:
            corrections = self._step(current, t - self.time, t, self._next, guarded=True)
        except StepRejected:
            corrections = self._subdivide(t)
        self._check_left_out(t)
        self._accept(t)
        return corrections

    # ------------------------------------------------------------------ internals
    def _step(self, state, h: float, t: float, out, guarded: bool) -> int:
        """One step of length `h` from `state` (q, qd, qdd) to time `t`, solved into `out`;
        raises `StepRejected` if Newton fails or (`guarded`) the branch guard rejects it."""
        q, velocity, acceleration = out
        np.multiply(state[1], h, out=q)  # the Taylor predictor, without a temporary
        q += state[0]
        np.multiply(state[2], 0.5 * h * h, out=self._predicted)
        q += self._predicted
        np.copyto(self._predicted, q)
        self.system.set_time(t)
        try:
            corrections = self._solve_positions(q)
            self._solve_rates(q, velocity, acceleration)
        except (NoConvergence, SingularMatrix) as failure:
            raise StepRejected(_reason(failure)) from None
        if guarded and jumped(h, *state, q, velocity, acceleration, self._predicted, self._coordinate_weights,
                              self._guard):  # fmt: skip
            raise _BranchJump("the step left the branch")
        return corrections

    def _accept(self, t: float) -> None:
        """The next sample, solved into `_next`, becomes the current one (the arrays swap)."""
        current = (self.coordinates, self.velocities, self.accelerations)
        self.coordinates, self.velocities, self.accelerations = self._next
        self._next = current
        self.time = t

    def _solve_positions(self, q: np.ndarray, chord: bool | None = None) -> int:
        """Newton from `q`, whose copy is in `_predicted` whenever chord Newton may run."""
        use_chord = (self.chord if chord is None else chord) and self._factored
        self._factored = False
        corrections = solve_positions(
            self.system, self.linear_solver, q, self.tolerance, self.max_iterations, use_chord, self.factorizer,
            self._predicted, self._correction,
        )  # fmt: skip
        self._factored = True
        return corrections

    def _solve_rates(self, q, velocity, acceleration) -> None:
        """Velocities and accelerations at the converged `q`, with the factorization there."""
        self.linear_solver.solve(self.system.velocity_rhs, out=velocity)
        self.system.fill_acceleration_rhs(q, velocity)
        self.linear_solver.solve(self.system.acceleration_rhs, out=acceleration)

    def _subdivide(self, end: float) -> int:
        """Solve the sample at `end` from the current one in shorter steps
        (`sparsekin.solve.step_control.march`); the result goes to `_next`.  Returns the
        corrections over all sub-steps."""
        state = [self.coordinates.copy(), self.velocities.copy(), self.accelerations.copy()]
        trial = [np.empty_like(state[0]) for _ in range(3)]

        def attempt(t_from: float, t_to: float, guarded: bool) -> int:
            corrections = self._step(state, t_to - t_from, t_to, trial, guarded)
            for k in range(3):
                state[k], trial[k] = trial[k], state[k]
            return corrections

        try:
            outcome = march(self.time, end, attempt, StepControl())
        except StepAbandoned as abandoned:
            self.n_subdivisions += abandoned.halvings
            raise self.diagnosis.stopped(
                self.system, self.assembler, self._first, (abandoned.t_from, state[0]), abandoned.t_to, abandoned.reason
            ) from None  # fmt: skip
        self.n_subdivisions += outcome.halvings
        for target, solved in zip(self._next, state):
            target[:] = solved
        return outcome.corrections

    def _leave_out_redundant(self, t: float, coordinates: np.ndarray) -> None:
        """More equations than coordinates: solve without the redundant ones."""
        self.redundant_rows = self.diagnosis.redundant_rows(
            self.assembler, t, coordinates, self.forces, tall_lu_from=self.options.thresholds.smallest_tall_lu
        )  # fmt: skip
        kept = kept_equations(self.pattern.n_equations, self.redundant_rows)
        self.system = ReducedSystem(self.assembler, kept)
        self.factorizer = Factorizer(self.system, self.linear_solver)
        factors = getattr(self.diagnosis.redundancy_analysis, "dependency_source", None)
        suggest = getattr(self.linear_solver, "suggest", None)
        if suggest is not None and hasattr(factors, "pivot_order"):  # the tall LU's pivots: no SuperLU
            suggest(*factors.pivot_order(kept))

    def _check_left_out(self, t: float, first: bool = False) -> None:
        """The redundant equations left out must still hold at the solved sample."""
        if not self.redundant_rows.size:
            return
        message = self.diagnosis.left_out_violated(self.assembler, self.redundant_rows, t)
        if not message:
            return
        if first:
            raise ModelError(message)
        raise ConvergenceError(message, time=t, driver_values=self.diagnosis.driver_values(self.assembler))

    def use_linear_solver(self, linear_solver, path: str | None = None) -> None:
        """Go on with another linear solver (its counts add to the stepper's).

        ``"auto"`` does this at the first sample when a refactorization's fill-in makes it
        costly at every sample (`sparsekin.solve.policy.SolverPlan.reuses`): `start` hands
        the Jacobian at the converged position to a `ReusingSolver` around the
        refactorization.  Called alone, it leaves the new solver without a factorization:
        the next sample runs plain Newton, then chord Newton again.
        """
        left = self.linear_solver
        self._retired += (left.n_factorizations, left.n_refactorizations, left.n_solves)
        self.linear_solver = linear_solver
        self.system.fill_in_order(None)  # the assembler's (through a reduced system's) CSR order
        self.factorizer = Factorizer(self.system, linear_solver)
        self._factored = False
        self.path = path or getattr(linear_solver, "name", type(linear_solver).__name__)


def _reason(failure: Exception) -> str:
    """Why a solve failed, in words."""
    return failure.reason if isinstance(failure, NoConvergence) else "the Jacobian is singular"
