"""Kinematic analysis: positions by Newton–Raphson, then velocities and accelerations.

At each time t the positions q solve Phi(q, t) = 0 by Newton–Raphson from a Taylor
predictor built on the previous sample.  The factorization of the Jacobian Phi_q at the
converged position then serves two more solves:

    Phi_q · qd  = -Phi_t        (velocities)
    Phi_q · qdd = gamma         (accelerations)

Convergence is judged on the residual, lengths relative to the size of the model (so a
chain 10^4 m long converges as surely as a 1 m linkage) and angles in radians.

Linear solvers (the `linear_solver` argument; ``"auto"`` picks the fastest):

* ``"dense"`` — for small models, the whole time loop compiled with numba
  (`sparsekin._compiled`) on a dense LU; a model it cannot run (a law of another kind,
  redundant equations) and any sample it cannot solve go to the Python loop below, with
  `DenseSolver`.
* ``"refactor"`` — `RefactorSolver`: the ordering and the L and U patterns are fixed by a
  first SuperLU factorization, every later factorization is a numeric refactorization.
* ``"superlu"`` — a fresh SuperLU factorization at every Newton iteration.

With ``"refactor"`` and ``"dense"`` the Newton corrections are *chord* corrections: they
reuse the factorization of the previous sample while each one divides the residual by at
least ``1 / CHORD_CONTRACTION``, and plain Newton restarts from the predictor otherwise.
Every path factors the Jacobian at the converged position, so velocities and
accelerations are solved with the Jacobian there, to the same accuracy on every path.

Robustness, in the order the run meets it:

* **Redundant equations.**  A model with more equations than coordinates is analysed
  once at t = 0 (`sparsekin.diagnostics.analyse_jacobian`); the equations that depend
  on the others are left out of every solve (a square view of the assembler's arrays,
  refilled in place), with a `RedundantConstraintWarning` naming them.  They must stay
  satisfied; a model with free motions is refused.
* **Step subdivision.**  When Newton fails from the predictor, or the solved positions,
  velocities and accelerations break the corrected trapezoidal rule over the step (the
  sign of a jump to another assembly branch), the step is halved and the intermediate
  samples are solved internally, without being stored.
* **Lock-up.**  When Newton still fails on a step a million times shorter, the Jacobian
  at the last solved configuration tells a singular configuration (its smallest singular
  value has collapsed) from other failures; the first is a `SingularConfigurationError`
  naming the uncontrolled motion and the constraints involved, the second a
  `ConvergenceError`.  Both keep the samples solved.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.sparse import csr_array

from ._compiled import CHORD_CONTRACTION, POLISH_BELOW, solve_compiled, supports_compiled
from ._kernels import _JIT
from .assembly import Assembler
from .diagnostics import (
    CONSISTENCY_TOLERANCE,
    analyse_jacobian,
    coordinate_label,
    describe_motion,
    equation_label,
    equations_summary,
    motion_summary,
    residual_weights,
    row_preference,
    shares,
)
from .errors import ConvergenceError, ModelError, RedundantConstraintWarning, SingularConfigurationError
from .laws import Spline
from .linalg import DenseSolver, RefactorSolver, SingularMatrix, SuperLUSolver
from .model import Mechanism
from .pattern import ConstraintPattern, PointMap, build_pattern, build_point_map

__all__ = ["KinematicsResult", "PointMotion", "coordinate_label", "equation_label", "solve_kinematics"]

#: Most Newton corrections at one time sample.
NEWTON_MAXITER = 12
#: Default convergence tolerance: the largest residual, lengths relative to the model size
#: and angles in rad.  Near the rounding floor, so that positions carry full accuracy.
DEFAULT_TOLERANCE = 1e-12
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
#: Lock-up: after a failure on the shortest step, the configuration is singular if the
#: smallest singular value of the scaled Jacobian, relative to its largest, has fallen
#: below this fraction of its value at the first sample.
LOCK_RATIO = 1e-2
#: How many drivers, coordinates and constraints an error message lists.
_LISTED = 4
#: The `linear_solver` argument of `solve_kinematics`.
LINEAR_SOLVERS = ("auto", "superlu", "refactor", "dense")
#: ``linear_solver="auto"`` runs the compiled dense loop up to this many coordinates and
#: the refactorization path above: the crossover measured on the test set
#: (benchmarks/RESULTS.md, "Crossover").
COMPILED_MAX_COORDINATES = 120
#: ``linear_solver="auto"`` keeps the refactorization while its L and U hold at most this
#: many entries per entry of the Jacobian.  With more fill-in (meshes rather than chains)
#: SuperLU's supernodal factorization beats the numba refactorization, and the run goes on
#: with SuperLU (and chord Newton).  Measured: L + U / Jacobian entries 1.2, 1.6 and 6.4
#: (four_bar_chain(10^4), task5_chain(10^4), lattice(22, 22)): refactorization 13 to 20
#: times faster than SuperLU; 9.6 and 13.7 (lattice at 10^4 and 10^5 bodies): 1.2 and 2.1
#: times slower.
MAX_REFACTOR_FILL = 8.0


class PointMotion(NamedTuple):
    """Motion of a named point: each array has shape (n_times, 2), global x and y."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


