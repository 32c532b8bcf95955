"""From a `Mechanism` to arrays, once: the packed equations, the CSR pattern and its slots.

Each element kind (`sparsekin.model.elements`) returns its equations as blocks of the four
primitives of `sparsekin.model.primitives`; `build_pattern` gathers them kind by kind and packs
them (`sparsekin.model.primitives.pack`) into what the numba kernels read, with the CSR
pattern of the Jacobian (``indptr``, ``indices``, sorted within rows) and, for every
entry of every equation, its slot in the CSR ``data``.  The ground is stored as body
``n_bodies``: its coordinates are zeros appended to the coordinate vector, and the
Jacobian entries of its columns go to one discard slot at ``data[nnz]``, so the kernels
need no branches.

`build_output_pattern` does the same for the elements' own coordinates (a revolute's
relative angle, a cylinder's stroke), which the results evaluate with the same kernels.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..model.laws import LawPacker, LawTable
from ..model.mechanism import Mechanism
from ..model.primitives import PackedEquations, Primitives, pack
from .columns import ObjectColumns, Resolver, TiledColumns

__all__ = ["ConstraintPattern", "OutputPattern", "PointMap", "build_pattern", "build_output_pattern", "build_point_map",
           "element_columns", "per_element", "pack_element_laws"]


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
        The packed parameters and slots the kernels read (`sparsekin.engine._kernels`).
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
    ``J qdd - gamma`` (see `sparsekin.engine._kernels.fill_outputs`).

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


def _by_kind(elements) -> dict[type, list[int]]:
    """Indices of the elements of each kind, kinds in order of first appearance."""
    groups: dict[type, list[int]] = {}
    for index, element in enumerate(elements):
        groups.setdefault(type(element), []).append(index)
    return groups


def element_columns(mechanism: Mechanism, kind: str, first_rows: np.ndarray, resolver: Resolver):
    """``(element kind, indices, columns)`` for every group of joints, drivers or loads
    (`kind`) of one element kind: the model's own elements, then each repeat's over all its
    copies (`TiledColumns`, copy-major).  `indices` are the elements' positions in the
    model; `first_rows` gives the first row of each element in model order (-1 for one
    without rows)."""
    own = mechanism.own(kind)
    for element_kind, indices in _by_kind(own).items():
        indices = np.array(indices, dtype=np.int64)
        yield element_kind, indices, ObjectColumns([own[k] for k in indices], first_rows[indices], resolver)
    for copies in mechanism.copies:
        unit_elements = getattr(copies.unit, kind)
        placed = copies.placed(kind)
        for element_kind, indices in _by_kind(unit_elements).items():
            # elements in the same copies are tiled together; a grid's boundary parts apart
            groups: dict[bytes, list[int]] = {}
            for e in indices:
                if not len(placed[e][0]):  # in no copy (an open boundary along a grid's one column)
                    continue
                groups.setdefault(placed[e][0].tobytes() if len(placed[e][0]) < copies.count else b"", []).append(e)
            for group in groups.values():
                ks = placed[group[0]][0]
                positions = copies.first[kind] + np.stack([placed[e][1] for e in group], axis=1).ravel()
                columns = TiledColumns(copies, [unit_elements[e] for e in group], first_rows[positions], resolver, ks)
                yield element_kind, positions, columns


def _blocks(mechanism: Mechanism, kind: str, first_rows: np.ndarray, resolver: Resolver, method: str) -> list:
    """The blocks of every joint, driver or load (`kind`): each element kind's `method`
    (``equations``, ``outputs``, ``loads``), asked once for the model's own elements and
    once per repeat for all its copies (`element_columns`).

    An element kind without `method` (no own coordinate, say) produces nothing.
    """
    blocks = []
    for element_kind, _, columns in element_columns(mechanism, kind, first_rows, resolver):
        build = getattr(element_kind, method, None)
        if build is not None:
            blocks += build(columns)
    return blocks


def per_element(mechanism: Mechanism, kind: str, value) -> np.ndarray:
    """``value(element)`` for every joint, driver or load, in model order: the own elements',
    then each repeat's unit values tiled over its copies."""
    own = [value(element) for element in mechanism.own(kind)]
    tiled = []
    for copies in mechanism.copies:
        values = np.array([value(element) for element in getattr(copies.unit, kind)], dtype=np.int64)
        out = np.empty(copies.total(kind), dtype=np.int64)
        for e, (_, starts) in enumerate(copies.placed(kind)):
            out[starts] = values[e]
        tiled.append(out)
    return np.concatenate([np.array(own, dtype=np.int64), *tiled])


