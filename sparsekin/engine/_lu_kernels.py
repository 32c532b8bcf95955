"""numba kernels of the LU factorizations: sparse refactorization on a fixed pattern, dense LU.

Symbols (for these kernels only):

* ``B = Pr A Pc`` — the permuted matrix that is factored, ``B = L U``, stored by columns
  (CSC): ``b_indptr``, ``b_rows`` (row indices already permuted, `fill_column_rows`) and
  values read either straight from ``values`` (factor order) or shifted by a per-column
  ``offsets`` (``B`` entry ``p`` of column ``j`` is ``values[p + offsets[j]]``: each
  column of ``B`` is one contiguous run of the values, a row of the CSR matrix whose
  transpose is ``A``).  Entries within a column may come in any order, and repeated rows
  are summed.
* ``L`` — unit lower triangular, strictly lower part by columns: ``l_indptr``,
  ``l_indices``, ``l_values``.
* ``U`` — upper triangular, strictly upper part by columns (rows in a topological order
  of the updates, see `analyse_lu_pattern`): ``u_indptr``, ``u_indices``, ``u_values``;
  the reciprocals of its diagonal (the pivots) in ``u_inverse``: the solves multiply
  by them, a division per column being on their critical path.
* ``perm_r``, ``perm_c`` — row ``i`` of ``A`` is row ``perm_r[i]`` of ``B``, column ``c``
  of ``A`` is column ``perm_c[c]`` of ``B``.
* The solves of `solve_lu_rows` (`sparsekin.engine.dissection.DissectionSolver`'s) take U
  by rows instead, the last row stored first (`rows_last_first`), and the inverse
  permutations ``row_of``, ``column_of``; its transposed solves take U back by columns
  (`columns_from_rows_last_first`) and `solve_lu_transposed`.
* Right-hand sides and solutions have shape (n,).
* Index arrays are int32 when the sizes allow it (half the memory traffic of int64,
  which the solves are bound by), int64 otherwise; `analyse_lu_pattern` returns int64
  ``*_indptr``, which its caller may narrow to int32 when their last entry fits.

Loops over int32 row pointers take int64 bounds (`_wide`): numba counts a ``range`` of
int32 bounds in int32, which made the refactorization 5–10 % slower than with int64
pointers (10^5-body chain, interleaved in one process); with the cast it is as fast.

The patterns of ``L`` and ``U`` are *structural*: every entry that can be nonzero for some
values of ``B`` with the pivot sequence fixed, so a value that is exactly zero at one
configuration keeps its place for the next.

The dense pair `dense_lu_factor` / `dense_lu_solve` is meant to be called from other
numba code (the compiled time loop) as well as from Python.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT as _JIT

_wide = np.int64  # a loop bound read from an int32 array, counted in int64 (module docstring)
#: An index read from an array, made unsigned: numba checks a signed index for a negative
#: (wrapping) value at every access; unsigned, the solves of the 10^4-body chain's saddle
#: took 0.92 of the time (docs/design-notes.md, "Compact factors").  Same arithmetic.
_index = np.uint64

#: Layout of the `stats` array filled by `refactor_lu`.
#: (`sparsekin.engine.linalg` unpacks it in this order.)
STAT_MIN_PIVOT_RATIO = 0  # smallest |pivot| / largest |candidate| of its column (1 = best)
STAT_MAX_ABS_U = 1  # largest |U| entry, diagonal included
STAT_MAX_ABS_B = 2  # largest |B| entry
STAT_BAD_COLUMN = 3  # first column with a zero or non-finite pivot, else -1
STAT_NON_FINITE = 4  # 0 if every entry of L and U is finite, NaN otherwise
N_STATS = 5


@njit(**_JIT)
def analyse_lu_pattern(b_indptr, b_rows, l_capacity, u_capacity, trim=True):
    """Structural patterns of L and U for ``B = L U`` with the diagonal as pivot sequence.

    Left-looking symbolic factorization (Gilbert–Peierls): the pattern of column j is the
    set of rows reachable from the rows of ``B(:, j)`` in the graph of the columns of L
    already found.  The diagonal is always kept.  This one kernel allocates and returns
    its outputs, whose sizes only the analysis finds (it grows them by doubling from the
    capacities given, and trims them unless `trim` is False: then ``l_indices`` and
    ``u_indices`` may be longer than ``l_indptr[n]`` and ``u_indptr[n]``, the caller's to
    trim or to drop).

    Returns
    -------
    l_indptr, u_indptr : ndarray of int64, shape (n + 1,)
    l_indices, u_indices : ndarray of the dtype of `b_rows`
        Strictly lower part of L and strictly upper part of U by columns.  U's rows come in
        a topological order of the updates (reverse postorder of the search), the order
        the numeric left-looking factorization needs; L's in no particular order.
    """
    n = b_indptr.size - 1
    l_indptr = np.zeros(n + 1, dtype=np.int64)
    u_indptr = np.zeros(n + 1, dtype=np.int64)
    l_indices = np.empty(max(l_capacity, n, 1), dtype=b_rows.dtype)
    u_indices = np.empty(max(u_capacity, n, 1), dtype=b_rows.dtype)
    # rows in the dtype of `b_rows` (int32 up to 2^31 entries: at a flat crossing of the
    # 10^6-body chain these scratch arrays were 240 MB of the new pivots' peak in int64), in
    # one allocation (`_pivoting_kernels.partial_pivoting_rows`: mapped, not from the heap)
    scratch = np.empty((4, n), dtype=b_rows.dtype)
    mark = scratch[0]
    mark[:] = -1
    stack = scratch[1]  # depth-first search: node ...
    next_child = np.empty(n, dtype=np.int64)  # ... and the position of its next child in L
    finished = scratch[2]  # rows < j of the pattern, in postorder
    lower = scratch[3]  # rows > j of the pattern
    for j in range(n):
        n_finished = 0
        n_lower = 0
        mark[j] = j
        for p in range(b_indptr[j], b_indptr[j + 1]):
            r = b_rows[p]
            if mark[r] == j:
                continue
            mark[r] = j
            if r > j:
                lower[n_lower] = r
                n_lower += 1
                continue
            top = 0
            stack[0] = r
            next_child[0] = l_indptr[r]
            while top >= 0:
                k = stack[top]
                position = next_child[top]
                if position == l_indptr[k + 1]:
                    finished[n_finished] = k
                    n_finished += 1
                    top -= 1
                    continue
                next_child[top] = position + 1
                i = l_indices[position]
                if mark[i] == j:
                    continue
                mark[i] = j
                if i < j:
                    top += 1
                    stack[top] = i
                    next_child[top] = l_indptr[i]
                else:
                    lower[n_lower] = i
                    n_lower += 1
        start = l_indptr[j]
        if start + n_lower > l_indices.size:
            grown = np.empty(max(2 * l_indices.size, start + n_lower), dtype=l_indices.dtype)
            grown[:start] = l_indices[:start]
            l_indices = grown
        for t in range(n_lower):
            l_indices[start + t] = lower[t]
        l_indptr[j + 1] = start + n_lower
        start = u_indptr[j]
        if start + n_finished > u_indices.size:
            grown = np.empty(max(2 * u_indices.size, start + n_finished), dtype=u_indices.dtype)
            grown[:start] = u_indices[:start]
            u_indices = grown
        for t in range(n_finished):
            u_indices[start + t] = finished[n_finished - 1 - t]
        u_indptr[j + 1] = start + n_finished
    if trim and l_indptr[n] < l_indices.size:  # trimmed (no copy when the capacity was exact)
        l_indices = l_indices[: l_indptr[n]].copy()
    if trim and u_indptr[n] < u_indices.size:
        u_indices = u_indices[: u_indptr[n]].copy()
    return l_indptr, l_indices, u_indptr, u_indices


@njit(**_JIT)
def refactor_lu(values, in_factor_order, b_pattern, lower, upper, work, stats):
    """Numeric left-looking LU of B on the fixed patterns: fill L, U and `stats`.

    `b_pattern` is B's ``(indptr, rows, offsets)``, `lower` L's ``(indptr, indices,
    values)``, `upper` U's ``(indptr, indices, values, inverse of the diagonal)``; the
    values of L and U are filled.  B's entry p of column j is ``values[p + offsets[j]]``,
    or ``values[p]`` if `in_factor_order`.
    `work` (shape (n,)) must be zero on entry and is zero on return.  The factorization
    stops at the first column whose pivot is zero or non-finite and records it in
    ``stats[STAT_BAD_COLUMN]``; a non-finite entry of L or U makes
    ``stats[STAT_NON_FINITE]`` NaN.
    """
    _left_looking_lu(values, in_factor_order, b_pattern, None, lower, upper, work, stats)


@njit(**_JIT)
def refactor_lu_gathered(values, in_factor_order, b_pattern, rows, lower, upper, work, stats):
    """`refactor_lu` without B's row indices held: ``rows`` is ``(indices, perm_r)``, the CSR
    column indices of the matrix whose transpose is factored and the row permutation, and
    B's entry p of column j is in row ``perm_r[indices[p + offsets[j]]]`` (what
    `fill_column_rows` would have stored).  The same elimination, in the same order: the
    same factors, bit for bit; 4 bytes per entry fewer held, ~18 % slower (10^5-body
    chain's saddle), for a solver that refactors rarely (`RefactorSolver`'s ``lean``)."""
    _left_looking_lu(values, in_factor_order, b_pattern, rows, lower, upper, work, stats)


@njit(inline="always", **_JIT)
def scatter_column(values, in_factor_order, b_pattern, rows, j, work, max_b):
    """B's column j added into `work` (`_left_looking_lu`'s first step, and
    `_relative_lu_kernels`'): returns the largest |entry| so far, `max_b` included."""
    b_indptr, offsets = b_pattern[0], b_pattern[2]
    shift = offsets[j]
    if rows is None:
        b_rows = b_pattern[1]
        if in_factor_order:
            for p in range(_wide(b_indptr[j]), _wide(b_indptr[j + 1])):
                value = values[p]
                work[_index(b_rows[p])] += value  # repeated entries add up
                max_b = max(max_b, abs(value))
        else:
            for p in range(_wide(b_indptr[j]), _wide(b_indptr[j + 1])):
                value = values[p + shift]
                work[_index(b_rows[p])] += value
                max_b = max(max_b, abs(value))
    else:
        indices, perm_r = rows
        if in_factor_order:
            for p in range(_wide(b_indptr[j]), _wide(b_indptr[j + 1])):
                value = values[p]
                work[_index(perm_r[_index(indices[p + shift])])] += value
                max_b = max(max_b, abs(value))
        else:
            for p in range(_wide(b_indptr[j]) + shift, _wide(b_indptr[j + 1]) + shift):
                value = values[p]
                work[_index(perm_r[_index(indices[p])])] += value
                max_b = max(max_b, abs(value))
    return max_b


