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

from dataclasses import dataclass, field

import numpy as np

from .model import (
    COORDINATE_NAMES,
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


def build_pattern(mechanism: Mechanism) -> ConstraintPattern:
    """Compute the constraint parameters and the Jacobian pattern of `mechanism`.

    The system need not be square: a mechanism with free motions or redundant
    equations has a pattern too (the solvers refuse it, the diagnostics study it).
    Each kind of element is gathered in one pass and turned into arrays at once, so the
    cost is a few list comprehensions per element kind: linear in the model size.
    """
    n = mechanism.n_bodies
    joints, drivers = mechanism.joints, mechanism.drivers
    frames = np.zeros((n + 1, 3))  # the ground is stored as body n, with zero coordinates
    frames[:n, :2] = mechanism.positions([body.origin for body in mechanism.bodies])
    frames[:n, 2] = [body.angle for body in mechanism.bodies]

    counts = [element.n_equations for element in joints] + [1] * len(drivers)
    element_first_row = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=element_first_row[1:])
    n_equations = int(element_first_row[-1])
    joint_rows, driver_rows = element_first_row[: len(joints)], element_first_row[len(joints) : -1]

    def of_kind(elements, kind):
        return [k for k, element in enumerate(elements) if isinstance(element, kind)]

    def stored_index(names):
        index = mechanism.body_indices(names)
        index[index < 0] = n
        return index

    def bodies_of(elements, picked):
        return stored_index([body for k in picked for body in elements[k].bodies]).reshape(-1, 2).T

    revolute, translational, rigid = (of_kind(joints, kind) for kind in (Revolute, Translational, Rigid))
    stroke, rotational, absolute = (
        of_kind(drivers, kind) for kind in (TranslationalDriver, RotationalDriver, AbsoluteDriver)
    )

    # Point coincidences: revolute joints at their point, rigid joints at body j's origin.
    revolute_i, revolute_j = bodies_of(joints, revolute)
    rigid_i, rigid_j = bodies_of(joints, rigid)
    revolute_at = mechanism.positions([joints[k].at for k in revolute])
    c_row = np.concatenate([joint_rows[revolute], joint_rows[rigid]])
    c_i = np.concatenate([revolute_i, rigid_i])
    c_j = np.concatenate([revolute_j, rigid_j])
    c_point = np.concatenate([revolute_at, frames[rigid_j, :2]])

    # Projected distances: translational joints on the normal, strokes along the axis.
    slide_i, slide_j = bodies_of(joints, translational)
    slide_start, slide_end, slide_axis = _translational_geometry(mechanism, [joints[k] for k in translational])
    stroke_joints = [mechanism.joint_named(drivers[k].joint) for k in stroke]
    stroke_i, stroke_j = bodies_of(stroke_joints, range(len(stroke_joints)))
    stroke_start, stroke_end, stroke_axis = _translational_geometry(mechanism, stroke_joints)
    p_row = np.concatenate([joint_rows[translational] + 1, driver_rows[stroke]])
    p_i = np.concatenate([slide_i, stroke_i])
    p_j = np.concatenate([slide_j, stroke_j])
    p_start = np.concatenate([slide_start, stroke_start])
    p_end = np.concatenate([slide_end, stroke_end])
    p_direction_global = np.concatenate([np.stack([-slide_axis[:, 1], slide_axis[:, 0]], axis=1), stroke_axis])

    # Coordinate differences: relative angles of translational and rigid joints and of
    # rotational drivers, and the coordinate of an absolute driver minus the ground's.
    turn_i, turn_j = bodies_of(drivers, rotational)
    absolute_body = stored_index([drivers[k].body for k in absolute])
    absolute_coordinate = np.array(
        [COORDINATE_NAMES.index(drivers[k].coordinate) for k in absolute], dtype=np.int64
    )
    angle_i = np.concatenate([slide_i, rigid_i, turn_i])
    angle_j = np.concatenate([slide_j, rigid_j, turn_j])
    d_row = np.concatenate([joint_rows[translational], joint_rows[rigid] + 2, driver_rows[rotational], driver_rows[absolute]])
    d_plus = np.concatenate([3 * angle_i + 2, 3 * absolute_body + absolute_coordinate])
    d_minus = np.concatenate([3 * angle_j + 2, 3 * n + absolute_coordinate])

    target = np.zeros(n_equations)
    n_joint_angles = len(translational) + len(rigid)
    target[d_row[:n_joint_angles]] = frames[angle_i[:n_joint_angles], 2] - frames[angle_j[:n_joint_angles], 2]
    row_is_angle = np.zeros(n_equations, dtype=bool)
    row_is_angle[d_row[: angle_i.size]] = True
    row_is_angle[driver_rows[absolute][absolute_coordinate == 2]] = True

    driver_initial = np.zeros(len(drivers))
    driver_initial[stroke] = np.einsum("ij,ij->i", stroke_end - stroke_start, stroke_axis)
    driver_initial[rotational] = frames[turn_i, 2] - frames[turn_j, 2]
    driver_initial[absolute] = frames[absolute_body, absolute_coordinate]

    return _assemble_pattern(
        mechanism, frames, n_equations, element_first_row, driver_initial, target, row_is_angle,
        (c_row, c_i, c_j, c_point), (p_row, p_i, p_j, p_start, p_end, p_direction_global), (d_row, d_plus, d_minus),
    )  # fmt: skip