def pack_element_laws(mechanism: Mechanism, kind: str, initial: np.ndarray | None = None) -> tuple[LawTable, list, int]:
    """The laws of every driver (one per equation) or load (one per component) of
    `mechanism`, in model order: law k fills entry k of the values.

    A repeat's unit law is packed once for all its copies, with the values the repeat's
    ``vary`` gives its parameters in each copy.

    Parameters
    ----------
    kind : {"drivers", "loads"}
    initial : ndarray, shape (n_laws,), optional
        The drawn value of each law's quantity (a law whose offset or start is not given
        starts there); zeros by default (a load has no drawn value).

    Returns
    -------
    table : LawTable
        The built-in laws.
    others : list of (int, Law)
        The other laws, by entry (evaluated in Python).
    n_laws : int
    """
    packer = LawPacker()
    target = 0

    def drawn(targets: np.ndarray) -> np.ndarray:
        return np.zeros(targets.size) if initial is None else initial[targets]

    for element in mechanism.own(kind):
        for law in element.laws():
            packer.add(law, np.array([target]), drawn(np.array([target])))
            target += 1
    for copies in mechanism.copies:  # each unit law over the copies that have it, by arrays
        unit = getattr(copies.unit, kind)
        sizes = [len(element.laws()) for element in unit]
        for e, (element, (ks, starts)) in enumerate(zip(unit, copies.placed(kind, sizes))):
            laws = element.laws()
            variations = copies.law_variations(e) if kind == "drivers" else {}
            for c, (field_name, law) in enumerate(zip(getattr(element, "law_fields", ()) or [None] * len(laws), laws)):
                targets = target + starts + c
                varied = variations.get(field_name)
                varied = None if varied is None else {key: values[ks] for key, values in varied.items()}
                packer.add(law, targets, drawn(targets), varied)
        target += sum(n * size for n, size in zip(copies.having(kind), sizes))
    return packer.table(), packer.others, target


def limited_elements(mechanism: Mechanism) -> dict[str, list[int]]:
    """The indices of the joints and of the drivers that carry ``limits``, found from the
    declared elements (a repeat's unit once), without building its copies."""
    return {kind: np.flatnonzero(per_element(mechanism, kind, lambda e: getattr(e, "limits", None) is not None)).tolist()
            for kind in ("joints", "drivers")}  # fmt: skip


def build_pattern(mechanism: Mechanism) -> ConstraintPattern:
    """Compute the packed equations and the Jacobian pattern of `mechanism`.

    The system need not be square: a mechanism with free motions or redundant
    equations has a pattern too (the solvers refuse it, the diagnostics study it).
    Each kind builds the equations of all its elements at once — the model's own, then
    a repeated unit's over all its copies — so the cost is a few array operations per
    kind: linear in the model size, without an object per copy.
    """
    resolver = Resolver(mechanism)
    joint_counts = per_element(mechanism, "joints", lambda element: element.n_equations)
    driver_counts = per_element(mechanism, "drivers", lambda element: element.n_equations)
    counts = np.concatenate([joint_counts, driver_counts])
    element_first_row = np.zeros(counts.size + 1, dtype=np.int64)
    np.cumsum(counts, out=element_first_row[1:])
    n_equations = int(element_first_row[-1])
    n_joints = joint_counts.size
    blocks = _blocks(mechanism, "joints", element_first_row[:n_joints], resolver, "equations")
    blocks += _blocks(mechanism, "drivers", element_first_row[n_joints:-1], resolver, "equations")
    packed: PackedEquations = pack(blocks, n_equations, resolver.frames, mechanism.shapes)

    first_driven = int(element_first_row[n_joints])
    driven_row = np.arange(first_driven, n_equations, dtype=np.int64)
    driven_driver = np.repeat(np.arange(driver_counts.size, dtype=np.int64), driver_counts)
    target = packed.initial.copy()
    target[driven_row] = 0.0
    points = mechanism.points
    all_points = points.all_positions() if hasattr(points, "all_positions") else np.array(list(points.values()))
    length_scale = max(
        float(np.abs(all_points.reshape(-1, 2)).max(initial=0.0)),
        float(np.abs(resolver.frames[:, :2]).max(initial=0.0)),
        1e-3,
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
        initial_coordinates=resolver.frames[:-1].ravel().copy(),
        length_scale=length_scale,
    )