@njit(**_JIT)
def _left_looking_lu(values, in_factor_order, b_pattern, rows, lower, upper, work, stats):
    """`refactor_lu` (`rows` None: B's row indices held in ``b_pattern[1]``) and
    `refactor_lu_gathered` (``rows = (indices, perm_r)``), one compiled specialization each
    (numba prunes the ``rows is None`` branch).  The elimination is written out in the loop
    over the columns: as a function called per column (inlined or not) the 10^5-body
    kinematic chain's refactorization took 14.8 ms instead of 3.8 ms; B's column is added in
    by `scatter_column` (inlined: the same time, 3.8–4.3 ms either way)."""
    l_indptr, l_indices, l_values = lower
    u_indptr, u_indices, u_values, u_inverse = upper
    n = b_pattern[0].size - 1
    max_l = 1.0
    max_u = 0.0
    max_b = 0.0
    probe = 0.0  # stays 0 unless an entry of L or U is inf or NaN
    stats[STAT_BAD_COLUMN] = -1.0
    for j in range(n):
        max_b = scatter_column(values, in_factor_order, b_pattern, rows, j, work, max_b)
        for p in range(_wide(u_indptr[j]), _wide(u_indptr[j + 1])):  # in topological order
            k = u_indices[p]
            x_k = work[_index(k)]
            work[_index(k)] = 0.0
            u_values[p] = x_k
            max_u = max(max_u, abs(x_k))
            probe += 0.0 * x_k
            for q in range(_wide(l_indptr[k]), _wide(l_indptr[k + 1])):
                work[_index(l_indices[q])] -= l_values[q] * x_k
        pivot = work[j]
        work[j] = 0.0
        if not (pivot != 0.0 and abs(pivot) < math.inf):  # NaN fails both tests
            for q in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
                work[_index(l_indices[q])] = 0.0
            stats[STAT_BAD_COLUMN] = j
            break
        max_u = max(max_u, abs(pivot))
        inverse = 1.0 / pivot
        u_inverse[j] = inverse
        for q in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
            i = _index(l_indices[q])
            entry = work[i] * inverse
            work[i] = 0.0
            l_values[q] = entry
            max_l = max(max_l, abs(entry))
            probe += 0.0 * entry
    # |pivot| / max(|pivot|, max |candidate|) over the columns is 1 / max(1, max |L|).
    stats[STAT_MIN_PIVOT_RATIO] = 1.0 / max_l
    stats[STAT_MAX_ABS_U] = max_u
    stats[STAT_MAX_ABS_B] = max_b
    stats[STAT_NON_FINITE] = probe