@dataclass(frozen=True, eq=False)
class KinematicsResult:
    """Positions, velocities and accelerations of every body at every time.

    Attributes
    ----------
    times : ndarray, shape (n_times,)
        Sample times, s.
    coordinates, velocities, accelerations : ndarray, shape (n_times, 3 * n_bodies)
        ``(x, y, angle)`` of each body frame, body order as in the model (m, rad), and
        their first and second time derivatives.
    body_names : tuple of str
    newton_iterations : ndarray of int, shape (n_times,)
        Newton corrections at each time (over all its sub-steps when the step to it was
        subdivided).
    n_factorizations, n_solves : int
        Factorizations of the Jacobian and linear solves in the whole run.
    complete : bool
        False when the analysis stopped early: then only the samples solved are here.
    n_subdivisions : int
        How many times a step was halved (a Newton failure, or a suspected jump to
        another assembly branch); 0 on a well-sampled run.
    redundant_equations : tuple of str
        The equations left out as redundant (empty for most models).
    n_refactorizations : int
        Numeric refactorizations on a fixed pattern (``linear_solver="refactor"``).
    linear_solver : str
        The path that solved the run: ``"compiled"`` (the compiled dense loop all the
        way), ``"compiled+dense"`` (the Python loop took over from it), ``"dense"``,
        ``"refactor"``, ``"superlu-chord"`` (``"auto"`` left a refactorization with too
        much fill-in after the first sample) or ``"superlu"``.
    """

    times: np.ndarray
    coordinates: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    body_names: tuple[str, ...]
    newton_iterations: np.ndarray
    n_factorizations: int
    n_solves: int
    complete: bool
    point_map: PointMap = field(repr=False)
    n_subdivisions: int = 0
    redundant_equations: tuple[str, ...] = ()
    n_refactorizations: int = 0
    linear_solver: str = "superlu"

    @property
    def n_times(self) -> int:
        return self.times.size

    @property
    def point_names(self) -> tuple[str, ...]:
        return self.point_map.names

    def point(self, name: str) -> PointMotion:
        """Global position (m), velocity (m/s) and acceleration (m/s²) of point `name`."""
        try:
            k = self.point_map.index(name)
        except KeyError:
            raise KeyError(f'unknown point "{name}"; the model has {", ".join(self.point_map.names)}') from None
        local = self.point_map.local[k]
        body = int(self.point_map.body[k])
        if body < 0:
            position = np.tile(local, (self.n_times, 1))
            return PointMotion(position, np.zeros_like(position), np.zeros_like(position))
        columns = slice(3 * body, 3 * body + 3)
        x, y, angle = self.coordinates[:, columns].T
        xd, yd, angle_d = self.velocities[:, columns].T
        xdd, ydd, angle_dd = self.accelerations[:, columns].T
        cosine, sine = np.cos(angle), np.sin(angle)
        sx = cosine * local[0] - sine * local[1]  # R s, global
        sy = sine * local[0] + cosine * local[1]
        position = np.stack([x + sx, y + sy], axis=1)
        velocity = np.stack([xd - sy * angle_d, yd + sx * angle_d], axis=1)
        acceleration = np.stack(
            [xdd - sy * angle_dd - sx * angle_d**2, ydd + sx * angle_dd - sy * angle_d**2], axis=1
        )
        return PointMotion(position, velocity, acceleration)



