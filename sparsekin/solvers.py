"""Kinematic analysis: positions by Newton–Raphson, then velocities and accelerations.

At each time t the positions q solve Phi(q, t) = 0 by Newton–Raphson from a Taylor
predictor built on the previous sample.  The factorization of the Jacobian Phi_q at the
converged position then serves two more solves:

    Phi_q · qd  = -Phi_t        (velocities)
    Phi_q · qdd = gamma         (accelerations)

Convergence is judged on the residual, lengths relative to the size of the model (so a
chain 10^4 m long converges as surely as a 1 m linkage) and angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .assembly import Assembler
from .errors import ConvergenceError, ModelError, SingularJacobianError
from .laws import Spline
from .linalg import SingularMatrix, SuperLUSolver
from .model import COORDINATE_NAMES, Mechanism
from .pattern import EQUATION_NAMES, ConstraintPattern, PointMap, build_pattern, build_point_map

__all__ = ["KinematicsResult", "PointMotion", "solve_kinematics"]

#: Most Newton corrections at one time sample.
NEWTON_MAXITER = 12
#: Default convergence tolerance: the largest residual, lengths relative to the model size
#: and angles in rad.  Near the rounding floor, so that positions carry full accuracy.
DEFAULT_TOLERANCE = 1e-12
#: Models up to this many coordinates get a dense diagnosis of a singular Jacobian.
_DIAGNOSIS_MAX_COORDINATES = 3000
#: How many drivers and constraints an error message lists.
_LISTED = 4


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
        Newton corrections at each time.
    n_factorizations, n_solves : int
        Factorizations of the Jacobian and linear solves in the whole run.
    complete : bool
        False when the analysis stopped early: then only the samples solved are here.
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
) -> KinematicsResult:
    """Positions, velocities and accelerations of `mechanism` at `times`.

    Parameters
    ----------
    mechanism : Mechanism
        A mechanism with as many equations (joints and drivers) as coordinates.
    times : array_like, shape (n_times,)
        Strictly increasing sample times, s.  The first sample starts Newton from the
        initial configuration of the model.
    tolerance : float
        Largest accepted residual: lengths relative to the size of the model, angles in
        rad.
    max_iterations : int
        Most Newton corrections at one time.

    Returns
    -------
    KinematicsResult

    Raises
    ------
    ModelError
        If the mechanism does not have as many equations as coordinates.
    ConvergenceError, SingularJacobianError
        If a sample cannot be solved; ``error.result`` holds the samples before it.

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
    times = _checked_times(times, mechanism)
    tolerance = _checked_positive(tolerance, "tolerance")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) or max_iterations < 1:
        raise ValueError(f"`max_iterations` must be a whole number >= 1, got {max_iterations!r}.")
    pattern = build_pattern(mechanism)
    if pattern.n_equations != pattern.n_coordinates:
        raise ModelError(_degrees_of_freedom_message(pattern.n_coordinates, pattern.n_equations, len(mechanism.drivers)))
    assembler = Assembler(mechanism, pattern)
    linear_solver = SuperLUSolver()
    weights = np.where(pattern.row_is_angle, 1.0, 1.0 / pattern.length_scale)

    n_times, n_coordinates = times.size, pattern.n_coordinates
    coordinates = np.empty((n_times, n_coordinates))
    velocities = np.empty((n_times, n_coordinates))
    accelerations = np.empty((n_times, n_coordinates))
    iterations = np.zeros(n_times, dtype=np.int64)

    def result(n_solved: int) -> KinematicsResult:
        return KinematicsResult(
            times=times[:n_solved],
            coordinates=coordinates[:n_solved],
            velocities=velocities[:n_solved],
            accelerations=accelerations[:n_solved],
            body_names=mechanism.body_names,
            newton_iterations=iterations[:n_solved],
            n_factorizations=linear_solver.n_factorizations,
            n_solves=linear_solver.n_solves,
            complete=n_solved == n_times,
            point_map=build_point_map(mechanism),
        )

    for k, t in enumerate(times):
        q = coordinates[k]  # Newton refines the predictor in place, in its row of the result
        if k == 0:
            q[:] = pattern.initial_coordinates
        else:  # Taylor predictor from the previous sample
            h = t - times[k - 1]
            np.multiply(velocities[k - 1], h, out=q)
            q += coordinates[k - 1]
            q += (0.5 * h * h) * accelerations[k - 1]
        assembler.set_time(t)
        try:
            iterations[k] = _solve_positions(assembler, linear_solver, q, weights, tolerance, max_iterations)
            velocities[k] = linear_solver.solve(assembler.velocity_rhs)
            assembler.fill_acceleration_rhs(q, velocities[k])
            accelerations[k] = linear_solver.solve(assembler.acceleration_rhs)
        except _NoConvergence as failure:
            raise ConvergenceError(
                _failure_message(mechanism, pattern, assembler, t, failure.reason, weights),
                time=float(t),
                driver_values=_driver_values(mechanism, assembler),
                result=result(k),
            ) from None
        except SingularMatrix as error:
            raise SingularJacobianError(
                _failure_message(mechanism, pattern, assembler, t, "singular Jacobian", weights, singular=True),
                time=float(t),
                driver_values=_driver_values(mechanism, assembler),
                result=result(k),
            ) from error
    return result(n_times)