@njit(**_JIT)
def solve_lu(factors, rhs, work, out, probe):
    """Solve ``A x = rhs`` with ``Pr A Pc = L U``: fill `out` (may be `rhs` itself).

    `factors` is ``(perm_r, perm_c, (L's indptr, indices, values), (U's indptr, indices,
    values, inverse of the diagonal))``; `rhs`, `work` and `out` have shape (n,).  ``probe[0]`` becomes 0 if every entry of
    the solution is finite, NaN otherwise.
    """
    perm_r, perm_c, (l_indptr, l_indices, l_values), (u_indptr, u_indices, u_values, u_inverse) = factors
    n = rhs.size
    for i in range(n):
        work[_index(perm_r[i])] = rhs[i]
    for j in range(n):  # L y = Pr rhs, column by column
        x_j = work[j]
        for p in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
            work[_index(l_indices[p])] -= l_values[p] * x_j
    for j in range(n - 1, -1, -1):  # U z = y
        x_j = work[j] * u_inverse[j]
        work[j] = x_j
        for p in range(_wide(u_indptr[j]), _wide(u_indptr[j + 1])):
            work[_index(u_indices[p])] -= u_values[p] * x_j
    total = 0.0
    for i in range(n):  # x = Pc z
        x_i = work[_index(perm_c[i])]
        out[i] = x_i
        total += 0.0 * x_i  # stays 0 unless an entry is inf or NaN
    probe[0] = total