def solve_kinematics(
    mechanism: Mechanism,
    times,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    max_iterations: int = NEWTON_MAXITER,
    linear_solver: str = "auto",
) -> KinematicsResult:
    """Positions, velocities and accelerations of `mechanism` at `times`.

    Parameters
    ----------
    mechanism : Mechanism
        A mechanism whose equations (joints and drivers) control every coordinate.  It
        may have more equations than coordinates if the surplus are redundant and
        consistent: they are left out, with a `RedundantConstraintWarning`.
    times : array_like, shape (n_times,)
        Strictly increasing, finite sample times, s.  The first sample starts Newton
        from the initial configuration of the model.
    tolerance : float
        Largest accepted residual: lengths relative to the size of the model, angles in
        rad; within `TOLERANCE_RANGE`.
    max_iterations : int
        Most Newton corrections at one time, at least 1.
    linear_solver : {"auto", "dense", "refactor", "superlu"}
        How the linear systems are solved (see the module docstring).  ``"auto"`` takes
        ``"dense"`` (the compiled loop) up to `COMPILED_MAX_COORDINATES` coordinates and
        ``"refactor"`` above, unless the refactorization's fill-in exceeds
        `MAX_REFACTOR_FILL`: then SuperLU with chord Newton.  Every choice gives the same
        results to rounding.

    Returns
    -------
    KinematicsResult

    Raises
    ------
    TypeError, ValueError
        If an argument is not of the expected type, shape or range.
    ModelError
        If the mechanism has free motions (fewer independent equations than
        coordinates), or redundant equations that contradict the others or involve
        drivers.
    SingularConfigurationError
        If the mechanism reaches a singular configuration (a lock-up, a dead centre):
        ``error.result`` holds the samples before it.
    ConvergenceError
        If a sample cannot be solved for another reason; ``error.result`` holds the
        samples before it.

    Warns
    -----
    RedundantConstraintWarning
        When redundant equations are left out.

    Examples
    --------
    >>> from sparsekin import Body, Mechanism, Revolute, RotationalDriver, Linear
    >>> crank = Mechanism(
    ...     points={"O": (0.0, 0.0), "A": (0.1, 0.0)},
    ...     bodies=[Body("crank", origin="O", points=("O", "A"))],
    ...     joints=[Revolute(("crank", "ground"), at="O")],
    ...     drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=2.0))],
    ... )
    >>> result = solve_kinematics(crank, times=[0.0, 0.5])
    >>> result.point("A").velocity[1].round(6).tolist()  # 0.2 m/s, perpendicular to the crank at 1 rad
    [-0.168294, 0.10806]
    """
    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    times = _checked_times(times, mechanism)
    tolerance = _checked_tolerance(tolerance)
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) or max_iterations < 1:
        raise ValueError(f"`max_iterations` must be a whole number >= 1, got {max_iterations!r}.")
    max_iterations = int(max_iterations)
    if linear_solver not in LINEAR_SOLVERS:
        raise ValueError(f"`linear_solver` must be one of {', '.join(map(repr, LINEAR_SOLVERS))}, got {linear_solver!r}.")
    pattern = build_pattern(mechanism)
    if pattern.n_equations == 0:  # nothing to solve, or nothing that holds the bodies
        return _without_equations(mechanism, pattern, times)
    auto = linear_solver == "auto"
    if auto:
        linear_solver = "dense" if pattern.n_coordinates <= COMPILED_MAX_COORDINATES else "refactor"
    solver = {"superlu": SuperLUSolver, "refactor": RefactorSolver, "dense": DenseSolver}[linear_solver]()
    compiled = (
        linear_solver == "dense" and pattern.n_equations == pattern.n_coordinates and supports_compiled(mechanism)
    )
    run = _Run(mechanism, pattern, Assembler(mechanism, pattern), solver, times, tolerance, max_iterations,
               chord=linear_solver != "superlu", auto=auto)  # fmt: skip
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # non-finite values are checked
        return run.solve(compiled=compiled)


def _without_equations(mechanism: Mechanism, pattern: ConstraintPattern, times) -> KinematicsResult:
    """The result for a mechanism without bodies; a `ModelError` if it has bodies but no equations."""
    if pattern.n_coordinates:
        bodies = ", ".join(mechanism.body_names[:_LISTED]) + (", …" if mechanism.n_bodies > _LISTED else "")
        raise ModelError(
            f"{pattern.n_coordinates} coordinates but no equation: every body ({bodies}) moves freely; "
            "expected joints and drivers"
        )
    empty = np.zeros((times.size, 0))
    return KinematicsResult(
        times=times, coordinates=empty, velocities=empty.copy(), accelerations=empty.copy(),
        body_names=(), newton_iterations=np.zeros(times.size, dtype=np.int64), n_factorizations=0,
        n_solves=0, complete=True, point_map=build_point_map(mechanism),
    )  # fmt: skip


