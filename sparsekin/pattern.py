"""From a `Mechanism` to arrays, once: the packed equations, the CSR pattern and its slots.

Each element kind (`sparsekin.elements`) returns its equations as blocks of the four
primitives of `sparsekin.primitives`; `build_pattern` gathers them kind by kind and packs
them (`sparsekin.primitives.pack`) into what the numba kernels read, with the CSR
pattern of the Jacobian (``indptr``, ``indices``, sorted within rows) and, for every
entry of every equation, its slot in the CSR ``data``.  The ground is stored as body
``n_bodies``: its coordinates are zeros appended to the coordinate vector, and the
Jacobian entries of its columns go to one discard slot at ``data[nnz]``, so the kernels
need no branches.

`build_output_pattern` does the same for the elements' own coordinates (a revolute's
relative angle, a cylinder's stroke), which the results evaluate with the same kernels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .geometry import to_local
from .model import Mechanism
from .primitives import PackedEquations, Primitives, pack

__all__ = ["ConstraintPattern", "OutputPattern", "PointMap", "build_pattern", "build_output_pattern", "build_point_map"]


@dataclass(frozen=True, eq=False)
class ConstraintPattern:
    """The constraint equations of a mechanism, packed, and the CSR pattern of their Jacobian.

    Rows are the joints' equations in model order, then the drivers'.  Every equation
    reads ``g(q) = target``: joints hold their drawn values; the rows of drivers (the
    *driven* rows) follow the drivers' laws.

    Attributes
    ----------
    n_bodies, n_equations : int
    primitives : Primitives
        The packed parameters and slots the kernels read (`sparsekin._kernels`).
    indptr, indices : ndarray
        CSR pattern of the Jacobian, shape (n_equations, n_coordinates).
    target : ndarray, shape (n_equations,)
        Constant targets: the drawn value of each joint row, 0 on driven rows.
    row_is_angle : ndarray of bool, shape (n_equations,)
        Rows measured in rad; the others are in m.
    driven_row : ndarray of int, shape (n_driven,)
        The row of each law of each driver, drivers in model order.
    driven_initial : ndarray, shape (n_driven,)
        The drawn value of each driven row: the laws' default offset.
    driven_driver : ndarray of int, shape (n_driven,)
        The driver of each driven row.
    element_first_row : ndarray, shape (n_joints + n_drivers + 1,)
        First row of each joint, then of each driver, then the number of rows.
    initial_coordinates : ndarray, shape (n_coordinates,)
        Frames of the bodies in the initial configuration.
    length_scale : float
        Size of the model, m: the largest coordinate magnitude of its points (at least
        1e-3).  Convergence tests measure lengths relative to it.
    """

    n_bodies: int
    n_equations: int
    primitives: Primitives
    indptr: np.ndarray
    indices: np.ndarray
    target: np.ndarray
    row_is_angle: np.ndarray
    driven_row: np.ndarray
    driven_initial: np.ndarray
    driven_driver: np.ndarray
    element_first_row: np.ndarray
    initial_coordinates: np.ndarray
    length_scale: float

    @property
    def n_coordinates(self) -> int:
        return 3 * self.n_bodies

    @property
    def nnz(self) -> int:
        return int(self.indptr[-1])

    @property
    def residual_weights(self) -> np.ndarray:
        """Weights that make residuals comparable: 1 for angles (rad), 1 / model size for lengths."""
        return np.where(self.row_is_angle, 1.0, 1.0 / self.length_scale)

    @property
    def coordinate_weights(self) -> np.ndarray:
        """The same for coordinates: 1 for angles, 1 / model size for x and y."""
        weights = np.full(self.n_coordinates, 1.0 / self.length_scale)
        weights[2::3] = 1.0
        return weights


@dataclass(frozen=True, eq=False)
class OutputPattern:
    """The own coordinates of the elements that have one, as a system of equations.

    Row r's value g(q) is the coordinate, its rate is ``J qd`` and its acceleration
    ``J qdd - gamma`` (see `sparsekin._kernels.fill_outputs`).

    Attributes
    ----------
    n_rows : int
    primitives : Primitives
    indptr, indices : ndarray
        CSR pattern of the outputs' Jacobian, shape (n_rows, n_coordinates).
    row_of_joint, row_of_driver : ndarray of int
        The row of each joint and driver, -1 for those without an own coordinate.
    row_is_angle : ndarray of bool, shape (n_rows,)
        Coordinates in rad; the others are in m.
    """

    n_rows: int
    primitives: Primitives
    indptr: np.ndarray
    indices: np.ndarray
    row_of_joint: np.ndarray
    row_of_driver: np.ndarray
    row_is_angle: np.ndarray


class _DrawnModel:
    """What element kinds may ask of the mechanism while they build their equations."""

    def __init__(self, mechanism: Mechanism) -> None:
        self._mechanism = mechanism
        self.ground = mechanism.n_bodies
        self.frames = np.zeros((self.ground + 1, 3))  # the ground last, with zero coordinates
        self.frames[:-1] = mechanism.frames()

    def bodies(self, names) -> np.ndarray:
        index = self._mechanism.body_indices(names)
        index[index < 0] = self.ground
        return index

    def pairs(self, elements) -> tuple[np.ndarray, np.ndarray]:
        both = self.bodies([body for element in elements for body in element.bodies]).reshape(-1, 2)
        return both[:, 0].copy(), both[:, 1].copy()

    def points(self, references) -> np.ndarray:
        return self._mechanism.positions(references)

    def joint(self, name: str):
        return self._mechanism.joint_named(name)


def _by_kind(elements) -> dict[type, list[int]]:
    """Indices of the elements of each kind, kinds in order of first appearance."""
    groups: dict[type, list[int]] = {}
    for index, element in enumerate(elements):
        groups.setdefault(type(element), []).append(index)
    return groups


def _blocks(elements, first_rows: np.ndarray, model: _DrawnModel, method: str) -> list:
    """The blocks of every element, asked of each kind once for all its elements."""
    blocks = []
    for kind, indices in _by_kind(elements).items():
        build = getattr(kind, method, None)
        if build is not None:
            blocks += build([elements[k] for k in indices], first_rows[indices], model)
    return blocks


def build_pattern(mechanism: Mechanism) -> ConstraintPattern:
    """Compute the packed equations and the Jacobian pattern of `mechanism`.

    The system need not be square: a mechanism with free motions or redundant
    equations has a pattern too (the solvers refuse it, the diagnostics study it).
    Each kind builds the equations of all its elements at once, so the cost is a few
    array operations per kind: linear in the model size.
    """
    model = _DrawnModel(mechanism)
    joints, drivers = mechanism.joints, mechanism.drivers
    counts = [element.n_equations for element in (*joints, *drivers)]
    element_first_row = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=element_first_row[1:])
    n_equations = int(element_first_row[-1])
    n_joints = len(joints)
    blocks = _blocks(joints, element_first_row[:n_joints], model, "equations")
    blocks += _blocks(drivers, element_first_row[n_joints:-1], model, "equations")
    packed: PackedEquations = pack(blocks, n_equations, model.frames)

    first_driven = int(element_first_row[n_joints])
    driven_row = np.arange(first_driven, n_equations, dtype=np.int64)
    driven_driver = np.repeat(np.arange(len(drivers), dtype=np.int64), counts[n_joints:])
    target = packed.initial.copy()
    target[driven_row] = 0.0
    all_points = np.array(list(mechanism.points.values()), dtype=float).reshape(-1, 2)
    length_scale = max(
        float(np.abs(all_points).max(initial=0.0)), float(np.abs(model.frames[:, :2]).max(initial=0.0)), 1e-3
    )
    return ConstraintPattern(
        n_bodies=mechanism.n_bodies,
        n_equations=n_equations,
        primitives=packed.primitives,
        indptr=packed.indptr,
        indices=packed.indices,
        target=target,
        row_is_angle=packed.row_is_angle,
        driven_row=driven_row,
        driven_initial=packed.initial[driven_row].copy(),
        driven_driver=driven_driver,
        element_first_row=element_first_row,
        initial_coordinates=model.frames[:-1].ravel().copy(),
        length_scale=length_scale,
    )


def build_output_pattern(mechanism: Mechanism) -> OutputPattern:
    """The own coordinate of every joint and driver whose kind declares one."""
    model = _DrawnModel(mechanism)
    has_output = [bool(type(element).output_names) for element in (*mechanism.joints, *mechanism.drivers)]
    rows = np.cumsum(has_output, dtype=np.int64) - 1
    rows[~np.array(has_output, dtype=bool)] = -1
    n_joints = len(mechanism.joints)
    row_of_joint, row_of_driver = rows[:n_joints], rows[n_joints:]
    blocks = _blocks(mechanism.joints, row_of_joint, model, "outputs")
    blocks += _blocks(mechanism.drivers, row_of_driver, model, "outputs")
    n_rows = int(sum(has_output))
    packed = pack(blocks, n_rows, model.frames)
    return OutputPattern(
        n_rows, packed.primitives, packed.indptr, packed.indices, row_of_joint, row_of_driver, packed.row_is_angle
    )


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
    frames = np.zeros((len(names), 3))
    on_body = body >= 0
    if on_body.any():
        frames[on_body] = mechanism.frames()[body[on_body]]
    return PointMap(names=names, body=body, local=to_local(frames, mechanism.positions(names)))