@njit(**_JIT)
def solve_lu_transposed(factors, rhs, work, out, probe):
    """Solve ``A^T x = rhs`` with ``Pr A Pc = L U`` (``A^T = Pc U^T L^T Pr``): fill `out`.

    `factors` as for `solve_lu`; `rhs`, `work` and `out` have shape (n,); `out` may be
    `rhs` itself.  ``probe[0]``
    becomes 0 if every entry of the solution is finite, NaN otherwise.
    """
    perm_r, perm_c, (l_indptr, l_indices, l_values), (u_indptr, u_indices, u_values, u_inverse) = factors
    n = rhs.size
    for i in range(n):
        work[_index(perm_c[i])] = rhs[i]
    for j in range(n):  # U^T y = Pc^T rhs: dot products with the columns of U
        total = work[j]
        for p in range(_wide(u_indptr[j]), _wide(u_indptr[j + 1])):
            total -= u_values[p] * work[_index(u_indices[p])]
        work[j] = total * u_inverse[j]
    for j in range(n - 1, -1, -1):  # L^T z = y
        total = work[j]
        for p in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
            total -= l_values[p] * work[_index(l_indices[p])]
        work[j] = total
    total = 0.0
    for i in range(n):  # x = Pr^T z
        x_i = work[_index(perm_r[i])]
        out[i] = x_i
        total += 0.0 * x_i  # stays 0 unless an entry is inf or NaN
    probe[0] = total


