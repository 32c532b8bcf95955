"""Kinematic analysis: `solve_kinematics` validates, runs the time loop, returns the result.

At each time t the positions q solve Phi(q, t) = 0 by Newton–Raphson from a Taylor
predictor built on the previous sample.  The factorization of the Jacobian Phi_q at the
converged position then serves two more solves:

    Phi_q · qd  = -Phi_t        (velocities)
    Phi_q · qdd = gamma         (accelerations)

Convergence is judged on the residual, lengths relative to the size of the model (so a
chain 10^4 m long converges as surely as a 1 m linkage) and angles in radians.  The loop
itself is `sparsekin.stepper.KinematicStepper` (predictor, Newton, branch guard, step
halving, lock-up diagnosis); for small models `sparsekin._compiled` runs the same loop in
one numba call first and hands over to the stepper at any sample it cannot solve.

Linear solvers (the `linear_solver` argument; ``"auto"`` picks the fastest):

* ``"dense"`` — for small models, the whole time loop compiled with numba on a dense LU;
  a model it cannot run (a law of another kind, redundant equations) and any sample it
  cannot solve go to the Python loop with `DenseSolver`.
* ``"refactor"`` — `RefactorSolver`: the ordering and the L and U patterns are fixed by a
  first SuperLU factorization, every later factorization is a numeric refactorization.
* ``"superlu"`` — a fresh SuperLU factorization at every Newton iteration.

With ``"refactor"`` and ``"dense"`` the Newton corrections are *chord* corrections (see
`sparsekin.newton`).  Every path factors the Jacobian at the converged position, so
velocities and accelerations are solved with the Jacobian there, to the same accuracy.
"""

from __future__ import annotations

import warnings

import numpy as np

from ._compiled import solve_compiled, supports_compiled
from .errors import ConvergenceError, LimitWarning
from .laws import Spline
from .model import Mechanism
from .newton import DEFAULT_TOLERANCE, NEWTON_MAXITER
from .pattern import build_pattern, build_point_map
from .results import KinematicsResult, PointMotion
from .stepper import (
    COMPILED_MAX_COORDINATES,
    LINEAR_SOLVERS,
    KinematicStepper,
    checked_max_iterations,
    checked_tolerance,
    first_branch_jump,
)

__all__ = ["KinematicsResult", "PointMotion", "solve_kinematics"]


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
        rad; within `sparsekin.stepper.TOLERANCE_RANGE`.
    max_iterations : int
        Most Newton corrections at one time, at least 1.
    linear_solver : {"auto", "dense", "refactor", "superlu"}
        How the linear systems are solved (see the module docstring).  ``"auto"`` takes
        ``"dense"`` (the compiled loop) up to `COMPILED_MAX_COORDINATES` coordinates and
        ``"refactor"`` above, unless the refactorization's fill-in exceeds
        `~sparsekin.stepper.MAX_REFACTOR_FILL`: then SuperLU with chord Newton.  Every
        choice gives the same results to rounding.

    Returns
    -------
    KinematicsResult

    Raises
    ------
    TypeError, ValueError
        If an argument is not of the expected type, shape or range.
    ModelError
        If the mechanism's equations do not control every coordinate at the first sample
        (free motions, a driver that the joints already fix, a drawing at a singular
        configuration), or its redundant equations contradict each other or involve
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
    LimitWarning
        Once for each element with ``limits`` whose own coordinate leaves them, at the
        first sample outside.

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
    tolerance = checked_tolerance(tolerance)
    max_iterations = checked_max_iterations(max_iterations)
    if linear_solver not in LINEAR_SOLVERS:
        raise ValueError(f"`linear_solver` must be one of {', '.join(map(repr, LINEAR_SOLVERS))}, got {linear_solver!r}.")
    pattern = build_pattern(mechanism)
    n, n_times = pattern.n_coordinates, times.size
    if pattern.n_equations == 0 and n == 0:  # nothing to solve
        empty = np.zeros((n_times, 0))
        return KinematicsResult(
            times=times, coordinates=empty, velocities=empty.copy(), accelerations=empty.copy(), body_names=(),
            newton_iterations=np.zeros(n_times, dtype=np.int64), n_factorizations=0, n_solves=0, complete=True,
            point_map=build_point_map(mechanism), mechanism=mechanism,
        )  # fmt: skip
    stepper = KinematicStepper(
        mechanism, linear_solver=linear_solver, tolerance=tolerance, max_iterations=max_iterations, pattern=pattern
    )
    run = _Run(stepper, times)
    compiled = (
        (linear_solver == "dense" or (linear_solver == "auto" and n <= COMPILED_MAX_COORDINATES))
        and pattern.n_equations == n
        and supports_compiled(mechanism)
    )
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # non-finite values are checked
            result = run.solve(compiled)
    except ConvergenceError as error:
        _warn_of_limits(error.result)
        raise
    _warn_of_limits(result)
    return result


