"""From a `Mechanism` to arrays: constraint parameters, the CSR pattern and its slots.

Every joint and driver is built from three kinds of constraint equation, each with one
numba kernel in `sparsekin._kernels`:

* **point coincidence** (2 rows): a point fixed in body i coincides with a point fixed in
  body j. A revolute joint is one; a rigid joint is one plus a coordinate difference.
* **projected distance** (1 row): the vector from a point of body i to a point of body j,
  projected on a unit vector fixed in body i. With the normal of a translational joint's
  axis it keeps the second body on the line (target 0); with the axis itself it is the
  stroke that a translational driver prescribes.
* **coordinate difference** (1 row): ``q[a] - q[b]``; the relative angle of a
  translational or rigid joint, a rotational driver, or an absolute driver (``b`` is a
  coordinate of the ground, which is always zero).

Each equation reads ``g(q) = target``.  The targets of joints are constants; those of
drivers follow their laws in time.

The ground is stored as body ``n_bodies``: its coordinates are appended to the coordinate
vector as zeros, and the Jacobian entries of its columns go to one discard slot at
``data[nnz]``, past the end of the CSR values.  So the kernels need no branches.

The pattern of the Jacobian is computed here once: ``indptr`` and ``indices`` (sorted
within rows), and for every entry of every equation its slot in the CSR ``data``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import (
    COORDINATE_NAMES,
    GROUND,
    AbsoluteDriver,
    Mechanism,
    Revolute,
    Rigid,
    RotationalDriver,
    Translational,
    TranslationalDriver,
)

__all__ = ["ConstraintPattern", "PointMap", "build_pattern", "build_point_map"]

#: Column offsets, within the 6 coordinates (x_i, y_i, angle_i, x_j, y_j, angle_j) of two
#: bodies, of the 8 Jacobian entries of a point coincidence (rows x then y).
_COINCIDENCE_COLUMNS = np.array([0, 2, 3, 5, 1, 2, 4, 5])
_COINCIDENCE_ROW_OFFSETS = np.array([0, 0, 0, 0, 1, 1, 1, 1])

#: Names of the equations each element contributes, in row order.
EQUATION_NAMES = {
    "revolute": ("x", "y"),
    "translational": ("relative angle", "offset from the axis"),
    "rigid": ("x", "y", "relative angle"),
}


@dataclass(frozen=True, eq=False)
class ConstraintPattern:
    """Constraint parameters and the CSR pattern of the Jacobian of a mechanism.

    Body indices run over ``0 .. n_bodies`` where ``n_bodies`` is the ground.  Local
    vectors are in body frames, m.  ``*_slots`` give, for each equation and each of its
    Jacobian entries, the position in the CSR ``data`` (``nnz`` for a ground column).

    Attributes
    ----------
    coincidence_row, coincidence_body_i, coincidence_body_j : ndarray, shape (n_c,)
        First of the two rows; the two bodies.
    coincidence_local_i, coincidence_local_j : ndarray, shape (n_c, 2)
        The point in body i's frame and in body j's frame.
    coincidence_slots : ndarray, shape (n_c, 8)
    projection_row, projection_body_i, projection_body_j : ndarray, shape (n_p,)
    projection_local_i, projection_local_j, projection_direction : ndarray, shape (n_p, 2)
        Start point (body i), end point (body j), unit vector (body i).
    projection_slots : ndarray, shape (n_p, 6)
    difference_row, difference_plus, difference_minus : ndarray, shape (n_d,)
        Row and the two coordinate indices of ``q[plus] - q[minus]``.
    difference_slots : ndarray, shape (n_d, 2)
    target : ndarray, shape (n_equations,)
        Constant targets of joint equations (0 on driver rows).
    row_is_angle : ndarray of bool, shape (n_equations,)
        Rows measured in rad; the others are in m.
    driver_row, driver_initial : ndarray, shape (n_drivers,)
        Row of each driver and the initial value of its driven quantity.
    element_first_row : ndarray, shape (n_joints + n_drivers + 1,)
        First row of each joint, then of each driver, then the number of rows.
    indptr, indices : ndarray
        CSR pattern of the Jacobian, shape (n_equations, n_coordinates).
    initial_coordinates : ndarray, shape (n_coordinates,)
        Frames of the bodies in the initial configuration.
    length_scale : float
        Size of the model, m: the largest coordinate magnitude of its points (at least
        1e-3). Convergence tests measure lengths relative to it.
    """

    n_bodies: int
    n_equations: int
    coincidence_row: np.ndarray
    coincidence_body_i: np.ndarray
    coincidence_body_j: np.ndarray
    coincidence_local_i: np.ndarray
    coincidence_local_j: np.ndarray
    coincidence_slots: np.ndarray
    projection_row: np.ndarray
    projection_body_i: np.ndarray
    projection_body_j: np.ndarray
    projection_local_i: np.ndarray
    projection_local_j: np.ndarray
    projection_direction: np.ndarray
    projection_slots: np.ndarray
    difference_row: np.ndarray
    difference_plus: np.ndarray
    difference_minus: np.ndarray
    difference_slots: np.ndarray
    target: np.ndarray
    row_is_angle: np.ndarray
    driver_row: np.ndarray
    driver_initial: np.ndarray
    element_first_row: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    initial_coordinates: np.ndarray
    length_scale: float

    @property
    def n_coordinates(self) -> int:
        return 3 * self.n_bodies

    @property
    def nnz(self) -> int:
        return int(self.indptr[-1])


class _Collector:
    """Gathers equations, in row order, as the elements of a mechanism are visited."""

    def __init__(self, mechanism: Mechanism) -> None:
        self.mechanism = mechanism
        n = mechanism.n_bodies
        self.frames = np.zeros((n + 1, 3))
        for index, body in enumerate(mechanism.bodies):
            self.frames[index] = mechanism.frame(body.name)
        self.ground = n
        self.row = 0
        self.coincidence: list[tuple[int, int, int, float, float]] = []
        self.projection: list[tuple[int, int, int, float, float, float, float, float, float]] = []
        self.difference: list[tuple[int, int, int, float]] = []
        self.angle_rows: list[int] = []

    def body(self, name: str) -> int:
        return self.ground if name == GROUND else self.mechanism.body_index(name)

    def add_coincidence(self, body_i: int, body_j: int, x: float, y: float) -> None:
        self.coincidence.append((self.row, body_i, body_j, x, y))
        self.row += 2

    def add_projection(self, body_i: int, body_j: int, start, end, direction) -> None:
        self.projection.append((self.row, body_i, body_j, *start, *end, *direction))
        self.row += 1

    def add_difference(self, plus: int, minus: int, target: float, is_angle: bool) -> None:
        self.difference.append((self.row, plus, minus, target))
        if is_angle:
            self.angle_rows.append(self.row)
        self.row += 1

    def relative_angle(self, body_i: int, body_j: int) -> float:
        return float(self.frames[body_i, 2] - self.frames[body_j, 2])


def _translational_geometry(mechanism: Mechanism, joint: Translational):
    """Start point, end point and unit axis of a translational joint, global, initial."""
    if joint.axis is not None:
        start = np.asarray(mechanism.position(joint.axis[0]), dtype=float)
        end = np.asarray(mechanism.position(joint.axis[1]), dtype=float)
        axis = end - start
    else:
        start = end = np.asarray(mechanism.position(joint.at), dtype=float)
        axis = np.asarray(joint.direction, dtype=float)
    return start, end, axis / np.hypot(*axis)


def build_pattern(mechanism: Mechanism) -> ConstraintPattern:
    """Compute the constraint parameters and the Jacobian pattern of `mechanism`.

    The system need not be square: a mechanism with free motions or redundant
    equations has a pattern too (the solvers refuse it, the diagnostics study it).
    """
    collect = _Collector(mechanism)
    element_first_row = []
    for joint in mechanism.joints:
        element_first_row.append(collect.row)
        i, j = collect.body(joint.bodies[0]), collect.body(joint.bodies[1])
        if isinstance(joint, Revolute):
            collect.add_coincidence(i, j, *mechanism.position(joint.at))
        elif isinstance(joint, Translational):
            start, end, axis = _translational_geometry(mechanism, joint)
            angle_i = 3 * i + 2
            collect.add_difference(angle_i, 3 * j + 2, collect.relative_angle(i, j), True)
            normal = np.array([-axis[1], axis[0]])
            collect.add_projection(i, j, start, end, normal)
        elif isinstance(joint, Rigid):
            collect.add_coincidence(i, j, *collect.frames[j, :2])
            collect.add_difference(3 * i + 2, 3 * j + 2, collect.relative_angle(i, j), True)
    driver_initial = []
    for driver in mechanism.drivers:
        element_first_row.append(collect.row)
        if isinstance(driver, TranslationalDriver):
            joint = mechanism.joint_named(driver.joint)
            i, j = collect.body(joint.bodies[0]), collect.body(joint.bodies[1])
            start, end, axis = _translational_geometry(mechanism, joint)
            driver_initial.append(float(np.dot(end - start, axis)))
            collect.add_projection(i, j, start, end, axis)
        elif isinstance(driver, RotationalDriver):
            i, j = collect.body(driver.bodies[0]), collect.body(driver.bodies[1])
            driver_initial.append(collect.relative_angle(i, j))
            collect.add_difference(3 * i + 2, 3 * j + 2, 0.0, True)
        elif isinstance(driver, AbsoluteDriver):
            i = collect.body(driver.body)
            k = COORDINATE_NAMES.index(driver.coordinate)
            driver_initial.append(float(collect.frames[i, k]))
            collect.add_difference(3 * i + k, 3 * collect.ground + k, 0.0, k == 2)
    element_first_row.append(collect.row)

    return _assemble_pattern(collect, mechanism, np.array(element_first_row), driver_initial)


def _assemble_pattern(collect: _Collector, mechanism, element_first_row, driver_initial):
    n = mechanism.n_bodies
    frames = collect.frames

    coincidence = np.array(collect.coincidence, dtype=float).reshape(-1, 5)
    c_row = coincidence[:, 0].astype(np.int64)
    c_i = coincidence[:, 1].astype(np.int64)
    c_j = coincidence[:, 2].astype(np.int64)
    c_local_i = _to_local(frames[c_i], coincidence[:, 3:5])
    c_local_j = _to_local(frames[c_j], coincidence[:, 3:5])

    projection = np.array(collect.projection, dtype=float).reshape(-1, 9)
    p_row = projection[:, 0].astype(np.int64)
    p_i = projection[:, 1].astype(np.int64)
    p_j = projection[:, 2].astype(np.int64)
    p_local_i = _to_local(frames[p_i], projection[:, 3:5])
    p_local_j = _to_local(frames[p_j], projection[:, 5:7])
    p_direction = _rotate(projection[:, 7:9], -frames[p_i, 2])

    difference = np.array(collect.difference, dtype=float).reshape(-1, 4)
    d_row = difference[:, 0].astype(np.int64)
    d_plus = difference[:, 1].astype(np.int64)
    d_minus = difference[:, 2].astype(np.int64)

    # (row, column) of every Jacobian entry, equation by equation, in kernel slot order.
    c_columns = np.where(_COINCIDENCE_COLUMNS < 3, 3 * c_i[:, None], 3 * c_j[:, None] - 3) + _COINCIDENCE_COLUMNS
    c_rows = c_row[:, None] + _COINCIDENCE_ROW_OFFSETS
    p_columns = np.concatenate([3 * p_i[:, None] + np.arange(3), 3 * p_j[:, None] + np.arange(3)], axis=1)
    p_rows = np.repeat(p_row[:, None], 6, axis=1)
    d_columns = np.stack([d_plus, d_minus], axis=1)
    d_rows = np.repeat(d_row[:, None], 2, axis=1)
    rows = np.concatenate([c_rows.ravel(), p_rows.ravel(), d_rows.ravel()])
    columns = np.concatenate([c_columns.ravel(), p_columns.ravel(), d_columns.ravel()])

    n_coordinates = 3 * n
    kept = columns < n_coordinates
    order = np.argsort(rows[kept] * n_coordinates + columns[kept], kind="stable")
    nnz = order.size
    slots = np.full(rows.size, nnz, dtype=np.int64)
    slots[np.flatnonzero(kept)[order]] = np.arange(nnz)
    indices = columns[kept][order].astype(np.int32 if n_coordinates < 2**31 - 1 else np.int64)
    indptr = np.zeros(collect.row + 1, dtype=indices.dtype)
    np.cumsum(np.bincount(rows[kept], minlength=collect.row), out=indptr[1:])
    c_end = c_rows.size
    p_end = c_end + p_rows.size

    target = np.zeros(collect.row)
    target[d_row] = difference[:, 3]
    row_is_angle = np.zeros(collect.row, dtype=bool)
    row_is_angle[np.array(collect.angle_rows, dtype=np.int64)] = True

    all_points = np.array(list(mechanism.points.values()), dtype=float).reshape(-1, 2)
    length_scale = max(float(np.abs(all_points).max(initial=0.0)), float(np.abs(frames[:, :2]).max(initial=0.0)), 1e-3)
    return ConstraintPattern(
        n_bodies=n,
        n_equations=collect.row,
        coincidence_row=c_row,
        coincidence_body_i=c_i,
        coincidence_body_j=c_j,
        coincidence_local_i=c_local_i,
        coincidence_local_j=c_local_j,
        coincidence_slots=slots[:c_end].reshape(-1, 8),
        projection_row=p_row,
        projection_body_i=p_i,
        projection_body_j=p_j,
        projection_local_i=p_local_i,
        projection_local_j=p_local_j,
        projection_direction=p_direction,
        projection_slots=slots[c_end:p_end].reshape(-1, 6),
        difference_row=d_row,
        difference_plus=d_plus,
        difference_minus=d_minus,
        difference_slots=slots[p_end:].reshape(-1, 2),
        target=target,
        row_is_angle=row_is_angle,
        driver_row=element_first_row[len(mechanism.joints) : -1].astype(np.int64),
        driver_initial=np.array(driver_initial, dtype=float),
        element_first_row=element_first_row,
        indptr=indptr,
        indices=indices,
        initial_coordinates=frames[:n].ravel().copy(),
        length_scale=length_scale,
    )


def _rotate(vectors: np.ndarray, angles: np.ndarray) -> np.ndarray:
    cosine, sine = np.cos(angles), np.sin(angles)
    return np.stack(
        [cosine * vectors[:, 0] - sine * vectors[:, 1], sine * vectors[:, 0] + cosine * vectors[:, 1]], axis=1
    )


def _to_local(frames: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Coordinates in the given body frames (x, y, angle) of global points."""
    return _rotate(points - frames[:, :2], -frames[:, 2])


@dataclass(frozen=True, eq=False)
class PointMap:
    """Where each named point rides: its body (``-1`` for the ground) and local position.

    Attributes
    ----------
    names : tuple of str
    body : ndarray of int, shape (n_points,)
    local : ndarray, shape (n_points, 2)
        Position in the body frame, m (global position for a ground point).
    """

    names: tuple[str, ...]
    body: np.ndarray
    local: np.ndarray

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(name) from None


def build_point_map(mechanism: Mechanism) -> PointMap:
    """Each named point on the first body that lists it; unlisted points on the ground."""
    carrier: dict[str, int] = {}
    for index, body in enumerate(mechanism.bodies):
        for point in body.points:
            carrier.setdefault(point, index)
    names = tuple(mechanism.points)
    body = np.array([carrier.get(point, -1) for point in names], dtype=np.int64)
    positions = np.array([mechanism.points[point] for point in names], dtype=float).reshape(-1, 2)
    frames = np.zeros((len(names), 3))
    on_body = body >= 0
    frames[on_body] = np.array([mechanism.frame(mechanism.bodies[b].name) for b in body[on_body]]).reshape(-1, 3)
    return PointMap(names=names, body=body, local=_to_local(frames, positions))