@njit(**_JIT)
def solve_lu_transposed_pair(factors, x0, x1, work, probe):
    """Solve ``A^T y = x0`` and ``A^T z = x1`` in one pass over the factors (as
    `solve_lu_transposed`, each solution bit for bit the same): `x0` and `x1` are overwritten
    by y and z; `work`, shape (n,), is the one scratch array (`x0` holds the second system's
    permuted unknowns meanwhile).

    A triangular solve of a chain is one long chain of dependent additions (each unknown
    waits for the ones before it); two independent right-hand sides interleaved fill the
    processor's waiting time: measured 1.17 times one solve on the 10^4-body chain's saddle
    matrix, not 2.  ``probe[0]`` becomes 0 if every entry of both solutions is finite, NaN
    otherwise.
    """
    perm_r, perm_c, (l_indptr, l_indices, l_values), (u_indptr, u_indices, u_values, u_inverse) = factors
    n = x0.size
    for i in range(n):
        work[_index(perm_c[i])] = x0[i]
    second = x0  # every entry of x0 is read: it holds the second system from here on
    for i in range(n):
        second[_index(perm_c[i])] = x1[i]
    for j in range(n):  # U^T y = Pc^T rhs, both at once
        total, other = work[j], second[j]
        for p in range(_wide(u_indptr[j]), _wide(u_indptr[j + 1])):
            value, k = u_values[p], _index(u_indices[p])
            total -= value * work[k]
            other -= value * second[k]
        work[j] = total * u_inverse[j]
        second[j] = other * u_inverse[j]
    for j in range(n - 1, -1, -1):  # L^T z = y
        total, other = work[j], second[j]
        for p in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
            value, k = l_values[p], _index(l_indices[p])
            total -= value * work[k]
            other -= value * second[k]
        work[j] = total
        second[j] = other
    total = 0.0
    for i in range(n):  # x = Pr^T z: the second system's first (x1 is free), then the first's
        x_i = second[_index(perm_r[i])]
        x1[i] = x_i
        total += 0.0 * x_i
    for i in range(n):
        x_i = work[_index(perm_r[i])]
        x0[i] = x_i
        total += 0.0 * x_i
    probe[0] = total


@njit(**_JIT)
def rows_last_first(indptr, indices, values, out_indptr, out_indices, out_values):
    """A compressed-column factor's nonzero entries by rows, the last row stored first.

    Row ``i`` of the factor becomes stored row ``n - 1 - i`` of ``(out_indptr, out_indices,
    out_values)`` (its entries by increasing column), so that a backward substitution with
    it reads the arrays front to back (`solve_lu_rows`); exactly zero entries (a
    refactorization's structural zeros) are left out.  The `out_` arrays are as large as
    the input's (`out_indptr` shape (n + 1,)) and are filled.
    """
    n = indptr.size - 1
    for k in range(n + 1):
        out_indptr[k] = 0
    for p in range(_wide(indptr[n])):  # the entries of each stored row, counted one place on
        if values[p] != 0.0:
            out_indptr[n - indices[p]] += 1
    for k in range(n):  # out_indptr[k]: where stored row k starts
        out_indptr[k + 1] += out_indptr[k]
    for j in range(n):  # out_indptr[k] moves to where stored row k ends
        for p in range(_wide(indptr[j]), _wide(indptr[j + 1])):
            value = values[p]
            if value != 0.0:
                k = n - 1 - indices[p]
                q = out_indptr[k]
                out_indices[q] = j
                out_values[q] = value
                out_indptr[k] = q + 1
    for k in range(n, 0, -1):
        out_indptr[k] = out_indptr[k - 1]
    out_indptr[0] = 0