class _NoConvergence(Exception):
    def __init__(self, reason: str) -> None:
        self.reason = reason


def _solve_positions(assembler, linear_solver, q, weights, tolerance, max_iterations):
    """Newton–Raphson from `q`, which it refines in place; returns the number of corrections.

    On return, `linear_solver` holds the factorization of the Jacobian at the converged q.
    """
    previous_norm = np.inf
    for iteration in range(max_iterations + 1):
        assembler.fill_residual_jacobian(q)
        norm = float(np.max(np.abs(assembler.residual) * weights, initial=0.0))
        if not np.isfinite(norm):
            raise _NoConvergence("the residual is not finite")
        linear_solver.factor(assembler.jacobian)
        if norm <= tolerance:
            return iteration
        if iteration == max_iterations:
            break
        if iteration >= 3 and norm > 0.5 * previous_norm:
            raise _NoConvergence(f"Newton stalled after {iteration} corrections")
        previous_norm = norm
        q -= linear_solver.solve(assembler.residual)
    raise _NoConvergence(f"no convergence in {max_iterations} Newton corrections")


def _checked_times(times, mechanism: Mechanism) -> np.ndarray:
    try:
        array = np.asarray(times, dtype=float)
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


def _degrees_of_freedom_message(n_coordinates: int, n_equations: int, n_drivers: int) -> str:
    free = n_coordinates - n_equations
    if free > 0:
        return (
            f"{n_coordinates} coordinates but {n_equations} equations: {free} degree(s) of freedom "
            f"left after the {n_drivers} driver(s); expected one driver per degree of freedom"
        )
    return (
        f"{n_coordinates} coordinates but {n_equations} equations: {-free} more equation(s) than "
        "coordinates; expected as many equations as coordinates (remove redundant joints or drivers)"
    )


def _checked_positive(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"`{name}` must be a positive number, got {value!r}.")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"`{name}` must be a positive finite number, got {value!r}.")
    return float(value)


# ---------------------------------------------------------------------- messages
def _driver_values(mechanism: Mechanism, assembler: Assembler) -> dict[str, float]:
    return {
        mechanism.element_label("drivers", k): float(value) for k, value in enumerate(assembler.driver_values)
    }


def equation_label(mechanism: Mechanism, pattern: ConstraintPattern, row: int) -> str:
    """``joints[2] (revolute c4–c1 at A), equation y``: the element and equation of a row."""
    element = int(np.searchsorted(pattern.element_first_row, row, side="right")) - 1
    within = row - int(pattern.element_first_row[element])
    n_joints = len(mechanism.joints)
    if element < n_joints:
        label = mechanism.element_label("joints", element)
        equation = EQUATION_NAMES[mechanism.joints[element].type_name][within]
    else:
        label = mechanism.element_label("drivers", element - n_joints)
        equation = "driven value"
    return f"{label}, equation {equation}"


def coordinate_label(mechanism: Mechanism, column: int) -> str:
    """``c3.angle``: the body and coordinate of a column."""
    return f"{mechanism.bodies[column // 3].name}.{COORDINATE_NAMES[column % 3]}"


def _failure_message(mechanism, pattern, assembler, t, reason, weights, singular=False) -> str:
    drivers = _driver_values(mechanism, assembler)
    shown = "; ".join(f"{label} = {value:.6g}" for label, value in list(drivers.items())[:_LISTED])
    if len(drivers) > _LISTED:
        shown += f"; … ({len(drivers)} drivers)"
    message = f"{reason} at t = {t:.6g} s (drivers: {shown or 'none'})"
    if singular and pattern.n_coordinates <= _DIAGNOSIS_MAX_COORDINATES:
        message += _singular_diagnosis(mechanism, pattern, assembler)
    elif assembler.residual.size:
        worst = int(np.argmax(np.abs(assembler.residual) * weights))
        message += (
            f"; largest residual {abs(assembler.residual[worst]):.3g} in "
            f"{equation_label(mechanism, pattern, worst)}"
        )
    return message


def _singular_diagnosis(mechanism, pattern, assembler) -> str:
    """The motion the constraints no longer control and the constraints involved."""
    left, singular_values, right = np.linalg.svd(assembler.jacobian.toarray())
    motion, equations = right[-1], left[:, -1]
    moving = np.argsort(-np.abs(motion))[:_LISTED]
    involved = np.argsort(-np.abs(equations))[:_LISTED]
    moving = [coordinate_label(mechanism, c) for c in moving if abs(motion[c]) > 0.1 * np.abs(motion).max()]
    involved = [
        equation_label(mechanism, pattern, r) for r in involved if abs(equations[r]) > 0.1 * np.abs(equations).max()
    ]
    return (
        f"; smallest singular value {singular_values[-1]:.3g}; uncontrolled motion of "
        f"{', '.join(moving)}; constraints involved: {'; '.join(involved)}"
    )