def build_output_pattern(mechanism: Mechanism, joints=None, drivers=None) -> OutputPattern:
    """The own coordinate of every joint and driver whose kind declares one, or of the
    joints and drivers of the given indices only (`joints`, `drivers`), in that order
    (an index given twice counts once)."""
    if joints is not None or drivers is not None:
        return _selected_outputs(mechanism, joints or (), drivers or ())
    resolver = Resolver(mechanism)
    has_output = np.concatenate([
        per_element(mechanism, kind, lambda element: bool(type(element).output_names)) for kind in ("joints", "drivers")
    ]).astype(bool)  # fmt: skip
    rows = np.cumsum(has_output, dtype=np.int64) - 1
    rows[~has_output] = -1
    n_joints = mechanism.n_joints
    row_of_joint, row_of_driver = rows[:n_joints], rows[n_joints:]
    blocks = _blocks(mechanism, "joints", row_of_joint, resolver, "outputs")
    blocks += _blocks(mechanism, "drivers", row_of_driver, resolver, "outputs")
    n_rows = int(has_output.sum())
    packed = pack(blocks, n_rows, resolver.frames, mechanism.shapes)
    return OutputPattern(
        n_rows, packed.primitives, packed.indptr, packed.indices, row_of_joint, row_of_driver, packed.row_is_angle
    )


def _selected_outputs(mechanism: Mechanism, joints, drivers) -> OutputPattern:
    """Output rows for a few chosen elements, built from them as objects; an element given
    twice has one row."""
    resolver = Resolver(mechanism)
    rows = {"joints": np.full(mechanism.n_joints, -1, dtype=np.int64),
            "drivers": np.full(mechanism.n_drivers, -1, dtype=np.int64)}  # fmt: skip
    blocks, n_rows = [], 0
    for kind, indices in (("joints", joints), ("drivers", drivers)):
        size = len(rows[kind])
        indices = list(dict.fromkeys(k + size if k < 0 else k for k in map(operator.index, indices)))  # one row each
        elements = [getattr(mechanism, kind)[k] for k in indices]
        for k, element in zip(indices, elements):
            if not type(element).output_names:
                raise ValueError(f"{kind}[{k}] is {element.type_name}, which has no coordinate of its own")
            rows[kind][k] = n_rows
            n_rows += 1
        for element_kind, group in _by_kind(elements).items():
            selected_rows = rows[kind][[indices[g] for g in group]]
            blocks += element_kind.outputs(ObjectColumns([elements[g] for g in group], selected_rows, resolver))
    packed = pack(blocks, n_rows, resolver.frames, mechanism.shapes)
    return OutputPattern(n_rows, packed.primitives, packed.indptr, packed.indices, rows["joints"], rows["drivers"],
                         packed.row_is_angle)  # fmt: skip


