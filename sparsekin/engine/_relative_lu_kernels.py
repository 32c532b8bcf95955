"""numba kernels of `RefactorSolver`'s factors on *relative* patterns: a byte a row.

The structural patterns of L and U (`_lu_kernels.analyse_lu_pattern`) keep their rows as
int32 indices, 4 bytes per entry, which a refactorization reads once and the solves read
only until the factors are compacted (`sparsekin.engine.compact_factors`).  Where every row
is within 127 of its column and no column holds more than 255 entries
(`_compact_lu_kernels.offsets_fit`: a chain's saddle matrix, whose order is local), the
rows are held as the compact factors hold theirs: the offset ``i - j`` of row i in column
j (int8) and each column's count (uint8), with the row pointers kept for the
refactorization's random access to L's columns.  At 10^6 bodies that is 3 bytes fewer per
entry: about 120 MB of the 3 GB of issue 25 (docs/design-notes.md, "Relative patterns").

U's columns are only read in order (the refactorization's and the solves' sweeps): its
row pointers are not held, its counts are.  `refactor_lu` and `refactor_lu_gathered` are
`_lu_kernels.refactor_lu` and `refactor_lu_gathered` on such patterns: the same operations
in the same order, so the same factors bit for bit; the solves before compaction are
`_compact_lu_kernels`' with the structural counts (every entry, zeros included: again the
same operations).  `refactor_lu_by_rows` is `refactor_lu_gathered` finding B's column j as
row ``column_of[j]`` of the CSR matrix (perm_c's inverse, which the compact solves hold
anyway) instead of through B's column pointers and offsets: at 10^6 bodies 48 MB fewer held
(docs/design-notes.md, "Memory at the end of the large run").
"""

from __future__ import annotations

import math

from numba import njit

from .._jit import JIT as _JIT
from ._lu_kernels import STAT_BAD_COLUMN, STAT_MAX_ABS_B, STAT_MAX_ABS_U, STAT_MIN_PIVOT_RATIO, STAT_NON_FINITE
from ._lu_kernels import _index, _wide, scatter_column


@njit(**_JIT)
def relative_pattern(indptr, indices, counts, offsets):
    """Fill `counts` (uint8, shape (n,)) and `offsets` (int8, as large as `indices`) from a
    compressed-column pattern that `_compact_lu_kernels.offsets_fit`."""
    for j in range(indptr.size - 1):
        counts[j] = indptr[j + 1] - indptr[j]
        for p in range(_wide(indptr[j]), _wide(indptr[j + 1])):
            offsets[p] = _wide(indices[p]) - j


@njit(**_JIT)
def rows_of(indptr, offsets, indices):
    """The absolute rows of a relative pattern, into `indices` (the inverse of `relative_pattern`)."""
    for j in range(indptr.size - 1):
        for p in range(_wide(indptr[j]), _wide(indptr[j + 1])):
            indices[p] = j + _wide(offsets[p])


@njit(**_JIT)
def refactor_lu(values, in_factor_order, b_pattern, lower, upper, work, stats):
    """`_lu_kernels.refactor_lu` with L's and U's rows as offsets from their columns:
    `lower` is ``(indptr, offsets, values)``, `upper` ``(counts, offsets, values, inverse
    of the diagonal)``."""
    _left_looking_lu(values, in_factor_order, b_pattern, None, None, lower, upper, work, stats)


@njit(**_JIT)
def refactor_lu_gathered(values, in_factor_order, b_pattern, rows, lower, upper, work, stats):
    """`_lu_kernels.refactor_lu_gathered` with L's and U's rows as offsets (`refactor_lu`)."""
    _left_looking_lu(values, in_factor_order, b_pattern, rows, None, lower, upper, work, stats)


@njit(**_JIT)
def refactor_lu_by_rows(values, csr, perm_r, column_of, lower, upper, work, stats):
    """`refactor_lu_gathered` with B's columns located through `column_of` instead of B's
    column pointers and offsets (two arrays of n fewer held): column j of B is row
    ``column_of[j]`` of the CSR matrix ``csr = (indptr, indices)`` whose transpose is
    factored, values ``values[indptr[c]:indptr[c + 1]]`` (CSR order) in rows
    ``perm_r[indices[p]]``: the same entries added in the same order, the same factors."""
    b_pattern = (csr[0], csr[1], column_of)  # (typed as `scatter_column`'s, which this specialization never calls)
    _left_looking_lu(values, False, b_pattern, (csr[1], perm_r), column_of, lower, upper, work, stats)


@njit(inline="always", **_JIT)
def _scatter_row(values, indptr, rows, c, work, max_b):
    """Row c of the CSR matrix (B's column ``perm_c[c]``) added into `work` at rows
    ``perm_r[indices[p]]``; returns the largest |entry| so far (`scatter_column`'s gathered
    form, the same run of values)."""
    indices, perm_r = rows
    for p in range(_wide(indptr[c]), _wide(indptr[c + 1])):
        value = values[p]
        work[_index(perm_r[_index(indices[p])])] += value
        max_b = max(max_b, abs(value))
    return max_b


@njit(**_JIT)
def _left_looking_lu(values, in_factor_order, b_pattern, rows, column_of, lower, upper, work, stats):
    """`_lu_kernels._left_looking_lu` (see there), L's and U's rows read as ``column + offset``;
    with `column_of` (`refactor_lu_by_rows`) ``b_pattern[0]`` is the CSR matrix's row pointers."""
    l_indptr, l_offsets, l_values = lower
    u_counts, u_offsets, u_values, u_inverse = upper
    n = u_counts.size
    max_l = 1.0
    max_u = 0.0
    max_b = 0.0
    probe = 0.0  # stays 0 unless an entry of L or U is inf or NaN
    stats[STAT_BAD_COLUMN] = -1.0
    u_end = 0  # U's column j ends here
    for j in range(n):
        if column_of is None:
            max_b = scatter_column(values, in_factor_order, b_pattern, rows, j, work, max_b)
        else:
            max_b = _scatter_row(values, b_pattern[0], rows, _wide(column_of[j]), work, max_b)
        u_start = u_end
        u_end += _wide(u_counts[j])
        for p in range(u_start, u_end):  # in topological order
            k = _index(j + _wide(u_offsets[p]))
            x_k = work[k]
            work[k] = 0.0
            u_values[p] = x_k
            max_u = max(max_u, abs(x_k))
            probe += 0.0 * x_k
            for q in range(_wide(l_indptr[k]), _wide(l_indptr[k + 1])):
                work[k + _index(l_offsets[q])] -= l_values[q] * x_k  # (L's offsets are positive)
        pivot = work[j]
        work[j] = 0.0
        if not (pivot != 0.0 and abs(pivot) < math.inf):  # NaN fails both tests
            for q in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
                work[_index(j + _wide(l_offsets[q]))] = 0.0
            stats[STAT_BAD_COLUMN] = j
            break
        max_u = max(max_u, abs(pivot))
        inverse = 1.0 / pivot
        u_inverse[j] = inverse
        for q in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
            i = _index(j + _wide(l_offsets[q]))
            entry = work[i] * inverse
            work[i] = 0.0
            l_values[q] = entry
            max_l = max(max_l, abs(entry))
            probe += 0.0 * entry
    stats[STAT_MIN_PIVOT_RATIO] = 1.0 / max_l
    stats[STAT_MAX_ABS_U] = max_u
    stats[STAT_MAX_ABS_B] = max_b
    stats[STAT_NON_FINITE] = probe
