"""The four primitive constraint equations that every joint and driver is made of.

Each equation reads ``g(q) = target``.  An element kind (`sparsekin.model.elements`) says which
primitives it is made of by returning *blocks*: arrays of parameters, one entry per
element, in the global coordinates of the drawn (initial) configuration, which is how a
user thinks of them.  `pack` turns the blocks of a whole mechanism into the packed,
body-local arrays the numba kernels of `sparsekin.engine._kernels` read, together with the CSR
pattern of the Jacobian and the slot of every Jacobian entry in the CSR values.

=================  ====  ==========================================================
primitive          rows  g(q)
=================  ====  ==========================================================
`Coincidence`      2     point fixed in body i minus point fixed in body j (x, y)
`Projection`       1     n · (point of j - point of i) + rolling · (angle_j - angle_i),
                         with n a unit vector fixed in body i
`Combination`      1     sum of coefficient · coordinate, over a few coordinates
`Distance`         1     | point of j - point of i |
=================  ====  ==========================================================

Bodies are numbered ``0 .. n_bodies - 1``, and ``n_bodies`` stands for the ground: its
coordinates are stored as a body of zeros after the others, and the Jacobian entries of
its columns go to one discard slot at ``data[nnz]``, so that the kernels need no branch.
A point "fixed in body i that starts at P" has the local coordinates of P in the drawn
frame of body i.  Joints hold their drawn values (`initial_values`); drivers' targets
follow their laws.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .._jit import JIT
from .geometry import LocalCoordinates

__all__ = [
    "Coincidence",
    "Projection",
    "Combination",
    "Distance",
    "BLOCK_ROWS",
    "CoincidenceArrays",
    "ProjectionArrays",
    "CombinationArrays",
    "DistanceArrays",
    "Primitives",
    "PackedEquations",
    "pack",
    "initial_values",
]


# ---------------------------------------------------------------------- blocks (what kinds emit)
class Coincidence(NamedTuple):
    """Rows ``row`` (x) and ``row + 1`` (y): the point of body i that starts at `point_i`
    coincides with the point of body j that starts at `point_j`.

    ``row, body_i, body_j``: int arrays, shape (k,); ``point_i, point_j``: (k, 2), m.
    """

    row: np.ndarray
    body_i: np.ndarray
    body_j: np.ndarray
    point_i: np.ndarray
    point_j: np.ndarray


class Projection(NamedTuple):
    """Row ``row``: ``n · (end on j - start on i) + rolling · (angle_j - angle_i)``.

    ``direction`` (k, 2) is the unit vector n in the drawn configuration; it turns with
    body i.  ``start`` is fixed in body i, ``end`` in body j (drawn positions, m);
    ``rolling`` (k,) in m per rad (0 for a plain projection).
    """

    row: np.ndarray
    body_i: np.ndarray
    body_j: np.ndarray
    start: np.ndarray
    end: np.ndarray
    direction: np.ndarray
    rolling: np.ndarray


class Combination(NamedTuple):
    """Row ``row``: ``sum over w of coefficient[:, w] · q[body[:, w], coordinate[:, w]]``.

    ``body, coordinate, coefficient``: shape (k, w), w terms per row; coordinate 0, 1, 2
    is x, y, angle.  Terms on the ground contribute nothing and are dropped.
    """

    row: np.ndarray
    body: np.ndarray
    coordinate: np.ndarray
    coefficient: np.ndarray


class Distance(NamedTuple):
    """Row ``row``: the distance from the point of i that starts at `point_i` to the point
    of j that starts at `point_j` (m).  The drawn distance must not be zero."""

    row: np.ndarray
    body_i: np.ndarray
    body_j: np.ndarray
    point_i: np.ndarray
    point_j: np.ndarray


#: Rows of each block entry.
BLOCK_ROWS = {Coincidence: 2, Projection: 1, Combination: 1, Distance: 1}


# ---------------------------------------------------------------------- packed (what kernels read)
class CoincidenceArrays(NamedTuple):
    body_i: np.ndarray  # int64 (k,)
    body_j: np.ndarray
    local_i: np.ndarray  # float64 (k, 2): the point in body i's frame
    local_j: np.ndarray
    row: np.ndarray  # int64 (k,): first of the two rows
    # int32 (int64 if nnz does not fit), (k, 8): x_i, angle_i, x_j, angle_j (row x),
    # then y_i, angle_i, y_j, angle_j
    slots: np.ndarray


class ProjectionArrays(NamedTuple):
    body_i: np.ndarray
    body_j: np.ndarray
    local_i: np.ndarray  # start, in body i's frame
    local_j: np.ndarray  # end, in body j's frame
    direction: np.ndarray  # unit vector in body i's frame
    rolling: np.ndarray  # float64 (k,)
    row: np.ndarray
    slots: np.ndarray  # (k, 6): x_i, y_i, angle_i, x_j, y_j, angle_j


class CombinationArrays(NamedTuple):
    start: np.ndarray  # int64 (k + 1,): terms of row e are start[e] .. start[e + 1] - 1
    column: np.ndarray  # int64 (m,): coordinate index of each term
    coefficient: np.ndarray  # float64 (m,)
    row: np.ndarray
    slots: np.ndarray  # (m,), the dtype of the others


class DistanceArrays(NamedTuple):
    body_i: np.ndarray
    body_j: np.ndarray
    local_i: np.ndarray
    local_j: np.ndarray
    row: np.ndarray
    slots: np.ndarray  # (k, 6) as for a projection


class Primitives(NamedTuple):
    """Every equation of a system, packed by primitive: the one argument of the kernels."""

    coincidence: CoincidenceArrays
    projection: ProjectionArrays
    combination: CombinationArrays
    distance: DistanceArrays

    def with_slots(self, positions: np.ndarray) -> Primitives:
        """The same equations writing entry k of the Jacobian to ``positions[k]`` instead.

        `positions` has the nnz + 1 entries of a permutation of the values followed by
        the discard slot.  The slots keep their dtype (the positions are below nnz + 1 too).
        """
        def moved(slots: np.ndarray) -> np.ndarray:
            return positions[slots].astype(slots.dtype, copy=False)

        return Primitives(*(arrays._replace(slots=moved(arrays.slots)) for arrays in self))


class PackedEquations(NamedTuple):
    """A system of equations ready for the kernels: `Primitives`, the CSR pattern, units.

    Attributes
    ----------
    primitives : Primitives
    indptr, indices : ndarray
        CSR pattern of the Jacobian, shape (n_rows, 3 · n_bodies), column indices sorted
        within rows.
    initial : ndarray, shape (n_rows,)
        g at the drawn configuration (m or rad).
    row_is_angle : ndarray of bool, shape (n_rows,)
        Rows measured in rad (combinations of angles only); the others are in m.
    """

    primitives: Primitives
    indptr: np.ndarray
    indices: np.ndarray
    initial: np.ndarray
    row_is_angle: np.ndarray


#: Column offsets within (x_i, y_i, angle_i, x_j, y_j, angle_j) of the 8 entries of a
#: coincidence, and their rows relative to its first row.
_COINCIDENCE_COLUMNS = np.array([0, 2, 3, 5, 1, 2, 4, 5])
_COINCIDENCE_ROW_OFFSETS = np.array([0, 0, 0, 0, 1, 1, 1, 1])


def pack(blocks, n_rows: int, frames: np.ndarray, shapes=None) -> PackedEquations:
    """Pack the blocks of a system of `n_rows` equations for the kernels.

    Parameters
    ----------
    blocks : iterable of Coincidence, Projection, Combination, Distance
        Every row ``0 .. n_rows - 1`` must be given by exactly one block entry.
    n_rows : int
    frames : ndarray, shape (n_bodies + 1, 3)
        Drawn frames ``(x, y, angle)`` of the bodies, the ground last (zeros).
    shapes : BodyShapes, optional
        The bodies with `lengths` (`sparsekin.model.lengths`): their points sit where their
        shape puts them, not where they are drawn.

    Returns
    -------
    PackedEquations
    """
    n = frames.shape[0] - 1
    blocks = list(blocks)
    merged = {kind: _merged([block for block in blocks if type(block) is kind], kind, n) for kind in BLOCK_ROWS}
    c, p, m, d = merged[Coincidence], merged[Projection], merged[Combination], merged[Distance]

    # Combination terms: one per (entry, w), the ground's dropped.
    terms = m.body < n
    counts = terms.sum(axis=1)
    term_start = np.zeros(m.row.size + 1, dtype=np.int64)
    np.cumsum(counts, out=term_start[1:])
    term_column = (3 * m.body + m.coordinate)[terms].astype(np.int64)
    term_coefficient = m.coefficient[terms].astype(float)

    # (row, column) of every Jacobian entry, block by block, in kernel slot order (one kernel:
    # at 10^6 bodies numpy's (k, 8) arrays, their sums and concatenations were ~0.6 GB of
    # fresh memory, whose first touch was most of the start's `pack`)
    n_entries = 8 * c.row.size + 6 * (p.row.size + d.row.size) + term_column.size
    entry_index = np.int32 if max(3 * n + 6, n_rows, n_entries) < 2**31 - 1 else np.int64
    rows, columns = np.empty(n_entries, dtype=entry_index), np.empty(n_entries, dtype=entry_index)
    _entry_rows_columns((c.row, c.body_i, c.body_j), (p.row, p.body_i, p.body_j), (m.row, counts), term_column,
                        (d.row, d.body_i, d.body_j), (_COINCIDENCE_COLUMNS, _COINCIDENCE_ROW_OFFSETS), rows, columns)  # fmt: skip

    n_coordinates = 3 * n
    # int32 when every index fits: half the memory traffic (the slots too: they are below nnz
    # + 1, the discard slot); made so when the entries' count says so (nnz is at most that:
    # at 10^6 bodies three int64 arrays and their casts were 0.1 s of the start)
    index = np.int32 if max(n_coordinates, rows.size) < 2**31 - 1 else np.int64
    indptr = np.zeros(n_rows + 1, dtype=np.int64)  # (cast after: made int32, the 10^6 start's peak was 8 MB higher)
    slots = np.empty(rows.size, dtype=index)
    indices = _csr_pattern(rows, columns, n_coordinates, indptr, slots)
    if max(n_coordinates, indices.size) < 2**31 - 1:
        indices, indptr, slots = (array.astype(np.int32, copy=False) for array in (indices, indptr, slots))
    ends = np.cumsum([8 * c.row.size, 6 * p.row.size, term_column.size])

    drawn_local = LocalCoordinates(frames)

    def local(frame, points, turn_only=False):
        out = drawn_local(frame, points, turn_only)
        if shapes and not turn_only:
            shapes.correct(frame, points, out)
        return out

    primitives = Primitives(
        CoincidenceArrays(
            _ints(c.body_i), _ints(c.body_j), local(c.body_i, c.point_i), local(c.body_j, c.point_j), _ints(c.row),
            slots[: ends[0]].reshape(-1, 8),
        ),
        ProjectionArrays(
            _ints(p.body_i), _ints(p.body_j), local(p.body_i, p.start), local(p.body_j, p.end),
            local(p.body_i, p.direction, turn_only=True), _floats(p.rolling), _ints(p.row),
            slots[ends[0] : ends[1]].reshape(-1, 6),
        ),
        CombinationArrays(term_start, term_column, term_coefficient, _ints(m.row), slots[ends[1] : ends[2]].copy()),
        DistanceArrays(
            _ints(d.body_i), _ints(d.body_j), local(d.body_i, d.point_i), local(d.body_j, d.point_j), _ints(d.row),
            slots[ends[2] :].reshape(-1, 6),
        ),
    )  # fmt: skip
    row_is_angle = np.zeros(n_rows, dtype=bool)
    row_is_angle[m.row] = np.all((m.coordinate == 2) | (m.body >= n), axis=1)
    initial = initial_values(c, p, m, d, frames, n_rows)
    return PackedEquations(primitives, indptr, indices, initial, row_is_angle)


def initial_values(c: Coincidence, p: Projection, m: Combination, d: Distance, frames, n_rows) -> np.ndarray:
    """g of every row at the drawn configuration, from the blocks' global parameters."""
    value = np.zeros(n_rows)
    value[c.row] = c.point_i[:, 0] - c.point_j[:, 0]
    value[c.row + 1] = c.point_i[:, 1] - c.point_j[:, 1]
    value[p.row] = np.einsum("ij,ij->i", p.direction, p.end - p.start) + p.rolling * (
        frames[p.body_j, 2] - frames[p.body_i, 2]
    )
    value[m.row] = np.einsum("ij,ij->i", m.coefficient, frames[m.body, m.coordinate])
    value[d.row] = np.hypot(*(d.point_j - d.point_i).T)
    return value