class _Run:
    """The state of one `solve_kinematics` run: arrays of results, the system solved, counters."""

    def __init__(self, mechanism, pattern, assembler, linear_solver, times, tolerance, max_iterations, chord, auto):
        self.mechanism, self.pattern, self.assembler = mechanism, pattern, assembler
        self.linear_solver, self.times = linear_solver, times
        self.tolerance, self.max_iterations = tolerance, max_iterations
        self.chord, self.auto = chord, auto
        self.retired_counts = np.zeros(3, dtype=np.int64)  # factorizations, refactorizations, solves
        # of linear solvers left during the run
        self.factored = False  # whether the linear solver holds a factorization to chord with
        self.factorizer = None
        self.path = linear_solver.name
        self.compiled_counts = (0, 0)  # factorizations and solves of the compiled loop
        self.system = assembler  # or a _ReducedSystem without the redundant equations
        self.weights = residual_weights(pattern)
        self.system_weights = self.weights  # those of the system's rows
        self.coordinate_weights = np.full(pattern.n_coordinates, 1.0 / pattern.length_scale)
        self.coordinate_weights[2::3] = 1.0
        n_times, n_coordinates = times.size, pattern.n_coordinates
        self.coordinates = np.empty((n_times, n_coordinates))
        self.velocities = np.empty((n_times, n_coordinates))
        self.accelerations = np.empty((n_times, n_coordinates))
        self.iterations = np.zeros(n_times, dtype=np.int64)
        self.predicted = np.empty(n_coordinates)  # the predictor of the current step, for the branch guard
        self.n_subdivisions = 0
        self.redundant_rows = np.zeros(0, dtype=np.int64)

    # ------------------------------------------------------------------ the loop
    def solve(self, compiled: bool = False) -> KinematicsResult:
        """Solve every sample; with `compiled`, as many as the compiled loop can first."""
        times, pattern = self.times, self.pattern
        if pattern.n_equations != pattern.n_coordinates:
            self._analyse_non_square()
        start = self._solve_compiled() if compiled else 0
        if start == times.size:
            return self.result(times.size)
        if start == 0:
            self._first_sample()
            start = 1
            if self.auto and _fill_is_heavy(self.linear_solver, self.pattern):
                self._switch_to_superlu()
        for k in range(start, times.size):
            q = self.coordinates[k]  # Newton refines the predictor in place, in its row of the result
            h = times[k] - times[k - 1]
            np.multiply(self.velocities[k - 1], h, out=q)  # Taylor predictor from the previous sample
            q += self.coordinates[k - 1]
            q += (0.5 * h * h) * self.accelerations[k - 1]
            np.copyto(self.predicted, q)
            self.system.set_time(times[k])
            try:
                self.iterations[k] = self._solve_positions(q)
                self._solve_rates(q, self.velocities[k], self.accelerations[k])
                if _jumped(
                    h, self.coordinates[k - 1], self.velocities[k - 1], self.accelerations[k - 1],
                    q, self.velocities[k], self.accelerations[k], self.predicted, self.coordinate_weights,
                    BRANCH_DEFECT_RATIO, BRANCH_MIN_DEFECT, BRANCH_MIN_CORRECTION,
                ):  # fmt: skip
                    raise _BranchJump
            except (_NoConvergence, SingularMatrix, _BranchJump):
                self._subdivide(k)
            if self.redundant_rows.size:
                self._check_left_out(k)
        return self.result(times.size)

    def _switch_to_superlu(self) -> None:
        """Leave a refactorization whose fill-in makes it slower than SuperLU (`MAX_REFACTOR_FILL`)."""
        left = self.linear_solver
        self.retired_counts += (left.n_factorizations, left.n_refactorizations, left.n_solves)
        self.linear_solver = SuperLUSolver()  # and the refactorization's factors are freed
        self.assembler.fill_in_order(None)
        self.factorizer = None
        self.factored = False  # the next sample runs plain Newton, then chord again
        self.path = "superlu-chord"

    def _solve_compiled(self) -> int:
        """Run the compiled loop; the number of samples it solved that pass the branch guard."""
        outcome = solve_compiled(
            self.mechanism, self.pattern, self.times, self.tolerance, self.max_iterations, self.weights,
            self.coordinates, self.velocities, self.accelerations, self.iterations,
        )  # fmt: skip
        self.compiled_counts = (outcome.n_factorizations, outcome.n_solves)
        solved = _first_branch_jump(
            self.times, self.coordinates, self.velocities, self.accelerations, self.coordinate_weights,
            outcome.n_solved, BRANCH_DEFECT_RATIO, BRANCH_MIN_DEFECT, BRANCH_MIN_CORRECTION,
        )  # fmt: skip
        self.path = "compiled" if solved == self.times.size else "compiled+dense"
        return solved

    def result(self, n_solved: int) -> KinematicsResult:
        solver, retired = self.linear_solver, self.retired_counts
        return KinematicsResult(
            times=self.times[:n_solved],
            coordinates=self.coordinates[:n_solved],
            velocities=self.velocities[:n_solved],
            accelerations=self.accelerations[:n_solved],
            body_names=self.mechanism.body_names,
            newton_iterations=self.iterations[:n_solved],
            n_factorizations=solver.n_factorizations + int(retired[0]) + self.compiled_counts[0],
            n_solves=solver.n_solves + int(retired[2]) + self.compiled_counts[1],
            complete=n_solved == self.times.size,
            point_map=build_point_map(self.mechanism),
            n_subdivisions=self.n_subdivisions,
            redundant_equations=tuple(self._label(row) for row in self.redundant_rows),
            n_refactorizations=solver.n_refactorizations + int(retired[1]),
            linear_solver=self.path,
        )

    def _solve_positions(self, q) -> int:
        """Newton from `q`, whose copy is in `self.predicted` whenever chord Newton may run."""
        chord, self.factored = self.chord and self.factored, False
        if self.factorizer is None or self.factorizer.system is not self.system:
            self.factorizer = _Factorizer(self.system, self.linear_solver)
        corrections = _solve_positions(
            self.system, self.linear_solver, q, self.system_weights, self.tolerance, self.max_iterations, chord,
            self.factorizer, self.predicted,
        )  # fmt: skip
        self.factored = True
        return corrections

    def _solve_rates(self, q, velocity, acceleration) -> None:
        """Velocities and accelerations at the converged `q`, with the factorization there."""
        self.linear_solver.solve(self.system.velocity_rhs, out=velocity)
        self.system.fill_acceleration_rhs(q, velocity)
        self.linear_solver.solve(self.system.acceleration_rhs, out=acceleration)

    def _first_sample(self) -> None:
        q = self.coordinates[0]
        q[:] = self.pattern.initial_coordinates
        t = self.times[0]
        self.system.set_time(t)
        try:
            self.iterations[0] = self._solve_positions(q)
            self._solve_rates(q, self.velocities[0], self.accelerations[0])
        except (_NoConvergence, SingularMatrix) as failure:
            reason = _reason(failure)
            worst = self._worst_residual()
            self.system.set_time(t)
            self.system.fill_residual_jacobian(self.pattern.initial_coordinates)
            analysis = analyse_jacobian(self.system.jacobian)
            if analysis.rank < self.pattern.n_coordinates:
                raise self._singular_error(analysis, self.pattern.initial_coordinates, t, 0) from None
            raise ConvergenceError(
                f"cannot assemble the model at t = {t:.6g} s: {reason} ({self._drivers_text()}){worst}",
                time=float(t),
                driver_values=self._driver_values(),
                result=self.result(0),
            ) from None
        if self.redundant_rows.size:
            self._check_left_out(0)

    # ------------------------------------------------------------------ subdivision
    def _subdivide(self, k: int) -> None:
        """Solve sample k from sample k - 1 in shorter steps, halved as often as needed.

        The intermediate samples are solved (positions, velocities, accelerations) but
        not stored.  A step whose result jumps away from its predictor is halved up to
        `BRANCH_MAX_HALVINGS` times, then accepted; a step on which Newton fails is
        halved up to `FAILURE_MAX_HALVINGS` times, then the analysis stops.
        """
        times = self.times
        start, end = float(times[k - 1]), float(times[k])
        span = end - start
        t = start
        q, velocity, acceleration = (self.coordinates[k - 1].copy(), self.velocities[k - 1].copy(),
                                     self.accelerations[k - 1].copy())  # fmt: skip
        trial = np.empty_like(q)
        trial_velocity, trial_acceleration = np.empty_like(q), np.empty_like(q)
        h = 0.5 * span
        self.n_subdivisions += 1
        corrections = 0
        while True:
            last = end - t <= h * (1.0 + 1e-9)
            step = end - t if last else h
            t_next = end if last else t + h
            np.multiply(velocity, step, out=trial)
            trial += q
            trial += (0.5 * step * step) * acceleration
            np.copyto(self.predicted, trial)
            self.system.set_time(t_next)
            try:
                n = self._solve_positions(trial)
                self._solve_rates(trial, trial_velocity, trial_acceleration)
                if step > span / 2**BRANCH_MAX_HALVINGS and _jumped(
                    step, q, velocity, acceleration, trial, trial_velocity, trial_acceleration,
                    self.predicted, self.coordinate_weights,
                    BRANCH_DEFECT_RATIO, BRANCH_MIN_DEFECT, BRANCH_MIN_CORRECTION,
                ):  # fmt: skip
                    raise _BranchJump
            except (_NoConvergence, SingularMatrix, _BranchJump) as failure:
                if step <= span / 2**FAILURE_MAX_HALVINGS:
                    raise self._stopped(k, t, q, t_next, _reason(failure)) from None
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
        self.coordinates[k], self.velocities[k], self.accelerations[k] = q, velocity, acceleration
        self.iterations[k] = corrections

    # ------------------------------------------------------------------ failures
    def _stopped(self, k, t_good, q_good, t_failed, reason) -> ConvergenceError:
        """The error for a step that failed on the shortest subdivision.

        A singular configuration if the smallest singular value of the (scaled)
        Jacobian at the last configuration solved has collapsed compared with the first
        sample; another failure otherwise.
        """
        worst = self._worst_residual()
        self.system.set_time(self.times[0])
        self.system.fill_residual_jacobian(self.coordinates[0])
        reference = analyse_jacobian(self.system.jacobian).smallest_singular_value
        self.system.set_time(t_good)
        self.system.fill_residual_jacobian(q_good)
        analysis = analyse_jacobian(self.system.jacobian)
        if analysis.rank < analysis.shape[1] or analysis.smallest_singular_value <= LOCK_RATIO * reference:
            return self._singular_error(
                analysis, q_good, t_failed, k, reference, f"{reason} on a step of {t_failed - t_good:.2g} s"
            )
        self.system.set_time(t_failed)
        return ConvergenceError(
            f"{reason} at t = {t_failed:.6g} s ({self._drivers_text()}){worst}; the step was halved down "
            f"to {t_failed - t_good:.2g} s and the Jacobian at the last configuration solved "
            f"(t = {t_good:.8g} s) is regular (smallest singular value "
            f"{analysis.smallest_singular_value:.2g} of the largest, scaled)",
            time=float(t_failed),
            driver_values=self._driver_values(),
            result=self.result(k),
        )

    def _singular_error(self, analysis, q, t, k, reference=None, how="") -> SingularConfigurationError:
        """A `SingularConfigurationError` at time `t`, the motion and constraints from `analysis`."""
        rows = self.system.rows if self.system is not self.assembler else None
        motion = motion_summary(self.mechanism, analysis.smallest_motion, limit=_LISTED)
        bodies = describe_motion(
            self.mechanism, self.pattern, q, analysis.column_scale * analysis.smallest_motion,
            analysis.smallest_motion, limit=3,
        )  # fmt: skip
        equations = equations_summary(
            self.mechanism, self.pattern, analysis.smallest_equations, rows=rows, limit=_LISTED
        )
        value = analysis.smallest_singular_value
        if analysis.rank < analysis.shape[1]:
            size = f"the Jacobian has rank {analysis.rank} for {analysis.shape[1]} coordinates"
        else:
            versus = f" (it was {reference:.2g} at t = {self.times[0]:g} s)" if reference is not None else ""
            size = f"smallest singular value of the scaled Jacobian {value:.2g} of the largest{versus}"
        self.system.set_time(t)
        return SingularConfigurationError(
            f"singular configuration at t = {t:.6g} s: {self._drivers_text(prefix='')}; uncontrolled motion: "
            f"{motion} — {bodies}; constraints involved: {equations}; {size}" + (f"; {how}" if how else ""),
            time=float(t),
            driver_values=self._driver_values(),
            result=self.result(k),
            smallest_singular_value=float(value),
        )

    def _worst_residual(self) -> str:
        residual = self.system.residual
        if not residual.size or not np.all(np.isfinite(residual)):
            return ""
        worst = int(np.argmax(np.abs(residual) * self.system_weights))
        row = worst if self.system is self.assembler else int(self.system.rows[worst])
        return f"; largest residual {abs(residual[worst]):.3g} in {self._label(row)}"

    def _driver_values(self) -> dict[str, float]:
        return {
            self.mechanism.element_label("drivers", k): float(value)
            for k, value in enumerate(self.assembler.driver_values)
        }

    def _drivers_text(self, prefix: str = "drivers: ") -> str:
        drivers = self._driver_values()
        shown = "; ".join(f"{label} = {value:.6g}" for label, value in list(drivers.items())[:_LISTED])
        if len(drivers) > _LISTED:
            shown += f"; … ({len(drivers)} drivers)"
        return prefix + (shown or "no drivers")

    def _label(self, row: int) -> str:
        return equation_label(self.mechanism, self.pattern, int(row))

    # ------------------------------------------------------------------ redundant equations
    def _analyse_non_square(self) -> None:
        """Refuse free motions; find the redundant equations at the drawn configuration and
        solve without them."""
        mechanism, pattern, assembler = self.mechanism, self.pattern, self.assembler
        drawn = pattern.initial_coordinates
        assembler.set_time(self.times[0])
        assembler.fill_residual_jacobian(drawn)
        analysis = analyse_jacobian(assembler.jacobian, row_preference=row_preference(mechanism, pattern))
        n_coordinates, n_equations = pattern.n_coordinates, pattern.n_equations
        if analysis.n_free:
            raise ModelError(self._free_motions_message(analysis, drawn))
        if n_equations - analysis.n_redundant != n_coordinates:  # borderline ranks: no square system
            raise ModelError(
                f"{n_coordinates} coordinates but {n_equations} equations, of which "
                f"{analysis.n_redundant} depend on the others at t = {self.times[0]:g} s, where "
                f"{n_equations - n_coordinates} were expected: the drawn configuration is too close to "
                "singular to tell (sparsekin check MODEL.toml shows more)"
            )
        n_joint_rows = int(pattern.element_first_row[len(mechanism.joints)])
        for k, row in enumerate(analysis.redundant_rows):
            if np.any(shares(analysis.dependencies[:, k])[n_joint_rows:] >= 1e-12):
                raise ModelError(
                    f"{n_coordinates} coordinates but {n_equations} equations, and the drivers take part in "
                    f"a redundancy: {self._label(row)} depends on "
                    f"{equations_summary(mechanism, pattern, analysis.dependencies[:, k], exclude=int(row))}"
                    "; the drivers prescribe a motion that the joints already fix "
                    "(remove a driver or a joint)"
                )
        self.redundant_rows = analysis.redundant_rows
        self.system = _ReducedSystem(assembler, np.setdiff1d(np.arange(n_equations), analysis.redundant_rows))
        self.system_weights = self.weights[self.system.rows]
        listed = "; ".join(self._label(row) for row in self.redundant_rows[:_LISTED])
        if self.redundant_rows.size > _LISTED:
            listed += f"; … ({self.redundant_rows.size} equations)"
        warnings.warn(
            f"{n_equations} equations for {n_coordinates} coordinates: {self.redundant_rows.size} redundant "
            f"equation{'s' * (self.redundant_rows.size != 1)} left out (each depends on the others at t = "
            f"{self.times[0]:g} s): {listed}",
            RedundantConstraintWarning,
            stacklevel=3,
        )

    def _free_motions_message(self, analysis, coordinates) -> str:
        pattern, mechanism = self.pattern, self.mechanism
        motions = "; ".join(
            describe_motion(mechanism, pattern, coordinates, analysis.free_motions[:, k],
                            analysis.scaled_free_motions[:, k], limit=3)
            for k in range(min(analysis.n_free, _LISTED))
        )  # fmt: skip
        more = f"; … ({analysis.n_free} in all)" if analysis.n_free > _LISTED else ""
        n_drivers = len(mechanism.drivers)
        return (
            f"{pattern.n_coordinates} coordinates but {pattern.n_equations} equations of rank "
            f"{analysis.rank}: {analysis.n_free} free motion{'s' * (analysis.n_free != 1)} left after the "
            f"{n_drivers} driver{'s' * (n_drivers != 1)}: {motions}{more}; expected one driver per degree of freedom "
            "(sparsekin check MODEL.toml shows more)"
        )

    def _check_left_out(self, k: int) -> None:
        """The redundant equations left out must still hold at the solved sample k."""
        residual = np.abs(self.assembler.residual[self.redundant_rows]) * self.weights[self.redundant_rows]
        worst = int(np.argmax(residual))
        if residual[worst] <= CONSISTENCY_TOLERANCE:
            return
        row = int(self.redundant_rows[worst])
        message = (
            f"the redundant equation {self._label(row)} left out of the analysis is not satisfied at "
            f"t = {self.times[k]:.6g} s: residual {abs(self.assembler.residual[row]):.3g}; the redundant "
            "joints contradict each other"
        )
        if k == 0:
            raise ModelError(message)
        raise ConvergenceError(message, time=float(self.times[k]), driver_values=self._driver_values(),
                               result=self.result(k))  # fmt: skip