@njit(**_JIT)
def solve_lu_rows(factors, rhs, work, out, probe):
    """Solve ``A x = rhs`` with ``Pr A Pc = L U``, U stored by rows last first: fill `out`.

    `factors` is ``(row_of, column_of, (L's indptr, indices, values), (U's indptr, indices,
    values, inverse of the diagonal))``: row ``i`` of ``B = L U`` is row ``row_of[i]`` of
    A, column ``j`` of B column ``column_of[j]`` of A; L strictly lower by columns, U
    strictly upper by rows stored last first (`rows_last_first`).  Every sweep reads the
    factors front to back and reaches the solution's entries of later columns only (the
    separators above in a nested dissection): L by columns subtracts into them, U by rows
    gathers from them.  Measured on the lattice's factors at 10^6 bodies (30.6 M entries):
    half the time of `solve_lu` on U by columns, whose backward sweep scatters over
    earlier rows and reads the arrays back to front.  `rhs`, `work` and `out` have shape
    (n,); `out` may be `rhs`.  ``probe[0]`` becomes 0 if every entry of the solution is
    finite, NaN otherwise.
    """
    row_of, column_of, (l_indptr, l_indices, l_values), (u_indptr, u_indices, u_values, u_inverse) = factors
    n = rhs.size
    for i in range(n):  # Pr rhs, gathered (a scattering pass was slower)
        work[i] = rhs[_index(row_of[i])]
    for j in range(n):  # L y = Pr rhs, column by column
        x_j = work[j]
        for p in range(_wide(l_indptr[j]), _wide(l_indptr[j + 1])):
            work[_index(l_indices[p])] -= l_values[p] * x_j
    for k in range(n):  # U z = y, row n - 1 - k stored k-th
        i = n - 1 - k
        total = work[i]
        for p in range(_wide(u_indptr[k]), _wide(u_indptr[k + 1])):
            total -= u_values[p] * work[_index(u_indices[p])]
        work[i] = total * u_inverse[i]
    total = 0.0
    for j in range(n):  # x = Pc z, scattered (a gathering pass was slower)
        x_j = work[j]
        out[_index(column_of[j])] = x_j
        total += 0.0 * x_j  # stays 0 unless an entry is inf or NaN
    probe[0] = total


@njit(**_JIT)
def columns_from_rows_last_first(indptr, indices, values, out_indptr, out_indices, out_values):
    """The strictly upper factor stored by `rows_last_first`, back by columns (rows increasing
    within each): for `solve_lu_transposed`, whose sweeps read U's columns (on U by rows
    they were 1.1–2 times slower).  The `out_` arrays are as large as the input's
    (`out_indptr` shape (n + 1,)) and are filled."""
    n = indptr.size - 1
    for c in range(n + 1):
        out_indptr[c] = 0
    for p in range(_wide(indptr[n])):
        out_indptr[indices[p] + 1] += 1
    for c in range(n):
        out_indptr[c + 1] += out_indptr[c]
    for k in range(n - 1, -1, -1):  # rows i = n - 1 - k in increasing order
        i = n - 1 - k
        for p in range(_wide(indptr[k]), _wide(indptr[k + 1])):
            c = indices[p]
            q = out_indptr[c]
            out_indices[q] = i
            out_values[q] = values[p]
            out_indptr[c] = q + 1
    for c in range(n, 0, -1):
        out_indptr[c] = out_indptr[c - 1]
    out_indptr[0] = 0


