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
* ``L_K`` — the chosen rows of L (square, unit lower triangular), for the solves: its
  strict part by columns, row indices as pivot steps (``k_indptr``, ``k_steps``,
  ``k_values``).

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
def _push(heap, size, value):
    """Add `value` to the binary min-heap ``heap[:size]``; returns the new size."""
    at = size
    heap[at] = value
    while at > 0:
        parent = (at - 1) // 2
        if heap[parent] <= value:
            break
        heap[at] = heap[parent]
        at = parent
    heap[at] = value
    return size + 1


@njit(**_JIT)
def _pop(heap, size):
    """Remove the smallest entry ``heap[0]`` of the binary min-heap; returns the new size."""
    size -= 1
    last = heap[size]
    at = 0
    while True:
        child = 2 * at + 1
        if child >= size:
            break
        if child + 1 < size and heap[child + 1] < heap[child]:
            child += 1
        if heap[child] >= last:
            break
        heap[at] = heap[child]
        at = child
    if size > 0:
        heap[at] = last
    return size


@njit(**_JIT)
def factor_tall(a_indptr, a_rows, a_values, n_rows, preference, threshold, tolerance, drop, capacity, stats):
    """Left-looking (Gilbert–Peierls) LU of a tall ``A`` with threshold row pivoting.

    For column k: the sparse triangular solve with the columns of L already made (each
    column of L read once: its pivot steps ordered by a heap instead of a depth-first
    search, which would read every reached column twice) gives the
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
    touched = np.empty(m, dtype=np.int64)  # the rows of x's pattern
    heap = np.empty(n, dtype=np.int64)  # pivot steps to apply, smallest first
    stats[STAT_MIN_PIVOT_RATIO] = 1.0
    stats[STAT_MAX_ABS_U] = 0.0
    stats[STAT_MAX_ABS_L] = 1.0
    stats[STAT_FAILED_COLUMN] = -1.0
    l_used = 0
    u_used = 0
    for k in range(n):
        # x = remainder of A(:, k): the updates by the columns of L of the pivot steps it
        # reaches, in increasing order of step (a topological order: column J of L only
        # reaches rows chosen after step J), the steps to come kept in a binary heap
        n_touched = 0
        n_heap = 0
        for p in range(a_indptr[k], a_indptr[k + 1]):
            row = a_rows[p]
            if mark[row] != k:
                mark[row] = k
                x[row] = 0.0
                touched[n_touched] = row
                n_touched += 1
                if step_of_row[row] >= 0:
                    n_heap = _push(heap, n_heap, step_of_row[row])
            x[row] += a_values[p]
        while n_heap > 0:
            step = heap[0]
            n_heap = _pop(heap, n_heap)
            value = x[row_of_step[step]]
            if value == 0.0:
                continue
            for q in range(l_indptr[step] + 1, l_indptr[step + 1]):
                row = l_rows[q]
                if mark[row] != k:
                    mark[row] = k
                    x[row] = 0.0
                    touched[n_touched] = row
                    n_touched += 1
                    if step_of_row[row] >= 0:
                        n_heap = _push(heap, n_heap, step_of_row[row])
                x[row] -= l_values[q] * value
        # U's column and the largest candidate
        largest = 0.0
        n_entries = n_touched
        if u_used + n_entries + 1 > u_steps.size:
            u_steps = _grow(u_steps, u_used + n_entries + 1)
            u_values = _grow(u_values, u_used + n_entries + 1)
        if l_used + n_entries + 1 > l_rows.size:
            l_rows = _grow(l_rows, l_used + n_entries + 1)
            l_values = _grow(l_values, l_used + n_entries + 1)
        for p in range(n_touched):
            row = touched[p]
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
        for p in range(n_touched):
            row = touched[p]
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
        for p in range(n_touched):
            row = touched[p]
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
def solve_lower_transposed(k_indptr, k_steps, k_values, rhs):
    """``rhs <- L_K^-T rhs`` in place (indexed by pivot step).

    ``L_K``: the chosen rows of L, unit lower triangular, its strict part by columns with
    row indices that are pivot steps (``k_indptr``, ``k_steps``, ``k_values``).
    """
    n = k_indptr.size - 1
    for k in range(n - 1, -1, -1):
        value = rhs[k]
        for q in range(k_indptr[k], k_indptr[k + 1]):
            value -= k_values[q] * rhs[k_steps[q]]
        rhs[k] = value


@njit(**_JIT)
def solve_lower(k_indptr, k_steps, k_values, rhs):
    """``rhs <- L_K^-1 rhs`` in place (indexed by pivot step)."""
    n = k_indptr.size - 1
    for k in range(n):
        value = rhs[k]
        for q in range(k_indptr[k], k_indptr[k + 1]):
            rhs[k_steps[q]] -= k_values[q] * value


@njit(**_JIT)
def split_lower(l_indptr, l_rows, l_values, step_of_row, n_redundant):
    """L's rows split: ``L_K``'s strict part (by columns, rows as pivot steps) and the rows of
    the redundant equations as a CSR matrix (``r_indptr``, ``r_steps``, ``r_values``; one
    row per redundant equation in ascending order of its row, columns by pivot step).

    Returns
    -------
    k_indptr, k_steps, k_values, r_indptr, r_steps, r_values
    """
    n = l_indptr.size - 1
    m = step_of_row.size
    position = np.full(m, -1, dtype=np.int64)
    count = 0
    for row in range(m):
        if step_of_row[row] < 0:
            position[row] = count
            count += 1
    k_indptr = np.zeros(n + 1, dtype=np.int64)
    r_indptr = np.zeros(n_redundant + 1, dtype=np.int64)
    for k in range(n):
        kept = 0
        for q in range(l_indptr[k] + 1, l_indptr[k + 1]):
            row = l_rows[q]
            if step_of_row[row] >= 0:
                kept += 1
            else:
                r_indptr[position[row] + 1] += 1
        k_indptr[k + 1] = k_indptr[k] + kept
    for r in range(n_redundant):
        r_indptr[r + 1] += r_indptr[r]
    k_steps = np.empty(k_indptr[n], dtype=np.int64)
    k_values = np.empty(k_indptr[n])
    r_steps = np.empty(r_indptr[n_redundant], dtype=np.int64)
    r_values = np.empty(r_indptr[n_redundant])
    filled = r_indptr[:-1].copy()
    used = 0
    for k in range(n):
        for q in range(l_indptr[k] + 1, l_indptr[k + 1]):
            row = l_rows[q]
            step = step_of_row[row]
            if step >= 0:
                k_steps[used] = step
                k_values[used] = l_values[q]
                used += 1
            else:
                at = filled[position[row]]
                r_steps[at] = k
                r_values[at] = l_values[q]
                filled[position[row]] = at + 1
    return k_indptr, k_steps, k_values, r_indptr, r_steps, r_values
