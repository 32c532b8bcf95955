"""numba kernels of the compact factors: L and U without their exact zeros, for the solves.

The structural patterns of L and U (`_lu_kernels.analyse_lu_pattern`) hold every entry that
can be nonzero with the pivot sequence fixed.  On a linkage's saddle matrix about a quarter
of them are exactly zero at every configuration met (the 10^4-body N-four-bar chain's held
iteration matrix: 110 000 of 415 000 off the diagonal; exact cancellations of the joints'
constant coefficients and of the mass matrix's blocks), and a solve multiplies and
subtracts each of them all the same.  A solve of a chain's saddle matrix is bound by the
work per entry and per column, not by its chain of dependent additions nor, at 10^4-10^5
unknowns, by memory (docs/design-notes.md, "Compact factors").

`refactor_lu` writes every entry to its structural place and reads only what it wrote in
the same call (L's columns before the current one), so the values can be compacted in
place between refactorizations.  Their rows are kept as one byte each, the offset ``i - j``
of row i in column j, and each column's count of entries as one byte (the solves' sweeps
go through the columns in order, forward or backward, and keep their own running
position): 1 byte per structural entry and 2 per unknown held, not 4 and 8 (at 10^6 bodies
the 3 GB of issue 25 are met by tens of MB).  A pattern whose offsets do not fit in
``[-128, 127]``, or a column in 255 entries, is not compacted (`offsets_fit`).

Symbols as in `sparsekin.engine._lu_kernels`; compact factors are ``(counts, offsets,
values)`` for L and ``(counts, offsets, values, inverse of the diagonal)`` for U.  Every
solve gives the structural factors' solution (``w - 0 * x`` is ``w``, to the sign of a zero).
"""

from __future__ import annotations

from numba import njit

from .._jit import JIT as _JIT
from ._lu_kernels import _index, _wide  # (an offset read from a narrow array is widened by `_wide` too)

MAX_OFFSET = 127  # int8
MAX_COUNT = 255  # uint8


@njit(**_JIT)
def offsets_fit(indptr, indices):
    """True if every entry of the compressed-column pattern is within `MAX_OFFSET` of the
    diagonal and no column holds more than `MAX_COUNT` entries."""
    for j in range(indptr.size - 1):
        if indptr[j + 1] - indptr[j] > MAX_COUNT:
            return False
        for p in range(_wide(indptr[j]), _wide(indptr[j + 1])):
            if abs(_wide(indices[p]) - j) > MAX_OFFSET:
                return False
    return True


@njit(**_JIT)
def compact_in_place(indptr, indices, values, counts, offsets):
    """The nonzero `values` of a compressed-column factor moved to the front (in order),
    their offsets ``i - j`` to `offsets` (int8, as large as `values`), each column's count
    to `counts` (uint8, shape (n,)); `indptr` and `indices` (the pattern, which
    `offsets_fit`) are left as they are.  NaN entries are kept."""
    kept = 0
    for j in range(indptr.size - 1):
        start = kept
        for p in range(_wide(indptr[j]), _wide(indptr[j + 1])):
            value = values[p]
            offsets[kept] = _wide(indices[p]) - j  # written always, kept if nonzero: no branch to mispredict
            values[kept] = value
            kept += value != 0.0
        counts[j] = kept - start


@njit(**_JIT)
def compact_relative_in_place(structural_counts, relative, values, counts, offsets):
    """`compact_in_place` on a relative pattern (`sparsekin.engine._relative_lu_kernels`):
    each column's entries counted by `structural_counts`, their rows read as offsets from
    `relative` (int8); both are left as they are."""
    kept = 0
    p = 0
    for j in range(structural_counts.size):
        start = kept
        end = p + _wide(structural_counts[j])
        while p < end:
            value = values[p]
            offsets[kept] = relative[p]
            values[kept] = value
            kept += value != 0.0
            p += 1
        counts[j] = kept - start


@njit(inline="always", **_JIT)
def _row(j, offset):
    """Row ``j + offset`` as an unsigned index (`_lu_kernels._index`: the paired solve was 12 %
    slower with a signed one, 10^4 chain)."""
    return _index(j + _wide(offset))


@njit(inline="always", **_JIT)
def _finish(work, permutation, out):
    """``out[i] = work[permutation[i]]``; 0 if every entry is finite, NaN otherwise."""
    total = 0.0
    for i in range(out.size):
        x_i = work[permutation[i]]
        out[i] = x_i
        total += 0.0 * x_i
    return total


@njit(**_JIT)
def solve_lu(factors, rhs, work, out, probe):
    """`_lu_kernels.solve_lu` (``A x = rhs``) on compact factors: fill `out` (may be `rhs`);
    ``probe[0]`` 0 if every entry of the solution is finite, NaN otherwise."""
    perm_r, perm_c, (l_counts, l_offsets, l_values), (u_counts, u_offsets, u_values, u_inverse) = factors
    n = rhs.size
    for i in range(n):
        work[perm_r[i]] = rhs[i]
    p = 0
    for j in range(n):  # L y = Pr rhs, column by column
        x_j = work[j]
        end = p + _wide(l_counts[j])
        while p < end:
            work[_row(j, l_offsets[p])] -= l_values[p] * x_j
            p += 1
    p = 0
    for j in range(n):
        p += _wide(u_counts[j])
    for j in range(n - 1, -1, -1):  # U z = y, from the last column back
        start = p - _wide(u_counts[j])
        x_j = work[j] * u_inverse[j]
        work[j] = x_j
        for q in range(start, p):
            work[_row(j, u_offsets[q])] -= u_values[q] * x_j
        p = start
    probe[0] = _finish(work, perm_c, out)  # x = Pc z