class _ReducedSystem:
    """The equations that are not redundant: a square view of an `Assembler`'s arrays.

    The CSR pattern of the kept rows and the positions of their values in the
    assembler's Jacobian are computed once; each refill copies those values (one gather)
    instead of building a matrix.

    Attributes
    ----------
    rows : ndarray of int
        The kept rows of the assembler's system.
    residual, velocity_rhs, acceleration_rhs : ndarray, shape (n_rows,)
    jacobian : csr_array, shape (n_rows, n_coordinates)
    """

    def __init__(self, assembler: Assembler, rows: np.ndarray) -> None:
        self.assembler = assembler
        self.rows = rows
        full = assembler.jacobian
        starts, ends = full.indptr[rows], full.indptr[rows + 1]
        lengths = (ends - starts).astype(np.int64)
        indptr = np.zeros(rows.size + 1, dtype=full.indptr.dtype)
        np.cumsum(lengths, out=indptr[1:])
        #: Positions in the full Jacobian's values of the kept rows' values, in order.
        self._entries = np.repeat(starts - indptr[:-1], lengths) + np.arange(int(indptr[-1]))
        values = np.zeros(self._entries.size)
        shape = (rows.size, full.shape[1])
        self.jacobian = csr_array((values, full.indices[self._entries], indptr), shape=shape)
        self.residual = np.zeros(rows.size)
        self.velocity_rhs = np.zeros(rows.size)
        self.acceleration_rhs = np.zeros(rows.size)

    @property
    def driver_values(self) -> np.ndarray:
        return self.assembler.driver_values

    def set_time(self, t: float) -> None:
        self.assembler.set_time(t)
        np.take(self.assembler.velocity_rhs, self.rows, out=self.velocity_rhs)

    def fill_residual_jacobian(self, coordinates: np.ndarray) -> None:
        self.assembler.fill_residual_jacobian(coordinates)
        np.take(self.assembler.residual, self.rows, out=self.residual)
        np.take(self.assembler.jacobian.data, self._entries, out=self.jacobian.data)

    def fill_acceleration_rhs(self, coordinates: np.ndarray, velocities: np.ndarray) -> None:
        self.assembler.fill_acceleration_rhs(coordinates, velocities)
        np.take(self.assembler.acceleration_rhs, self.rows, out=self.acceleration_rhs)


