"""numba kernels of the LU factorization that chooses independent rows of a tall Jacobian.

Symbols (for these kernels only):

* ``M = A^T`` — the transpose of the (scaled) Jacobian A (m equations, n coordinates):
  n rows (coordinates) by m columns (equations), given by columns (CSC; the rows of A as
  CSR) in the order the equations are offered: ``a_indptr``, ``a_rows``, ``a_values``.
* The columns of M are taken in turn; a column whose remainder (after the columns kept so
  far) is at most ``tolerance`` is a combination of them and is skipped (a redundant
  equation); the others are kept, each with a pivot row (a coordinate) by partial pivoting.
  With ``K`` the kept columns in pivot-step order and ``P`` the coordinates' pivot order,
  ``P M_K = L U``.
* ``L`` — n by n, unit lower triangular, by columns with coordinate row indices
  (``l_indptr``, ``l_rows``, ``l_values``; the first entry of column s is its pivot row,
  value 1); ``U`` — upper triangular, by columns with pivot-step row indices (``u_indptr``,
  ``u_steps``, ``u_values``; the diagonal last).
* ``step_of_row`` — the pivot step of each coordinate (-1 if none: a free coordinate);
  ``row_of_step`` its inverse; ``column_of_step`` — the position in the offered order of the
  equation kept at each step.
* For the solves, ``L``'s strict part by columns with pivot-step row indices:
  ``k_indptr``, ``k_steps``, ``k_values`` (`split_lower`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._jit import JIT as _JIT

#: Layout of the `stats` array filled by `factor_rows`.
STAT_MAX_ABS_U = 0  # largest |U| entry (growth: the scaled A has entries up to 1)
STAT_LARGEST_SKIPPED = 1  # largest remainder of a skipped column (rounding, for a sound model)
STAT_SMALLEST_PIVOT = 2  # smallest |pivot| of a kept column
N_STATS = 3


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
def _touch(row, stamp, mark, x, touched, n_touched, step_of_row, heap, n_heap):
    """Bring `row` into the pattern of column `stamp` (x zeroed, listed, its pivot step
    queued) unless it is already there; returns the new ``n_touched, n_heap``."""
    if mark[row] != stamp:
        mark[row] = stamp
        x[row] = 0.0
        touched[n_touched] = row
        n_touched += 1
        if step_of_row[row] >= 0:
            n_heap = _push(heap, n_heap, step_of_row[row])
    return n_touched, n_heap


@njit(**_JIT)
def factor_rows(a_indptr, a_rows, a_values, n_rows, n_early, tolerance, defer, capacity, budget, stats):
    """Left-looking (Gilbert–Peierls) LU of ``M = A^T`` that keeps the independent columns.

    For column k: the sparse triangular solve with the columns of L already made (their
    pivot steps applied in increasing order from a binary heap: each reached column of L
    is read once) gives the remainder of ``M(:, k)`` on the coordinates not yet pivoted.
    If its largest entry is at most `tolerance` the column is skipped; if it is at most
    `defer`, the column is offered again after all the others (a nearly dependent row kept
    early makes the kept block ill-conditioned); otherwise the largest entry is the pivot.
    The columns from `n_early` on are offered only after the deferred ones.  Stops when
    every coordinate has a pivot, or when L and U hold more than `budget` entries (the
    order fills in too much: the steps not reached are left empty).

    Returns
    -------
    l_indptr, l_rows, l_values, u_indptr, u_steps, u_values, step_of_row, row_of_step,
    column_of_step : ndarray
        As in the module docstring, sized for n = `n_rows` steps; the arrays of the steps
        not reached (free coordinates) are left at -1 and 0.
    """
    n_columns = a_indptr.size - 1
    n = n_rows
    l_indptr = np.zeros(n + 1, dtype=np.int64)
    u_indptr = np.zeros(n + 1, dtype=np.int64)
    l_rows = np.empty(capacity, dtype=np.int64)
    l_values = np.empty(capacity)
    u_steps = np.empty(capacity, dtype=np.int64)
    u_values = np.empty(capacity)
    step_of_row = np.full(n, -1, dtype=np.int64)
    row_of_step = np.full(n, -1, dtype=np.int64)
    column_of_step = np.full(n, -1, dtype=np.int64)
    x = np.zeros(n)
    mark = np.full(n, -1, dtype=np.int64)
    touched = np.empty(n, dtype=np.int64)  # the rows of x's pattern
    heap = np.empty(n, dtype=np.int64)  # pivot steps to apply, smallest first
    stats[STAT_MAX_ABS_U] = 0.0
    stats[STAT_LARGEST_SKIPPED] = 0.0
    stats[STAT_SMALLEST_PIVOT] = np.inf
    l_used = 0
    u_used = 0
    s = 0
    deferred = np.empty(n_columns, dtype=np.int64)
    n_deferred = 0
    stamp = -1
    for offer in range(2 * n_columns):
        if s == n or l_used + u_used > budget:
            break
        first_pass = offer < n_columns
        if first_pass and offer >= n_early:  # a late column: offered only after the deferred ones
            deferred[n_deferred] = offer
            n_deferred += 1
            continue
        if first_pass:
            k = offer
        elif offer - n_columns < n_deferred:
            k = deferred[offer - n_columns]
        else:
            break
        stamp += 1
        n_touched = 0
        n_heap = 0
        for p in range(a_indptr[k], a_indptr[k + 1]):
            row = a_rows[p]
            n_touched, n_heap = _touch(row, stamp, mark, x, touched, n_touched, step_of_row, heap, n_heap)
            x[row] += a_values[p]
        while n_heap > 0:
            step = heap[0]
            n_heap = _pop(heap, n_heap)
            value = x[row_of_step[step]]
            if value == 0.0:
                continue
            for q in range(l_indptr[step] + 1, l_indptr[step + 1]):
                row = l_rows[q]
                n_touched, n_heap = _touch(row, stamp, mark, x, touched, n_touched, step_of_row, heap, n_heap)
                x[row] -= l_values[q] * value
        pivot_row = -1
        for p in range(n_touched):
            row = touched[p]
            if step_of_row[row] < 0 and (pivot_row < 0 or abs(x[row]) > abs(x[pivot_row])):
                pivot_row = row
        largest = abs(x[pivot_row]) if pivot_row >= 0 else 0.0
        if not largest > tolerance:  # a combination of the kept columns (NaN: kept out too)
            if largest > stats[STAT_LARGEST_SKIPPED]:
                stats[STAT_LARGEST_SKIPPED] = largest
            continue
        if first_pass and not largest > defer:  # nearly a combination: offered again at the end
            deferred[n_deferred] = k
            n_deferred += 1
            continue
        if u_used + n_touched > u_steps.size:
            u_steps = _grow(u_steps, u_used + n_touched)
            u_values = _grow(u_values, u_used + n_touched)
        if l_used + n_touched > l_rows.size:
            l_rows = _grow(l_rows, l_used + n_touched)
            l_values = _grow(l_values, l_used + n_touched)
        pivot = x[pivot_row]
        for p in range(n_touched):
            row = touched[p]
            step = step_of_row[row]
            if step >= 0:
                u_steps[u_used] = step
                u_values[u_used] = x[row]
                u_used += 1
                if abs(x[row]) > stats[STAT_MAX_ABS_U]:
                    stats[STAT_MAX_ABS_U] = abs(x[row])
        u_steps[u_used] = s
        u_values[u_used] = pivot
        u_used += 1
        u_indptr[s + 1] = u_used
        stats[STAT_MAX_ABS_U] = max(stats[STAT_MAX_ABS_U], largest)
        stats[STAT_SMALLEST_PIVOT] = min(stats[STAT_SMALLEST_PIVOT], largest)
        step_of_row[pivot_row] = s
        row_of_step[s] = pivot_row
        column_of_step[s] = k
        l_rows[l_used] = pivot_row
        l_values[l_used] = 1.0
        l_used += 1
        for p in range(n_touched):
            row = touched[p]
            if step_of_row[row] < 0:
                l_rows[l_used] = row
                l_values[l_used] = x[row] / pivot
                l_used += 1
        l_indptr[s + 1] = l_used
        s += 1
    for rest in range(s, n):  # steps not reached: empty columns
        l_indptr[rest + 1] = l_used
        u_indptr[rest + 1] = u_used
    return l_indptr, l_rows, l_values, u_indptr, u_steps, u_values, step_of_row, row_of_step, column_of_step


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
def split_lower(l_indptr, l_rows, l_values, step_of_row):
    """``L``'s strict part with pivot-step row indices: ``k_indptr, k_steps, k_values``."""
    n = l_indptr.size - 1
    k_indptr = np.zeros(n + 1, dtype=np.int64)
    for k in range(n):
        k_indptr[k + 1] = k_indptr[k] + max(l_indptr[k + 1] - l_indptr[k] - 1, 0)
    k_steps = np.empty(k_indptr[n], dtype=np.int64)
    k_values = np.empty(k_indptr[n])
    used = 0
    for k in range(n):
        for q in range(l_indptr[k] + 1, l_indptr[k + 1]):
            k_steps[used] = step_of_row[l_rows[q]]
            k_values[used] = l_values[q]
            used += 1
    return k_indptr, k_steps, k_values
