"""The time loop, one sample at a time: `KinematicStepper`.

From the solved sample at time t0 to the next at t1 = t0 + h:

1. the Taylor predictor ``q0 + h qd0 + h²/2 qdd0``;
2. Newton–Raphson on the positions (`sparsekin.engine.newton`; chord Newton on the fast paths);
3. the velocities ``Phi_q qd = -Phi_t`` and accelerations ``Phi_q qdd = gamma`` with the
   factorization at the converged position;
4. the branch guard: the solved step must follow the corrected trapezoidal rule
   (`BRANCH_DEFECT_RATIO`), or it may have jumped to another assembly branch.

A step on which Newton fails, or which the guard rejects, is halved and its intermediate
samples are solved internally, without being returned.  A step that still fails a
million times shorter stops the analysis with the error `sparsekin.analysis.failures.Diagnosis`
writes (a lock-up is a `SingularConfigurationError`).

`sparsekin.solve_kinematics` drives a stepper over its sample times; the benchmarks drive
one step by step with timed linear solvers and assemblers.

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

import math

import numpy as np
from numba import njit

from .._jit import JIT
from ..analysis.failures import Diagnosis
from ..engine.assembly import Assembler
from ..engine.krylov import ReusingSolver
from ..engine.linalg import DenseSolver, RefactorSolver, SingularMatrix, SuperLUSolver
from ..engine.newton import DEFAULT_TOLERANCE, NEWTON_MAXITER, Factorizer, NoConvergence, solve_positions
from ..engine.ordering import MIN_TILED_COORDINATES, hub_last_ordering, metis_installed, tiled_ordering
from ..engine.pattern import ConstraintPattern, build_pattern
from ..engine.reduced import ReducedSystem
from ..errors import ConvergenceError, ModelError
from ..model.mechanism import Mechanism

__all__ = [
    "KinematicStepper",
    "LINEAR_SOLVERS",
    "COMPILED_MAX_COORDINATES",
    "MAX_REFACTOR_FILL",
    "MIN_METIS_COORDINATES",
    "TOLERANCE_RANGE",
    "fill_is_heavy",
]

#: Smallest and largest accepted `tolerance`: below about 4 eps the residual cannot be
#: reached in floating point; above 1 % of the model size a "solution" is not one.
TOLERANCE_RANGE = (4 * np.finfo(float).eps, 1e-2)
#: Branch guard.  Over a step h from sample 0 to sample 1 of a smooth motion,
#: ``q1 - q0 = h/2 (qd0 + qd1) - h²/12 (qdd1 - qdd0) + O(h^5)`` (the corrected trapezoidal
#: rule).  A solution that jumped to another assembly branch breaks this by a finite
#: amount, and Newton travelled a finite distance from the predictor to reach it.  The
#: step is halved when both happen: the defect of that rule exceeds `BRANCH_DEFECT_RATIO`
#: times the displacement (and `BRANCH_MIN_DEFECT`), and Newton's total correction exceeds
#: `BRANCH_MIN_CORRECTION` — distances are the largest coordinate, angles in rad and
#: lengths relative to the model size.  For a harmonic motion of angular frequency w the
#: defect ratio is about (h w)^4 / 720: a step must cover more than 1.5 rad of phase to
#: be halved without cause.  Near a dead centre, where the motion stops being smooth on
#: the scale of the step, Newton from the predictor moves little (Task 5 at 1 ms: 1.5e-3
#: rad at the last sample before it), whereas a jump moves by the distance between the
#: branches (0.13 rad for the four-bar of tests/test_branch_following.py).
BRANCH_DEFECT_RATIO = 0.01
BRANCH_MIN_DEFECT = 1e-8
BRANCH_MIN_CORRECTION = 5e-3
#: How many times a step is halved at most: for a suspect branch (then the result is
#: accepted) and for a failure of Newton (then the analysis stops).
BRANCH_MAX_HALVINGS = 8
FAILURE_MAX_HALVINGS = 20
#: The `linear_solver` names.
LINEAR_SOLVERS = ("auto", "superlu", "refactor", "dense")
#: ``linear_solver="auto"`` runs the compiled dense loop (`sparsekin.solve_kinematics`) or
#: the dense path up to this many coordinates and the refactorization path above: the
#: crossover measured on the test set (benchmarks/RESULTS.md, "Crossover").
COMPILED_MAX_COORDINATES = 120
#: ``linear_solver="auto"`` refactors at every sample while L and U hold at most this
#: many entries per entry of the Jacobian.  With more fill-in (meshes rather than chains)
#: a factorization costs tens of solves, and the run goes on reusing it across samples
#: (`sparsekin.engine.krylov.ReusingSolver`: GMRES preconditioned by the held
#: factorization, path ``"reuse"``); docs/design-notes.md gives the measured fill ratios.
MAX_REFACTOR_FILL = 8.0
#: ``linear_solver="auto"`` orders the refactorization's fresh factorizations by METIS's
#: nested dissection from this many coordinates on, when `pymetis` is installed (the
#: ``meshes`` extra): on the lattice at 10^4 bodies (3·10^4 coordinates) it and COLAMD
#: give the same fill, at 10^5 METIS's refactorization is twice as fast
#: (docs/design-notes.md, "Fill-reducing column order").
MIN_METIS_COORDINATES = 30_000

_SOLVER_CLASSES = {"superlu": SuperLUSolver, "refactor": RefactorSolver, "dense": DenseSolver}


class _BranchJump(Exception):
    """The solved step breaks the corrected trapezoidal rule: perhaps a jump to another branch."""


class KinematicStepper:
    """Solve a mechanism's motion sample after sample.

    Parameters
    ----------
    mechanism : Mechanism
        A mechanism whose equations control every coordinate (redundant but consistent
        equations are left out with a `RedundantConstraintWarning`).
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
        ``build_pattern(mechanism)``, if already made.
    assembler : Assembler, optional
        The assembler to fill the equations with (for instance one whose calls are timed).
    forces : bool
        Whether the run computes forces from the stepper's factorizations
        (`sparsekin.engine.forces.ForceSolver`); only the warning about redundant equations
        says more then.

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
        sample too costly (`fill_is_heavy`) and reuses it across samples.
    n_subdivisions : int
        How many times a step was halved.
    redundant_rows : ndarray of int
        Equations left out as redundant.
    """

    def __init__(
        self,
        mechanism: Mechanism,
        *,
        linear_solver="auto",
        tolerance: float = DEFAULT_TOLERANCE,
        max_iterations: int = NEWTON_MAXITER,
        chord: bool | None = None,
        pattern: ConstraintPattern | None = None,
        assembler: Assembler | None = None,
        forces: bool = False,
    ) -> None:
        if not isinstance(mechanism, Mechanism):
            raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
        self.tolerance = checked_tolerance(tolerance)
        self.max_iterations = checked_max_iterations(max_iterations)
        self.mechanism = mechanism
        self.pattern = pattern = build_pattern(mechanism) if pattern is None else pattern
        if pattern.n_equations == 0 and pattern.n_coordinates:
            bodies = ", ".join(mechanism.body_names[:4]) + (", …" if mechanism.n_bodies > 4 else "")
            raise ModelError(
                f"{pattern.n_coordinates} coordinates but no equation: every body ({bodies}) moves freely; "
                "expected joints and drivers"
            )
        self.assembler = Assembler(mechanism, pattern) if assembler is None else assembler
        self.diagnosis = Diagnosis(mechanism, pattern)
        self.auto = isinstance(linear_solver, str) and linear_solver == "auto"
        if isinstance(linear_solver, str):
            if linear_solver not in LINEAR_SOLVERS:
                raise ValueError(
                    f"`linear_solver` must be one of {', '.join(map(repr, LINEAR_SOLVERS))}, got {linear_solver!r}."
                )
            if self.auto:
                linear_solver = "dense" if pattern.n_coordinates <= COMPILED_MAX_COORDINATES else "refactor"
            self.chord = linear_solver != "superlu" if chord is None else bool(chord)
            if self.auto and pattern.n_coordinates >= MIN_METIS_COORDINATES and metis_installed():
                linear_solver = RefactorSolver(ordering="metis")
            else:
                linear_solver = _SOLVER_CLASSES[linear_solver]()
        else:
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
            if self.auto and fill_is_heavy(self.linear_solver, self.pattern):
                # The refactorization goes on under a solver that reuses its factorization
                # across samples; it takes the Jacobian at the converged position (the
                # forces of this sample solve with it, the next sample's chord Newton
                # starts from it).
                self.use_linear_solver(ReusingSolver(self.linear_solver, factored=True), path="reuse")
                self.factorizer()
                self._factored = True
        except (NoConvergence, SingularMatrix) as failure:
            raise self.diagnosis.cannot_start(self.system, self.assembler, t, drawn, _reason(failure)) from None
        self._check_left_out(t, first=True)
        self._accept(t)
        self._first = (t, self.coordinates.copy())
        return corrections

    def _suggest_ordering(self, t: float) -> None:
        """A chain of many repeated units: the refactorization's first pivot order tiled from
        a short chain (`sparsekin.engine.ordering`), not from SuperLU on the whole chain."""
        suggest = getattr(self.linear_solver, "suggest", None)  # a RefactorSolver's
        if suggest is None or self.system is not self.assembler:
            return
        ordering = hub_last_ordering(self.mechanism, self.pattern, t)  # many bodies on one: the hub last (issue 27)
        if ordering is None and self.mechanism.copies and self.pattern.n_coordinates >= MIN_TILED_COORDINATES:
            ordering = tiled_ordering(self.mechanism, self.pattern, t)
        if ordering is not None:
            suggest(*ordering)

    def resume(self, t: float, coordinates, velocities, accelerations, first: tuple[float, np.ndarray]) -> None:
        """Continue from a sample solved elsewhere (the compiled loop), at time `t`.

        `first` is ``(t, coordinates)`` of the run's first sample, the reference of the
        lock-up diagnosis.
        """
        self.coordinates[:], self.velocities[:], self.accelerations[:] = coordinates, velocities, accelerations
        self.time = float(t)
        self._first = (float(first[0]), np.array(first[1], dtype=float))
        self._factored = False

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
        h = t - self.time
        q, velocity, acceleration = self._next
        np.multiply(self.velocities, h, out=q)  # the Taylor predictor, without a temporary
        q += self.coordinates
        np.multiply(self.accelerations, 0.5 * h * h, out=self._predicted)
        q += self._predicted
        np.copyto(self._predicted, q)
        self.system.set_time(t)
        try:
            corrections = self._solve_positions(q)
            self._solve_rates(q, velocity, acceleration)
            if _jumped(
                h, self.coordinates, self.velocities, self.accelerations, q, velocity, acceleration,
                self._predicted, self._coordinate_weights, BRANCH_DEFECT_RATIO, BRANCH_MIN_DEFECT,
                BRANCH_MIN_CORRECTION,
            ):  # fmt: skip
                raise _BranchJump
        except (NoConvergence, SingularMatrix, _BranchJump):
            corrections = self._subdivide(t)
        self._check_left_out(t)
        self._accept(t)
        return corrections

    # ------------------------------------------------------------------ internals
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
        """Solve the sample at `end` from the current one in shorter steps, halved as often
        as needed; the result goes to `_next`.  Returns the corrections over all sub-steps.

        A step whose result jumps away from its predictor is halved up to
        `BRANCH_MAX_HALVINGS` times, then accepted; a step on which Newton fails is
        halved up to `FAILURE_MAX_HALVINGS` times, then the analysis stops.
        """
        start = self.time
        span = end - start
        t = start
        q, velocity, acceleration = self.coordinates.copy(), self.velocities.copy(), self.accelerations.copy()
        trial, trial_velocity, trial_acceleration = np.empty_like(q), np.empty_like(q), np.empty_like(q)
        h = 0.5 * span
        self.n_subdivisions += 1
        corrections = 0
        while True:
            last = end - t <= h * (1.0 + 1e-9)
            step = end - t if last else h
            t_next = end if last else t + h
            np.multiply(velocity, step, out=trial)
            trial += q
            np.multiply(acceleration, 0.5 * step * step, out=self._predicted)
            trial += self._predicted
            np.copyto(self._predicted, trial)
            self.system.set_time(t_next)
            try:
                n = self._solve_positions(trial)
                self._solve_rates(trial, trial_velocity, trial_acceleration)
                if step > span / 2**BRANCH_MAX_HALVINGS and _jumped(
                    step, q, velocity, acceleration, trial, trial_velocity, trial_acceleration,
                    self._predicted, self._coordinate_weights, BRANCH_DEFECT_RATIO, BRANCH_MIN_DEFECT,
                    BRANCH_MIN_CORRECTION,
                ):  # fmt: skip
                    raise _BranchJump
            except (NoConvergence, SingularMatrix, _BranchJump) as failure:
                if step <= span / 2**FAILURE_MAX_HALVINGS:
                    raise self.diagnosis.stopped(
                        self.system, self.assembler, self._first, (t, q), t_next, _reason(failure)
                    ) from None
                h = 0.5 * step
                self.n_subdivisions += 1
                continue
            corrections += n
            t = t_next
            q, trial = trial, q
            velocity, trial_velocity = trial_velocity, velocity
            acceleration, trial_acceleration = trial_acceleration, acceleration
            if last:
                break
            h = min(2.0 * h, span)
        for target, solved in zip(self._next, (q, velocity, acceleration)):
            target[:] = solved
        return corrections

    def _leave_out_redundant(self, t: float, coordinates: np.ndarray) -> None:
        """More equations than coordinates: solve without the redundant ones."""
        self.redundant_rows = self.diagnosis.redundant_rows(self.assembler, t, coordinates, self.forces)
        kept = np.setdiff1d(np.arange(self.pattern.n_equations), self.redundant_rows)
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
        costly at every sample (`fill_is_heavy`): `start` hands the Jacobian at the
        converged position to a `ReusingSolver` around the refactorization.  Called
        alone, it leaves the new solver without a factorization: the next sample runs
        plain Newton, then chord Newton again.
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


def fill_is_heavy(linear_solver, pattern: ConstraintPattern) -> bool:
    """Whether `linear_solver` is a refactorization with more fill-in than `MAX_REFACTOR_FILL`."""
    return isinstance(linear_solver, RefactorSolver) and linear_solver.nnz_factors > MAX_REFACTOR_FILL * pattern.nnz


def checked_tolerance(value) -> float:
    """`value` as a float within `TOLERANCE_RANGE`, else a ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"`tolerance` must be a positive number, got {value!r}.")
    low, high = TOLERANCE_RANGE
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"`tolerance` must be a number in [{low:.3g}, {high:g}], got {value!r}.")
    return float(value)