@njit(inline="always", **_JIT)
def _forward_upper(work, u_counts, u_offsets, u_values, u_inverse):
    """U^T y = work in place: dot products with U's columns, first to last."""
    p = 0
    for j in range(work.size):
        total = work[j]
        end = p + _wide(u_counts[j])
        while p < end:
            total -= u_values[p] * work[_row(j, u_offsets[p])]
            p += 1
        work[j] = total * u_inverse[j]


@njit(inline="always", **_JIT)
def _backward_lower(work, l_counts, l_offsets, l_values):
    """L^T z = work in place: dot products with L's columns, last to first."""
    p = 0
    for j in range(work.size):
        p += _wide(l_counts[j])
    for j in range(work.size - 1, -1, -1):
        total = work[j]
        start = p - _wide(l_counts[j])
        for q in range(start, p):
            total -= l_values[q] * work[_row(j, l_offsets[q])]
        work[j] = total
        p = start


@njit(**_JIT)
def solve_lu_transposed(factors, rhs, work, out, probe):
    """`_lu_kernels.solve_lu_transposed` (``A^T x = rhs``) on compact factors: fill `out`
    (may be `rhs`); ``probe[0]`` 0 if every entry of the solution is finite, NaN otherwise."""
    perm_r, perm_c, (l_counts, l_offsets, l_values), (u_counts, u_offsets, u_values, u_inverse) = factors
    for i in range(rhs.size):
        work[perm_c[i]] = rhs[i]
    _forward_upper(work, u_counts, u_offsets, u_values, u_inverse)
    _backward_lower(work, l_counts, l_offsets, l_values)
    probe[0] = _finish(work, perm_r, out)


@njit(**_JIT)
def solve_lu_transposed_pair(factors, x0, x1, work, probe):
    """`_lu_kernels.solve_lu_transposed_pair` on compact factors: ``A^T y = x0`` and
    ``A^T z = x1`` in one pass, `x0` and `x1` overwritten by y and z (`x0` holds the second
    system's permuted unknowns meanwhile)."""
    perm_r, perm_c, (l_counts, l_offsets, l_values), (u_counts, u_offsets, u_values, u_inverse) = factors
    n = x0.size
    for i in range(n):
        work[perm_c[i]] = x0[i]
    second = x0  # every entry of x0 is read: it holds the second system from here on
    for i in range(n):
        second[perm_c[i]] = x1[i]
    p = 0
    for j in range(n):  # U^T y = Pc^T rhs, both at once
        total, other = work[j], second[j]
        end = p + _wide(u_counts[j])
        while p < end:
            value, k = u_values[p], _row(j, u_offsets[p])
            total -= value * work[k]
            other -= value * second[k]
            p += 1
        work[j] = total * u_inverse[j]
        second[j] = other * u_inverse[j]
    p = 0
    for j in range(n):
        p += _wide(l_counts[j])
    for j in range(n - 1, -1, -1):  # L^T z = y
        total, other = work[j], second[j]
        start = p - _wide(l_counts[j])
        for q in range(start, p):
            value, k = l_values[q], _row(j, l_offsets[q])
            total -= value * work[k]
            other -= value * second[k]
        work[j] = total
        second[j] = other
        p = start
    probe[0] = _finish(second, perm_r, x1) + _finish(work, perm_r, x0)


@njit(**_JIT)
def solve_lu_transposed_inverted(factors, rhs, work, out, probe):
    """`solve_lu_transposed` on factors that carry the permutations' inverses in place of
    the permutations, ``(inverse_r, inverse_c, lower, upper)`` (`_lu_kernels.inverse_permutation` of
    ``perm_r`` and ``perm_c``): column j of U's sweep starts from ``rhs[inverse_c[j]]`` and
    L's sweep writes each unknown to ``out[inverse_r[j]]`` as it is made, instead of a
    scatter and a gather of their own (two passes over n-sized arrays fewer: the same
    numbers; `out` may be `rhs`, every entry of which U's sweep reads before L's writes the
    first)."""
    inverse_r, inverse_c, (l_counts, l_offsets, l_values), (u_counts, u_offsets, u_values, u_inverse) = factors
    n = rhs.size
    p = 0
    for j in range(n):  # U^T y = Pc^T rhs
        total = rhs[inverse_c[j]]
        end = p + _wide(u_counts[j])
        while p < end:
            total -= u_values[p] * work[_row(j, u_offsets[p])]
            p += 1
        work[j] = total * u_inverse[j]
    p = 0
    for j in range(n):
        p += _wide(l_counts[j])
    check = 0.0
    for j in range(n - 1, -1, -1):  # L^T z = y, and x = Pr^T z
        total = work[j]
        start = p - _wide(l_counts[j])
        for q in range(start, p):
            total -= l_values[q] * work[_row(j, l_offsets[q])]
        work[j] = total
        out[inverse_r[j]] = total
        check += 0.0 * total
        p = start
    probe[0] = check