def _merged(blocks, kind, ground: int):
    """One block of `kind` with the entries of all `blocks` (an empty one if none).

    Combination blocks may differ in their number of terms; the narrower ones are padded
    with terms on the `ground` (which `pack` drops).
    """
    if not blocks:
        return kind(*(_empty(name, kind) for name in kind._fields))
    if kind is Combination:
        width = max(block.body.shape[1] for block in blocks)
        blocks = [
            Combination(block.row, *(_padded(array, width, value) for array, value in
                                     ((block.body, ground), (block.coordinate, 0), (block.coefficient, 0.0))))
            for block in blocks
        ]  # fmt: skip
    return kind(*(np.concatenate([getattr(block, name) for block in blocks]) for name in kind._fields))


def _padded(array: np.ndarray, width: int, value) -> np.ndarray:
    return np.pad(array, ((0, 0), (0, width - array.shape[1])), constant_values=value)


def _empty(name: str, kind) -> np.ndarray:
    if name in ("point_i", "point_j", "start", "end", "direction"):
        return np.zeros((0, 2))
    if kind is Combination and name != "row":
        return np.zeros((0, 1), dtype=float if name == "coefficient" else np.int64)
    return np.zeros(0, dtype=float if name == "rolling" else np.int64)


@njit(**JIT)
def _entry_rows_columns(coincidences, projections, combinations, term_column, distances, coincidence_layout, rows,
                        columns):  # fmt: skip
    """The row and column of every Jacobian entry, in kernel slot order, into `rows` and
    `columns`: a coincidence's 8 (`_COINCIDENCE_COLUMNS` within ``(x_i, y_i, angle_i, x_j,
    y_j, angle_j)`` on the rows `_COINCIDENCE_ROW_OFFSETS` after its first), a projection's
    6 (those six), each combination's terms (`term_column`, ``counts`` of them on its row),
    a distance's 6.  ``coincidences`` and the others are ``(row, body_i, body_j)``,
    ``combinations`` ``(row, counts)``; the ground's columns are from ``3 n_bodies`` on."""
    offsets, row_offsets = coincidence_layout
    row, body_i, body_j = coincidences
    e = 0
    for k in range(row.size):
        for s in range(offsets.size):
            offset = offsets[s]
            rows[e] = row[k] + row_offsets[s]
            columns[e] = 3 * body_i[k] + offset if offset < 3 else 3 * body_j[k] - 3 + offset
            e += 1
    row, body_i, body_j = projections
    e = _pair_entries(row, body_i, body_j, rows, columns, e)
    row, counts = combinations
    t = 0
    for k in range(row.size):
        for _ in range(counts[k]):
            rows[e] = row[k]
            columns[e] = term_column[t]
            e += 1
            t += 1
    row, body_i, body_j = distances
    _pair_entries(row, body_i, body_j, rows, columns, e)


