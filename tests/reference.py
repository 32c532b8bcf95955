"""Slow NumPy references, written from the definitions of the model, not from the kernels.

`constraint_residual(mechanism, q, t)` evaluates every joint and driver equation of a
mechanism one element at a time, from global point positions.  It shares no code with
`sparsekin.engine.pattern` or `sparsekin.engine._kernels`; the tests compare those against it.
"""

from __future__ import annotations

import numpy as np

from sparsekin import (
    AbsoluteDriver,
    DistanceDriver,
    Gear,
    Mechanism,
    PathDriver,
    PinInSlot,
    RackPinion,
    Revolute,
    Rigid,
    RotationalDriver,
    Translational,
    TranslationalDriver,
)


def rotation(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


def frame(mechanism: Mechanism, q: np.ndarray, body: str):
    """Current (origin, angle) and initial (origin, angle) of a body frame."""
    initial = np.array(mechanism.frame(body))
    if body == "ground":
        return np.zeros(2), 0.0, initial[:2], initial[2]
    k = mechanism.body_index(body)
    return q[3 * k : 3 * k + 2], q[3 * k + 2], initial[:2], initial[2]


def position(mechanism: Mechanism, q: np.ndarray, body: str, point) -> np.ndarray:
    """Current global position of the material point of `body` that started at `point`."""
    origin, angle, origin0, angle0 = frame(mechanism, q, body)
    start = np.asarray(mechanism.position(point), dtype=float)
    return origin + rotation(angle - angle0) @ (start - origin0)


def turned(mechanism: Mechanism, q: np.ndarray, body: str, vector) -> np.ndarray:
    """A vector fixed in `body`, given in the initial configuration, now."""
    _, angle, _, angle0 = frame(mechanism, q, body)
    return rotation(angle - angle0) @ np.asarray(vector, dtype=float)


def axis_of(mechanism: Mechanism, joint: Translational):
    """(start point, end point, unit axis) of a translational joint, initial, global."""
    if joint.axis is not None:
        start, end = (np.asarray(mechanism.position(p), dtype=float) for p in joint.axis)
        direction = end - start
    else:
        start = end = np.asarray(mechanism.position(joint.at), dtype=float)
        direction = np.asarray(joint.direction, dtype=float)
    return start, end, direction / np.linalg.norm(direction)


def relative_angle(mechanism, q, body_i, body_j) -> float:
    return frame(mechanism, q, body_i)[1] - frame(mechanism, q, body_j)[1]


def unit(vector) -> np.ndarray:
    vector = np.asarray(vector, dtype=float)
    return vector / np.linalg.norm(vector)


def left_normal(vector) -> np.ndarray:
    return np.array([-vector[1], vector[0]])


def drawn_relative_angle(mechanism, body_i, body_j) -> float:
    return mechanism.frame(body_i)[2] - mechanism.frame(body_j)[2]


def constraint_residual(mechanism: Mechanism, q: np.ndarray, driver_values=None) -> np.ndarray:
    """All equations, joints then drivers; `driver_values` (one per driver equation) default
    to the initial values."""
    equations: list[float] = []
    for joint in mechanism.joints:
        i, j = joint.bodies
        if isinstance(joint, Revolute):
            equations += list(position(mechanism, q, i, joint.at) - position(mechanism, q, j, joint.at))
        elif isinstance(joint, Translational):
            start, end, axis = axis_of(mechanism, joint)
            normal = turned(mechanism, q, i, [-axis[1], axis[0]])
            offset = position(mechanism, q, j, end) - position(mechanism, q, i, start)
            angle0 = mechanism.frame(i)[2] - mechanism.frame(j)[2]
            equations += [relative_angle(mechanism, q, i, j) - angle0, float(normal @ offset)]
        elif isinstance(joint, Rigid):
            origin_j = mechanism.frame(j)[:2]
            equations += list(position(mechanism, q, i, origin_j) - position(mechanism, q, j, origin_j))
            equations.append(relative_angle(mechanism, q, i, j) - (mechanism.frame(i)[2] - mechanism.frame(j)[2]))
        elif isinstance(joint, PinInSlot):
            # the pin (on j) seen from the slot's point (on i), across the slot's line
            offset = position(mechanism, q, j, joint.at) - position(mechanism, q, i, joint.at)
            equations.append(float(turned(mechanism, q, i, left_normal(unit(joint.direction))) @ offset))
        elif isinstance(joint, Gear):
            k_body = joint.carrier
            turn = [relative_angle(mechanism, q, b, k_body) - drawn_relative_angle(mechanism, b, k_body) for b in (i, j)]
            equations.append(turn[0] + joint.ratio * turn[1])
        elif isinstance(joint, RackPinion):
            travel = float(turned(mechanism, q, i, unit(joint.direction))
                           @ (position(mechanism, q, j, joint.at) - position(mechanism, q, i, joint.at)))
            rotation = relative_angle(mechanism, q, j, i) - drawn_relative_angle(mechanism, j, i)
            equations.append(travel + joint.radius * rotation)
    n_joint_rows = len(equations)
    for driver in mechanism.drivers:
        if isinstance(driver, TranslationalDriver):
            joint = mechanism.joint_named(driver.joint)
            start, end, axis = axis_of(mechanism, joint)
            i, j = joint.bodies
            offset = position(mechanism, q, j, end) - position(mechanism, q, i, start)
            value = float(turned(mechanism, q, i, axis) @ offset)
            initial = float(axis @ (end - start))
        elif isinstance(driver, RotationalDriver):
            value = relative_angle(mechanism, q, *driver.bodies)
            initial = mechanism.frame(driver.bodies[0])[2] - mechanism.frame(driver.bodies[1])[2]
        elif isinstance(driver, AbsoluteDriver):
            coordinate = ("x", "y", "angle").index(driver.coordinate)
            k_body = mechanism.body_index(driver.body)
            value = q[3 * k_body + coordinate]
            initial = mechanism.frame(driver.body)[coordinate]
        elif isinstance(driver, DistanceDriver):
            (i, j), (p, r) = driver.bodies, driver.points
            value = float(np.linalg.norm(position(mechanism, q, j, r) - position(mechanism, q, i, p)))
            initial = float(np.linalg.norm(np.subtract(mechanism.position(r), mechanism.position(p))))
        elif isinstance(driver, PathDriver):
            # two equations: the point's x and y; `driver_values` gives one value per equation
            where = position(mechanism, q, driver.body, driver.point)
            drawn = np.asarray(mechanism.position(driver.point), dtype=float)
            targets = drawn if driver_values is None else driver_values[len(equations) - n_joint_rows :][:2]
            equations += list(where - targets)
            continue
        target = initial if driver_values is None else driver_values[len(equations) - n_joint_rows]
        equations.append(value - target)
    return np.array(equations)