def _translational_geometry(mechanism: Mechanism, joints) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start points, end points and unit axes of translational joints, global, initial.

    Each has shape (len(joints), 2).  For the ``at`` / ``direction`` form the start and
    end are both the point ``at``.
    """
    references = [point for joint in joints for point in (joint.axis if joint.axis is not None else (joint.at, joint.at))]
    geometry = mechanism.positions(references).reshape(-1, 4)
    start, end = geometry[:, :2], geometry[:, 2:]
    axis = end - start
    at_form = np.array([joint.axis is None for joint in joints], dtype=bool)
    if at_form.any():
        axis[at_form] = np.array([joint.direction for joint in joints if joint.axis is None], dtype=float)
    return start, end, axis / np.hypot(axis[:, 0], axis[:, 1])[:, None]


def _assemble_pattern(
    mechanism, frames, n_equations, element_first_row, driver_initial, target, row_is_angle,
    coincidence, projection, difference,
) -> ConstraintPattern:  # fmt: skip
    """Local constraint parameters, and the CSR pattern with every equation's slots."""
    n = mechanism.n_bodies
    c_row, c_i, c_j, c_point = coincidence
    c_local_i = _to_local(frames[c_i], c_point)
    c_local_j = _to_local(frames[c_j], c_point)
    p_row, p_i, p_j, p_start, p_end, p_direction_global = projection
    p_local_i = _to_local(frames[p_i], p_start)
    p_local_j = _to_local(frames[p_j], p_end)
    p_direction = _rotate(p_direction_global, -frames[p_i, 2])
    d_row, d_plus, d_minus = difference

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
    order = _row_major_order(rows[kept], columns[kept], n_equations)
    nnz = order.size
    slots = np.full(rows.size, nnz, dtype=np.int64)
    slots[np.flatnonzero(kept)[order]] = np.arange(nnz)
    indices = columns[kept][order].astype(np.int32 if n_coordinates < 2**31 - 1 else np.int64)
    indptr = np.zeros(n_equations + 1, dtype=indices.dtype)
    np.cumsum(np.bincount(rows[kept], minlength=n_equations), out=indptr[1:])
    c_end = c_rows.size
    p_end = c_end + p_rows.size

    all_points = np.array(list(mechanism.points.values()), dtype=float).reshape(-1, 2)
    length_scale = max(float(np.abs(all_points).max(initial=0.0)), float(np.abs(frames[:, :2]).max(initial=0.0)), 1e-3)
    return ConstraintPattern(
        n_bodies=n,
        n_equations=n_equations,
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
        driver_row=element_first_row[len(mechanism.joints) : -1].copy(),
        driver_initial=driver_initial,
        element_first_row=element_first_row,
        indptr=indptr,
        indices=indices,
        initial_coordinates=frames[:n].ravel().copy(),
        length_scale=length_scale,
    )


def _row_major_order(rows: np.ndarray, columns: np.ndarray, n_rows: int) -> np.ndarray:
    """The permutation that sorts entries by row, then column, in linear time.

    Two stable counting sorts (by column, then by row) in place of one comparison sort:
    numpy's stable argsort of small-range integers is a radix sort.
    """
    by_column = np.argsort(columns, kind="stable")
    return by_column[np.argsort(rows[by_column], kind="stable")]


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
    _index: dict[str, int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_index", {name: k for k, name in enumerate(self.names)})

    def index(self, name: str) -> int:
        """Position of point `name` in `names`; KeyError if there is none."""
        return self._index[name]


def build_point_map(mechanism: Mechanism) -> PointMap:
    """Each named point on the first body that lists it; unlisted points on the ground."""
    carrier: dict[str, int] = {}
    for index, body in enumerate(mechanism.bodies):
        for point in body.points:
            carrier.setdefault(point, index)
    names = tuple(mechanism.points)
    body = np.fromiter((carrier.get(point, -1) for point in names), dtype=np.int64, count=len(names))
    positions = mechanism.positions(names)
    frames = np.zeros((len(names), 3))
    on_body = body >= 0
    if on_body.any():
        bodies = mechanism.bodies
        carriers = np.flatnonzero(on_body)
        frames[carriers, :2] = mechanism.positions([bodies[b].origin for b in body[carriers]])
        frames[carriers, 2] = [bodies[b].angle for b in body[carriers]]
    return PointMap(names=names, body=body, local=_to_local(frames, positions))