class _NoConvergence(Exception):
    def __init__(self, reason: str) -> None:
        self.reason = reason


def _reason(failure: Exception) -> str:
    """Why a solve failed, in words."""
    return failure.reason if isinstance(failure, _NoConvergence) else "the Jacobian is singular"


class _BranchJump(Exception):
    """The solved step breaks the corrected trapezoidal rule: perhaps a jump to another branch."""


def _fill_is_heavy(linear_solver, pattern: ConstraintPattern) -> bool:
    """Whether `linear_solver` is a refactorization with more fill-in than `MAX_REFACTOR_FILL`."""
    return isinstance(linear_solver, RefactorSolver) and linear_solver.nnz_factors > MAX_REFACTOR_FILL * pattern.nnz


class _Factorizer:
    """Factors the Jacobian of `system` with `linear_solver`, reading its values in place.

    With a solver that reads values in its own order (`RefactorSolver`) on an `Assembler`
    (not on a `_ReducedSystem`), the first factorization fixes the solver's
    value order; from then on the kernels write the Jacobian straight in that order
    (`Assembler.fill_in_order`) and the solver refactors from it without a gather — a
    random access over every value that cost about as much as the kernels at 10^6 bodies.
    """

    def __init__(self, system, linear_solver) -> None:
        self.system, self.linear_solver = system, linear_solver
        self._may_order = hasattr(linear_solver, "factor_ordered") and hasattr(system, "fill_in_order")
        self._layout = None  # the solver's layout the system fills in, once ordered

    def __call__(self) -> None:
        system, solver = self.system, self.linear_solver
        if self._layout is None:
            solver.factor(system.jacobian)
        else:
            solver.factor_ordered(system.values)
        if self._may_order and solver.layout_version != self._layout:
            system.fill_in_order(solver.value_positions)
            self._layout = solver.layout_version


