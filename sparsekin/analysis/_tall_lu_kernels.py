"""numba kernels of the LU factorization of a tall Jacobian with threshold row pivoting.

Symbols (for these kernels only):

* ``A`` — the (scaled) Jacobian, m rows by n columns, m >= n, given by columns (CSC)
  in the column order of the factorization: ``a_indptr``, ``a_rows``, ``a_values``.
* ``P A = L U`` with the rows of ``A`` in pivot order first: ``L`` is m by n, unit lower
  trapezoidal, stored by columns with row indices of ``A`` (``l_indptr``, ``l_rows``,
  ``l_values``; the first entry of column k is its pivot row, value 1); ``U`` is n by n,
  upper triangular, stored by columns with row indices that are pivot steps
  (``u_indptr``, ``u_steps``, ``u_values``; the diagonal last).
* ``step_of_row`` — the pivot step of each row of ``A``, -1 for a row never chosen
  (a redundant row); ``row_of_step`` its inverse on the chosen rows.

Every row of ``A`` is reproduced exactly (up to rounding) by its row of ``L`` times
``U``, chosen or not: the rows left unchosen are combinations of the chosen ones.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._jit import JIT as _JIT

#: Layout of the `stats` array filled by `factor_tall`.
STAT_MIN_PIVOT_RATIO = 0  # smallest |pivot| / largest |candidate| of its column
STAT_MAX_ABS_U = 1  # largest |U| entry (growth: the scaled A has entries up to 1)
STAT_MAX_ABS_L = 2  # largest |L| entry (at most 1 / threshold)
STAT_FAILED_COLUMN = 3  # first column without a candidate above the tolerance, else -1
N_STATS = 4


@njit(**_JIT)
def _grow(array, size):
    """`array` copied into a new one of at least `size` entries (doubling)."""
    capacity = max(2 * array.size, size)
    grown = np.empty(capacity, dtype=array.dtype)
    grown[: array.size] = array
    return grown


@njit(**_JIT)
def factor_tall(a_indptr, a_rows, a_values, n_rows, preference, threshold, tolerance, drop, capacity, stats):
    """Left-looking (Gilbert–Peierls) LU of a tall ``A`` with threshold row pivoting.

    For column k: the sparse triangular solve with the columns of L already made gives the
    remainder of ``A(:, k)`` on the rows not yet chosen; the pivot is, among those whose
    magnitude is at least `threshold` times the largest, the one of smallest `preference`
    (ties: the largest).  A column whose largest remainder is at most `tolerance` stops the
    factorization (``stats[STAT_FAILED_COLUMN]``): the Jacobian may have a free coordinate
    there, a case left to the dense analysis.  Remainders of rows not chosen that are at
    most `drop` (rounding) are left out of L: a row that has become a combination of the
    chosen ones (a redundant row) then stops spreading fill to later columns.

    Returns
    -------
    l_indptr, l_rows, l_values, u_indptr, u_steps, u_values, step_of_row, row_of_step
    """
    n = a_indptr.size - 1
    m = n_rows
    l_indptr = np.zeros(n + 1, dtype=np.int64)
    u_indptr = np.zeros(n + 1, dtype=np.int64)
    l_rows = np.empty(capacity, dtype=np.int64)
    l_values = np.empty(capacity)
    u_steps = np.empty(capacity, dtype=np.int64)
    u_values = np.empty(capacity)
    step_of_row = np.full(m, -1, dtype=np.int64)
    row_of_step = np.full(n, -1, dtype=np.int64)
    x = np.zeros(m)
    mark = np.full(m, -1, dtype=np.int64)
    reach = np.empty(m, dtype=np.int64)  # DFS stack from the bottom, the reach from the top
    positions = np.empty(m, dtype=np.int64)
    stats[STAT_MIN_PIVOT_RATIO] = 1.0
    stats[STAT_MAX_ABS_U] = 0.0
    stats[STAT_MAX_ABS_L] = 1.0
    stats[STAT_FAILED_COLUMN] = -1.0
    l_used = 0
    u_used = 0
    for k in range(n):
        # the rows reachable from A(:, k) through the columns of L made so far, in topological order
        top = m
        for p in range(a_indptr[k], a_indptr[k + 1]):
            start = a_rows[p]
            if mark[start] == k:
                continue
            head = 0
            reach[0] = start
            while head >= 0:
                row = reach[head]
                step = step_of_row[row]
                if mark[row] != k:
                    mark[row] = k
                    positions[head] = l_indptr[step] if step >= 0 else 0
                end = l_indptr[step + 1] if step >= 0 else 0
                done = True
                for q in range(positions[head], end):
                    other = l_rows[q]
                    if mark[other] == k:
                        continue
                    positions[head] = q
                    head += 1
                    reach[head] = other
                    done = False
                    break
                if done:
                    head -= 1
                    top -= 1
                    reach[top] = row
        # numeric: x = remainder of A(:, k)
        for p in range(top, m):
            x[reach[p]] = 0.0
        for p in range(a_indptr[k], a_indptr[k + 1]):
            x[a_rows[p]] += a_values[p]
        for p in range(top, m):
            row = reach[p]
            step = step_of_row[row]
            if step < 0:
                continue
            value = x[row]
            for q in range(l_indptr[step] + 1, l_indptr[step + 1]):
                x[l_rows[q]] -= l_values[q] * value
        # U's column and the largest candidate
        largest = 0.0
        n_entries = m - top
        if u_used + n_entries + 1 > u_steps.size:
            u_steps = _grow(u_steps, u_used + n_entries + 1)
            u_values = _grow(u_values, u_used + n_entries + 1)
        if l_used + n_entries + 1 > l_rows.size:
            l_rows = _grow(l_rows, l_used + n_entries + 1)
            l_values = _grow(l_values, l_used + n_entries + 1)
        for p in range(top, m):
            row = reach[p]
            step = step_of_row[row]
            if step >= 0:
                u_steps[u_used] = step
                u_values[u_used] = x[row]
                u_used += 1
                if abs(x[row]) > stats[STAT_MAX_ABS_U]:
                    stats[STAT_MAX_ABS_U] = abs(x[row])
            elif abs(x[row]) > largest:
                largest = abs(x[row])
        if not largest > tolerance:  # NaN included
            stats[STAT_FAILED_COLUMN] = k
            return l_indptr, l_rows, l_values, u_indptr, u_steps, u_values, step_of_row, row_of_step
        pivot_row = -1
        for p in range(top, m):
            row = reach[p]
            if step_of_row[row] >= 0 or abs(x[row]) < threshold * largest:
                continue
            if pivot_row < 0 or preference[row] < preference[pivot_row] or (
                preference[row] == preference[pivot_row] and abs(x[row]) > abs(x[pivot_row])
            ):
                pivot_row = row
        pivot = x[pivot_row]
        ratio = abs(pivot) / largest
        if ratio < stats[STAT_MIN_PIVOT_RATIO]:
            stats[STAT_MIN_PIVOT_RATIO] = ratio
        if abs(pivot) > stats[STAT_MAX_ABS_U]:
            stats[STAT_MAX_ABS_U] = abs(pivot)
        u_steps[u_used] = k
        u_values[u_used] = pivot
        u_used += 1
        u_indptr[k + 1] = u_used
        step_of_row[pivot_row] = k
        row_of_step[k] = pivot_row
        l_rows[l_used] = pivot_row
        l_values[l_used] = 1.0
        l_used += 1
        for p in range(top, m):
            row = reach[p]
            if step_of_row[row] >= 0:
                continue
            if abs(x[row]) <= drop:
                continue
            value = x[row] / pivot
            l_rows[l_used] = row
            l_values[l_used] = value
            l_used += 1
            if abs(value) > stats[STAT_MAX_ABS_L]:
                stats[STAT_MAX_ABS_L] = abs(value)
        l_indptr[k + 1] = l_used
    return l_indptr, l_rows, l_values, u_indptr, u_steps, u_values, step_of_row, row_of_step


@njit(**_JIT)
def solve_upper(u_indptr, u_steps, u_values, rhs):
    """``rhs <- U^-1 rhs`` in place (indexed by pivot step in, by column out)."""
    n = u_indptr.size - 1
    for k in range(n - 1, -1, -1):
        end = u_indptr[k + 1] - 1
        value = rhs[k] / u_values[end]
        rhs[k] = value
        for q in range(u_indptr[k], end):
            rhs[u_steps[q]] -= u_values[q] * value


@njit(**_JIT)
def solve_upper_transposed(u_indptr, u_steps, u_values, rhs):
    """``rhs <- U^-T rhs`` in place (indexed by column in, by pivot step out)."""
    n = u_indptr.size - 1
    for k in range(n):
        end = u_indptr[k + 1] - 1
        value = rhs[k]
        for q in range(u_indptr[k], end):
            value -= u_values[q] * rhs[u_steps[q]]
        rhs[k] = value / u_values[end]


@njit(**_JIT)
def solve_lower_transposed(l_indptr, l_rows, l_values, step_of_row, out):
    """``out <- L_K^-T out`` in place (indexed by pivot step): L_K, the chosen rows of L."""
    n = l_indptr.size - 1
    for k in range(n - 1, -1, -1):
        value = out[k]
        for q in range(l_indptr[k] + 1, l_indptr[k + 1]):
            step = step_of_row[l_rows[q]]
            if step >= 0:
                value -= l_values[q] * out[step]
        out[k] = value


@njit(**_JIT)
def solve_lower(l_indptr, l_rows, l_values, step_of_row, out):
    """``out <- L_K^-1 out`` in place (indexed by pivot step): L_K, the chosen rows of L."""
    n = l_indptr.size - 1
    for k in range(n):
        value = out[k]
        for q in range(l_indptr[k] + 1, l_indptr[k + 1]):
            step = step_of_row[l_rows[q]]
            if step >= 0:
                out[step] -= l_values[q] * value