class PointMap:
    """Where each named point rides: its body (-1 for the ground) and its local position.

    A point rides on the first body that lists it, in the order of `Mechanism.bodies`
    (the model's own, then each repeat's copies); a point that no body lists is on the
    ground (its local position is then its global one).  Points of a repeated unit's
    copies are located by index arithmetic when asked, without a table of every point;
    a point of the model that a unit's body lists rides on that body of the unit's
    first copy (as in `Mechanism.expanded`) unless an earlier body lists it.

    Attributes
    ----------
    names : sequence of str
        Every point name, in the model's order.
    """

    def __init__(self, mechanism: Mechanism) -> None:
        self._mechanism = mechanism
        self.names = mechanism.points if not mechanism.copies else _Names(mechanism.points)
        self._carrier: dict[str, int] = {}
        for index, body in enumerate(mechanism.own("bodies")):
            for point in body.points:
                self._carrier.setdefault(point, index)
        self._unit_carriers = []
        self._model_carriers: dict[str, int] = {}  # model points that units' bodies list: copy 0's body
        for copies in mechanism.copies:
            carriers: dict[str, list[int]] = {}  # the unit's bodies that list each unit point, in order
            for index, body in enumerate(copies.unit.bodies):
                for point in body.points:
                    if point in copies.point_index:
                        carriers.setdefault(point, []).append(index)
                    elif copies.present("bodies", 0, index):  # copy 0 has that body
                        self._model_carriers.setdefault(point, copies.first_body + int(copies.slot("bodies", 0, index)))
            self._unit_carriers.append(carriers)
        self._frames: np.ndarray | None = None

    def locate(self, name: str) -> tuple[int, np.ndarray]:
        """``(body, local)`` of point `name`; KeyError if the model has no such point."""
        mechanism = self._mechanism
        position = np.asarray(mechanism.points[name], dtype=float)  # KeyError for an unknown name
        body = self._carrier.get(name, -1)
        if body < 0 and mechanism.copies:
            candidates = [self._model_carriers.get(name, -1)]
            located = mechanism.points.locate(name)
            if located is not None:
                copies, k, p = located
                listing = self._unit_carriers[copies.index].get(list(copies.unit.points)[p], ())
                unit_body = next((b for b in listing if copies.present("bodies", k, b)), -1)  # copy k has it
                if unit_body >= 0:
                    candidates.append(copies.first_body + int(copies.slot("bodies", k, unit_body)))
            body = min((c for c in candidates if c >= 0), default=-1)  # the first body that lists it
        if body < 0:
            return -1, position
        if self._frames is None:
            self._frames = mechanism.frames()
        return body, mechanism.local_points(np.array([body]), position[None], self._frames)[0]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(body, local)`` of every point, shapes (n_points,) and (n_points, 2)."""
        located = [self.locate(name) for name in self.names]
        return (np.array([body for body, _ in located], dtype=np.int64),
                np.array([local for _, local in located], dtype=float).reshape(-1, 2))  # fmt: skip


class _Names(Sequence):
    """The point names of a mechanism with repeats (a `~sparsekin.model.units.PointTable`), as a
    sequence: name i found by index arithmetic, not by walking the names before it."""

    def __init__(self, points) -> None:
        self._points = points
        self._own = tuple(points.own)
        self._unit_names = [tuple(copies.unit.points) for copies in points.copies]
        sizes = [len(self._own), *(c.count * len(names) for c, names in zip(points.copies, self._unit_names))]
        self._starts = np.cumsum([0, *sizes])

    def __len__(self) -> int:
        return int(self._starts[-1])

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        index = operator.index(index)
        if index < 0:
            index += len(self)
        if not 0 <= index < len(self):
            raise IndexError(f"point index {index} out of range")
        if index < len(self._own):
            return self._own[index]
        segment = int(np.searchsorted(self._starts, index, side="right")) - 1  # 1 + the repeat's position
        names = self._unit_names[segment - 1]
        within = index - int(self._starts[segment])
        return self._points.copies[segment - 1].name(within // len(names), names[within % len(names)])

    def __iter__(self):
        return iter(self._points)

    def __contains__(self, name) -> bool:
        return name in self._points


def build_point_map(mechanism: Mechanism) -> PointMap:
    """Where each named point of `mechanism` rides (see `PointMap`)."""
    return PointMap(mechanism)