@njit(**_JIT)
def dense_lu_factor(a, pivots):
    """LU with partial pivoting of a square matrix, in place; True unless a pivot fails.

    Zeros are skipped: a row whose multiplier is zero is not updated, and when the pivot
    row is mostly zeros only its nonzero columns are (linkage Jacobians have about four
    nonzeros per row, and their factors stay nearly as sparse).  The rounding is that of
    the plain algorithm.

    Parameters
    ----------
    a : ndarray, shape (n, n), float64, C-contiguous
        Overwritten by L (strictly lower part, unit diagonal implied) and U.
    pivots : ndarray, shape (n,), int64
        Filled with the row interchanges, as LAPACK's ``getrf`` but 0-based: at step k,
        rows k and ``pivots[k] >= k`` were swapped.  Applying the swaps in order to the
        rows of the original `a` gives ``L U``.

    Returns
    -------
    bool
        False if a pivot is exactly zero or not finite (the matrix is singular, or holds
        an inf or NaN in a pivot's column); `a` and `pivots` are then only partly
        factored.  A NaN elsewhere shows in the solution.
    """
    n = a.shape[0]
    columns = np.empty(n, dtype=np.int64)  # nonzero columns of the pivot row, right of k
    for k in range(n):
        best = k
        largest = abs(a[k, k])
        for i in range(k + 1, n):
            magnitude = abs(a[i, k])
            if magnitude > largest:
                largest = magnitude
                best = i
        pivots[k] = best
        if not (largest > 0.0 and largest < math.inf):  # NaN fails both tests
            return False
        if best != k:
            for c in range(n):
                a[k, c], a[best, c] = a[best, c], a[k, c]
        n_columns = 0
        for c in range(k + 1, n):
            if a[k, c] != 0.0:
                columns[n_columns] = c
                n_columns += 1
        dense = 2 * n_columns > n - k - 1
        inverse = 1.0 / a[k, k]
        for i in range(k + 1, n):
            if a[i, k] == 0.0:
                continue
            factor = a[i, k] * inverse
            a[i, k] = factor
            if dense:
                for c in range(k + 1, n):
                    a[i, c] -= factor * a[k, c]
            else:
                for t in range(n_columns):
                    c = columns[t]
                    a[i, c] -= factor * a[k, c]
    return True


@njit(**_JIT)
def dense_lu_solve(a, pivots, b):
    """Solve ``matrix @ x = b`` in place in `b` (shape (n,)) from `dense_lu_factor`'s output.

    Column-oriented substitutions, so that a zero entry of the partial solution skips its
    column (right-hand sides of kinematics are mostly zeros).
    """
    n = a.shape[0]
    for k in range(n):
        swap = pivots[k]
        if swap != k:
            b[k], b[swap] = b[swap], b[k]
    for j in range(n):
        x_j = b[j]
        if x_j != 0.0:
            for i in range(j + 1, n):
                b[i] -= a[i, j] * x_j
    for j in range(n - 1, -1, -1):
        x_j = b[j] / a[j, j]
        b[j] = x_j
        if x_j != 0.0:
            for i in range(j):
                b[i] -= a[i, j] * x_j


@njit(**_JIT)
def dense_lu_solve_transposed(a, pivots, b):
    """Solve ``matrix.T @ x = b`` in place in `b` from `dense_lu_factor`'s output.

    ``P matrix = L U`` (P the row interchanges), so ``matrix.T = U.T L.T P``: forward
    substitution with U.T, back substitution with the unit L.T, then the interchanges
    undone in reverse order.  Both substitutions read rows of `a` (contiguous) and skip
    the zero entries of the partial solution, as `dense_lu_solve` does with columns.
    """
    n = a.shape[0]
    for j in range(n):  # U.T y = b: y_j, then take row j of U out of the rest
        y_j = b[j] / a[j, j]
        b[j] = y_j
        if y_j != 0.0:
            for i in range(j + 1, n):
                b[i] -= a[j, i] * y_j
    for j in range(n - 1, -1, -1):  # L.T z = y: z_j, then take row j of L out of the rest
        z_j = b[j]
        if z_j != 0.0:
            for i in range(j):
                b[i] -= a[j, i] * z_j
    for k in range(n - 1, -1, -1):
        swap = pivots[k]
        if swap != k:
            b[k], b[swap] = b[swap], b[k]


@njit(**_JIT)
def split_off_diagonal(indptr, indices, values, diagonal):
    """Take the diagonal out of a square CSC triangular factor, in place.

    Moves each column's off-diagonal entries to the front of the arrays, in order, writes
    the diagonal entry of column j to ``diagonal[j]`` (0 where there is none) and returns
    the new `indptr`: the factor without its diagonal is ``indices[:indptr[-1]]`` and
    ``values[:indptr[-1]]``.
    """
    n = indptr.size - 1
    kept = np.empty(n + 1, dtype=np.int64)
    kept[0] = 0
    k = 0
    for j in range(n):
        diagonal[j] = 0.0
        for p in range(indptr[j], indptr[j + 1]):
            if indices[p] == j:
                diagonal[j] = values[p]
            else:
                indices[k] = indices[p]
                values[k] = values[p]
                k += 1
        kept[j + 1] = k
    return kept