def checked_max_iterations(value) -> int:
    """`value` as an int >= 1, else a ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"`max_iterations` must be a whole number >= 1, got {value!r}.")
    return int(value)


@njit(**JIT)
def first_branch_jump(times, coordinates, velocities, accelerations, weights, stop):
    """The first sample below `stop` whose step from the previous one fails the branch guard
    (`_jumped`); `stop` if none.  Checks the samples of the compiled loop."""
    predicted = np.empty(coordinates.shape[1])
    for k in range(1, stop):
        h = times[k] - times[k - 1]
        for i in range(predicted.size):
            predicted[i] = coordinates[k - 1, i] + h * velocities[k - 1, i] + 0.5 * h * h * accelerations[k - 1, i]
        if _jumped(
            h, coordinates[k - 1], velocities[k - 1], accelerations[k - 1], coordinates[k], velocities[k],
            accelerations[k], predicted, weights, BRANCH_DEFECT_RATIO, BRANCH_MIN_DEFECT, BRANCH_MIN_CORRECTION,
        ):  # fmt: skip
            return k
    return stop


@njit(**JIT)
def _jumped(h, q0, qd0, qdd0, q1, qd1, qdd1, predicted, weights, ratio, min_defect, min_correction):
    """Whether a solved step looks like a jump to another assembly branch (see `BRANCH_DEFECT_RATIO`).

    The defect ``q1 - q0 - h/2 (qd0 + qd1) + h²/12 (qdd1 - qdd0)``, the displacement
    ``q1 - q0`` and Newton's correction ``q1 - predicted`` are each measured by their
    largest weighted coordinate.  A NaN anywhere counts as a jump.
    """
    defect = 0.0
    displacement = 0.0
    correction = 0.0
    for i in range(q0.size):
        move = q1[i] - q0[i]
        d = abs(move - 0.5 * h * (qd0[i] + qd1[i]) + (h * h / 12.0) * (qdd1[i] - qdd0[i])) * weights[i]
        m = abs(move) * weights[i]
        c = abs(q1[i] - predicted[i]) * weights[i]
        if not d <= defect:  # also true for a NaN
            defect = d
        displacement = max(displacement, m)
        correction = max(correction, c)
    return defect > min_defect and defect > ratio * displacement and correction > min_correction