@njit(**JIT)
def _pair_entries(row, body_i, body_j, rows, columns, e):
    """A projection's or a distance's six entries (x_i, y_i, angle_i, x_j, y_j, angle_j) for
    each of its rows, from entry `e` on; returns the entry after them."""
    for k in range(row.size):
        for s in range(3):
            rows[e], columns[e] = row[k], 3 * body_i[k] + s
            e += 1
        for s in range(3):
            rows[e], columns[e] = row[k], 3 * body_j[k] + s
            e += 1
    return e


@njit(**JIT)
def _csr_pattern(rows, columns, n_columns, indptr, slots):
    """CSR pattern of the entries (rows[e], columns[e]) with columns below `n_columns`.

    Fills `indptr` (n_rows + 1) and, for every entry, its position in the CSR values
    (`slots`; entries in a column from `n_columns` on — the ground's — get the discard
    position nnz); returns `indices` (of `slots`' dtype), sorted within rows.  Linear time:
    a counting sort by row, then an insertion sort of each row's few entries by column.
    """
    n_rows = indptr.size - 1
    for e in range(rows.size):
        if columns[e] < n_columns:
            indptr[rows[e] + 1] += 1
    for r in range(n_rows):
        indptr[r + 1] += indptr[r]
    nnz = indptr[n_rows]
    indices = np.empty(nnz, dtype=slots.dtype)
    entry = np.empty(nnz, dtype=slots.dtype)  # the entry at each position
    # row r's next free place in indptr[r] (no scratch array of n_rows), moved back after
    for e in range(rows.size):
        if columns[e] < n_columns:
            position = indptr[rows[e]]
            indices[position] = columns[e]
            entry[position] = e
            indptr[rows[e]] += 1
        else:
            slots[e] = nnz
    for r in range(n_rows, 0, -1):
        indptr[r] = indptr[r - 1]
    indptr[0] = 0
    for r in range(n_rows):
        for position in range(indptr[r] + 1, indptr[r + 1]):
            column, moved = indices[position], entry[position]
            before = position - 1
            while before >= indptr[r] and indices[before] > column:
                indices[before + 1], entry[before + 1] = indices[before], entry[before]
                before -= 1
            indices[before + 1], entry[before + 1] = column, moved
    for position in range(nnz):
        slots[entry[position]] = position
    return indices


def _ints(array) -> np.ndarray:
    return np.ascontiguousarray(array, dtype=np.int64)


def _floats(array) -> np.ndarray:
    return np.ascontiguousarray(array, dtype=np.float64)