@njit(**_JIT)
def ordered_columns(indptr, indices, order):
    """The pattern of ``matrix[:, order]`` in CSC for a CSR matrix ``(indptr, indices)`` with
    ``order.size`` columns, and where its values come from.

    Returns ``(c_indptr, c_indices, gather)``: column k of the result is column ``order[k]``
    of the matrix, its row indices sorted, its values ``data[gather[c_indptr[k]:c_indptr[k + 1]]]``.
    """
    n_rows, n_cols = indptr.size - 1, order.size
    counts = np.zeros(n_cols, dtype=np.int64)
    for p in range(indptr[n_rows]):
        counts[indices[p]] += 1
    c_indptr = np.zeros(n_cols + 1, dtype=np.int64)
    start = np.empty(n_cols, dtype=np.int64)
    for k in range(n_cols):
        start[order[k]] = c_indptr[k]
        c_indptr[k + 1] = c_indptr[k] + counts[order[k]]
    c_indices = np.empty(indptr[n_rows], dtype=indices.dtype)
    gather = np.empty(indptr[n_rows], dtype=np.int64)
    for i in range(n_rows):
        for p in range(indptr[i], indptr[i + 1]):
            q = start[indices[p]]
            c_indices[q] = i
            gather[q] = p
            start[indices[p]] = q + 1
    return c_indptr, c_indices, gather


@njit(**_JIT)
def inverse_permutation(permutation, out):
    """``out[permutation[i]] = i``: the inverse of a permutation (`out` of its dtype and size)."""
    for i in range(permutation.size):
        out[permutation[i]] = i


@njit(**_JIT)
def fill_column_layout(indptr, perm_c, b_indptr, offsets):
    """Column j of B (A's columns in the order `perm_c`: column c of A is column
    ``perm_c[c]`` of B) is column c of A, i.e. row c of the CSR matrix whose transpose A
    is (row pointers `indptr`), its entries in the CSR order: a contiguous run of the CSR
    values.  Fills B's column pointers `b_indptr` (n + 1) and ``offsets[j] = indptr[c] -
    b_indptr[j]``, where that run starts after B's column j."""
    n = perm_c.size
    column_of = np.empty(n, dtype=np.int64)
    inverse_permutation(perm_c, column_of)
    b_indptr[0] = 0
    for j in range(n):
        c = column_of[j]
        b_indptr[j + 1] = b_indptr[j] + (indptr[c + 1] - indptr[c])
        offsets[j] = indptr[c] - b_indptr[j]


@njit(**_JIT)
def fill_column_rows(indices, offsets, b_indptr, perm_r, b_rows):
    """``b_rows[p] = perm_r[indices[p + offsets[j]]]`` for the entries p of each column j of
    B: B's row indices, permuted, read from the CSR indices of the matrix whose transpose
    is factored (without an index array per entry to gather them through)."""
    for j in range(b_indptr.size - 1):
        shift = offsets[j]
        for p in range(b_indptr[j], b_indptr[j + 1]):
            b_rows[p] = perm_r[indices[p + shift]]


@njit(**_JIT)
def copy_nonzeros(indptr, indices, values, out_indptr, out_indices, out_values):
    """Copy a compressed-column factor without its exactly zero entries (a refactorization's
    structural zeros: exact cancellations of the Jacobian's constant coefficients) into the
    `out_` arrays (as large as the input's); ``out_indptr`` receives the new column pointers."""
    n = indptr.size - 1
    k = 0
    out_indptr[0] = 0
    for j in range(n):
        for p in range(indptr[j], indptr[j + 1]):
            if values[p] != 0.0:
                out_indices[k] = indices[p]
                out_values[k] = values[p]
                k += 1
        out_indptr[j + 1] = k