def _solve_positions(
    assembler, linear_solver, q, weights, tolerance, max_iterations, chord=False, factor=None, restart=None
):
    """Newton–Raphson from `q`, which it refines in place; returns the number of corrections.

    With `chord`, first chord Newton: corrections solved with the factorization the
    linear solver already holds, kept while each divides the residual by at least
    ``1 / CHORD_CONTRACTION``; if that fails, plain Newton restarts from the original `q`.
    On return, `linear_solver` holds the factorization of the Jacobian at the converged q.
    `factor`, if given, factors the Jacobian just filled (a `_Factorizer`); by default
    ``linear_solver.factor(assembler.jacobian)``.  `restart`, if given, is a copy of the
    original `q` that the caller keeps anyway (the predictor); by default one is made.
    """
    if factor is None:
        factor = lambda: linear_solver.factor(assembler.jacobian)  # noqa: E731
    if chord:
        start = q.copy() if restart is None else restart
        corrections = _chord_newton(assembler, linear_solver, q, weights, tolerance, max_iterations, factor)
        if corrections is not None:
            return corrections
        q[:] = start
    previous_norm = np.inf
    for iteration in range(max_iterations + 1):
        assembler.fill_residual_jacobian(q)
        norm = _weighted_norm(assembler.residual, weights)
        if not np.isfinite(norm):
            raise _NoConvergence("the residual is not finite")
        factor()
        if norm <= tolerance:
            return iteration
        if iteration == max_iterations:
            break
        if iteration >= 3 and norm > 0.5 * previous_norm:
            raise _NoConvergence(f"Newton stalled after {iteration} corrections")
        previous_norm = norm
        q -= linear_solver.solve(assembler.residual)
    raise _NoConvergence(f"no convergence in {max_iterations} Newton corrections")