def _warn_of_limits(result: KinematicsResult) -> None:
    """A `LimitWarning` for each element that left its ``limits`` during the run."""
    mechanism = result.mechanism
    if any(getattr(element, "limits", None) is not None for kind in ("joints", "drivers")
           for element in mechanism.declared(kind)):  # fmt: skip
        for state in result.limit_crossings():
            warnings.warn(f"{state.label} left its limits: {state.quantity} {state.value:.6g} {state.unit} at "
                          f"t = {state.time:.6g} s, outside [{state.limits[0]:g}, {state.limits[1]:g}]",
                          LimitWarning, stacklevel=3)  # fmt: skip


class _Run:
    """The arrays of one run's results, filled by the compiled loop and the stepper."""

    def __init__(self, stepper: KinematicStepper, times: np.ndarray) -> None:
        self.stepper, self.times = stepper, times
        shape = (times.size, stepper.pattern.n_coordinates)
        self.coordinates, self.velocities, self.accelerations = np.empty(shape), np.empty(shape), np.empty(shape)
        self.iterations = np.zeros(times.size, dtype=np.int64)
        self.compiled_counts = (0, 0)  # factorizations and solves of the compiled loop
        self.path = stepper.path

    def solve(self, compiled: bool) -> KinematicsResult:
        stepper, times = self.stepper, self.times
        first = self._solve_compiled() if compiled else 0
        k = first
        try:
            if first == 0:
                self.iterations[0] = stepper.start(times[0])
                self._store(0)
                first = 1
            elif first < times.size:
                previous = first - 1
                stepper.resume(times[previous], self.coordinates[previous], self.velocities[previous],
                               self.accelerations[previous], first=(times[0], self.coordinates[0]))  # fmt: skip
            for k in range(first, times.size):
                self.iterations[k] = stepper.advance(times[k])
                self._store(k)
        except ConvergenceError as error:
            error.result = self.result(k)
            raise
        return self.result(times.size)

    def _store(self, k: int) -> None:
        stepper = self.stepper
        self.coordinates[k], self.velocities[k], self.accelerations[k] = (
            stepper.coordinates, stepper.velocities, stepper.accelerations
        )

    def _solve_compiled(self) -> int:
        """Run the compiled loop; the number of samples it solved that pass the branch guard."""
        stepper = self.stepper
        outcome = solve_compiled(
            stepper.mechanism, stepper.pattern, self.times, stepper.tolerance, stepper.max_iterations,
            self.coordinates, self.velocities, self.accelerations, self.iterations,
        )  # fmt: skip
        self.compiled_counts = (outcome.n_factorizations, outcome.n_solves)
        solved = first_branch_jump(
            self.times, self.coordinates, self.velocities, self.accelerations, stepper.pattern.coordinate_weights,
            outcome.n_solved,
        )
        self.path = "compiled" if solved == self.times.size else "compiled+dense"
        return solved

    def result(self, n_solved: int) -> KinematicsResult:
        stepper = self.stepper
        path = self.path if self.path.startswith("compiled") else stepper.path
        return KinematicsResult(
            times=self.times[:n_solved],
            coordinates=self.coordinates[:n_solved],
            velocities=self.velocities[:n_solved],
            accelerations=self.accelerations[:n_solved],
            body_names=stepper.mechanism.body_names,
            newton_iterations=self.iterations[:n_solved],
            n_factorizations=stepper.n_factorizations + self.compiled_counts[0],
            n_solves=stepper.n_solves + self.compiled_counts[1],
            complete=n_solved == self.times.size,
            point_map=build_point_map(stepper.mechanism),
            mechanism=stepper.mechanism,
            n_subdivisions=stepper.n_subdivisions,
            redundant_equations=tuple(stepper.diagnosis.label(row) for row in stepper.redundant_rows),
            n_refactorizations=stepper.n_refactorizations,
            linear_solver=path,
        )


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
    for driver in mechanism.declared("drivers"):
        for field_name in driver.law_fields:
            law = getattr(driver, field_name)
            if isinstance(law, Spline):
                first, last = law.time_range
                if array[0] < first or array[-1] > last:
                    raise ValueError(
                        f"`times` span [{array[0]:g}, {array[-1]:g}] s but the {field_name} of driver "
                        f"{driver.describe()!r}, a spline, is defined on [{first:g}, {last:g}] s."
                    )
    return array