def _chord_newton(assembler, linear_solver, q, weights, tolerance, max_iterations, factor) -> int | None:
    """Chord corrections from `q` with the factorization at hand; None if they do not converge fast.

    At convergence the Jacobian at `q` is factored, as plain Newton leaves it, and one
    Newton correction with it polishes `q` (it moves `q` by less than the tolerance)
    unless the residual is already below ``POLISH_BELOW * tolerance``.
    """
    previous_norm = np.inf
    for iteration in range(max_iterations + 1):
        assembler.fill_residual_jacobian(q)
        norm = _weighted_norm(assembler.residual, weights)
        if norm <= tolerance:
            factor()
            if iteration and norm > POLISH_BELOW * tolerance:
                # Chord corrections converge linearly and stop anywhere below the tolerance;
                # one Newton correction with the fresh factorization takes q to full
                # accuracy, as plain Newton's quadratic convergence does.
                q -= linear_solver.solve(assembler.residual)
                return iteration + 1
            return iteration
        if not norm <= CHORD_CONTRACTION * previous_norm or iteration == max_iterations:  # also NaN
            return None
        previous_norm = norm
        try:
            q -= linear_solver.solve(assembler.residual)
        except SingularMatrix:
            return None
    return None


@njit(**_JIT)
def _weighted_norm(residual, weights):
    """max |residual| · weights, without temporaries; NaN if any entry is not finite."""
    norm = 0.0
    for r in range(residual.size):
        weighted = abs(residual[r]) * weights[r]
        if not weighted <= norm:  # larger, or NaN
            if not math.isfinite(weighted):
                return math.nan
            norm = weighted
    return norm


@njit(**_JIT)
def _first_branch_jump(times, coordinates, velocities, accelerations, weights, stop, ratio, min_defect, min_correction):
    """The first sample below `stop` whose step from the previous one fails `_jumped`; `stop` if none."""
    predicted = np.empty(coordinates.shape[1])
    for k in range(1, stop):
        h = times[k] - times[k - 1]
        for i in range(predicted.size):
            predicted[i] = coordinates[k - 1, i] + h * velocities[k - 1, i] + 0.5 * h * h * accelerations[k - 1, i]
        if _jumped(
            h, coordinates[k - 1], velocities[k - 1], accelerations[k - 1], coordinates[k], velocities[k],
            accelerations[k], predicted, weights, ratio, min_defect, min_correction,
        ):  # fmt: skip
            return k
    return stop


@njit(**_JIT)
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


def _checked_times(times, mechanism: Mechanism) -> np.ndarray:
    try:
        array = np.array(times, dtype=float)  # a copy, C-contiguous: the compiled loop reads it
    except (TypeError, ValueError):
        raise ValueError(f"`times` must be an array of numbers, got {type(times).__name__}.") from None
    if array.ndim != 1 or array.size == 0:
        raise ValueError(f"`times` must be a non-empty 1-D array, got shape {array.shape}.")
    if not np.all(np.isfinite(array)):
        raise ValueError("`times` must be finite.")
    if np.any(np.diff(array) <= 0.0):
        raise ValueError("`times` must be strictly increasing.")
    for k, driver in enumerate(mechanism.drivers):
        if isinstance(driver.law, Spline):
            first, last = driver.law.time_range
            if array[0] < first or array[-1] > last:
                raise ValueError(
                    f"`times` span [{array[0]:g}, {array[-1]:g}] s but drivers[{k}].law, a spline, is "
                    f"defined on [{first:g}, {last:g}] s."
                )
    return array


def _checked_tolerance(value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"`tolerance` must be a positive number, got {value!r}.")
    low, high = TOLERANCE_RANGE
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"`tolerance` must be a number in [{low:.3g}, {high:g}], got {value!r}.")
    return float(value)
