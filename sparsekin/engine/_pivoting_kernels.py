"""numba kernel: new row pivots for a held column order, by threshold partial pivoting.

`RefactorSolver` refactors on a fixed pivot sequence.  When the guard rejects it, the
matrix needs new row pivots, but its column order (a fill-reducing order of the pattern,
which has not changed) stays good.  `partial_pivoting_rows` chooses them by threshold
partial pivoting on that column order (left-looking, Gilbert–Peierls): each column keeps
its held pivot row while that is within `threshold` of the column's largest candidate,
else takes the largest (the diagonal where it ties: SuperLU's rule).  Kept rows keep the
held factors' fill; threshold 1 is plain partial pivoting, LAPACK's choice.  It holds only
L's columns: the elimination of column j reads L, never U.  SuperLU makes both factors in
its own storage on top of the caller's arrays, ~1 GB at the 10^6-body chain's saddle
(docs/design-notes.md, "New pivots on the held column order").

Symbols as in `sparsekin.engine._lu_kernels`: ``A = jacobian.T``; B is A with its columns
in the held order and its rows as they come: column j of B is a contiguous run of the
values, its entry p (``b_indptr[j] <= p < b_indptr[j + 1]``) in row ``indices[p +
offsets[j]]`` of A, valued ``values[p]`` in factor order or ``values[p + offsets[j]]``.
Rows are A's own numbers throughout; ``pivot_of[i]`` is the column whose pivot row i
became (-1 while it is a candidate): that is ``perm_r``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT as _JIT


@njit(**_JIT)
def partial_pivoting_rows(values, in_factor_order, b_pattern, indices, held, threshold, l_capacity, work):
    """Row pivots of B by left-looking threshold partial pivoting; the factors' structural sizes.

    Parameters
    ----------
    values, in_factor_order
        B's values, as `sparsekin.engine._lu_kernels.refactor_lu` reads them.
    b_pattern : tuple
        ``(b_indptr, offsets)``: B's column pointers and each column's offset in `values`
        and `indices`.
    indices : ndarray
        The CSR column indices of the Jacobian: row ``indices[p + offsets[j]]`` of A.
    held : tuple
        ``(perm_r, perm_c)``, the held order: column c of A is column ``perm_c[c]`` of B
        (its diagonal entry, row c, is the pivot where it ties with the largest candidate),
        and column j's held pivot row i (``perm_r[i] == j``) stays its pivot while
        ``|x_i| >= threshold * max |x|`` over the column's candidates.
    threshold : float
        In (0, 1].
    l_capacity : int
        Entries of L to allocate first (grown by doubling if short).
    work : ndarray of float64, shape (n,)
        Zero on entry and on return.

    Returns
    -------
    pivot_of : ndarray of the dtype of `indices`, shape (n,)
        Row i of A is row ``pivot_of[i]`` of the permuted matrix (SuperLU's ``perm_r``).
    bad_column : int
        The first column without a nonzero finite candidate (then `pivot_of` is
        incomplete), else -1.
    l_entries, u_entries : int
        Entries of L's strictly lower and U's strictly upper structural patterns with these
        pivots (what `analyse_lu_pattern` will find).
    """
    b_indptr, offsets = b_pattern
    n = b_indptr.size - 1
    index = indices.dtype  # rows and columns (int32 up to 2^31 rows: half the memory)
    pivot_of = np.full(n, -1, dtype=index)
    # the row scratch in one allocation: at 10^6 bodies 5 arrays of 24 MB, each under glibc's
    # largest mmap threshold (32 MB), came from the heap and stayed resident after the
    # crossing (the heap keeps freed chunks); one of 120 MB is mapped and given back whole
    scratch = np.empty((5, n), dtype=index)
    mark = scratch[0]
    mark[:] = -1
    stack = scratch[1]  # depth-first search: row ...
    next_child = np.empty(n, dtype=np.int64)  # ... and the position of its next child in L
    reach = scratch[2]  # the rows of column j, topological order at the end
    l_indptr = np.zeros(n + 1, dtype=np.int64)
    l_rows = np.empty(max(l_capacity, n, 1), dtype=index)
    l_values = np.empty(l_rows.size)
    perm_r, perm_c = held
    column_of = scratch[3]  # column j of B is column column_of[j] of A
    held_row = scratch[4]  # column j's held pivot row
    for c in range(n):
        column_of[perm_c[c]] = c
        held_row[perm_r[c]] = c
    u_entries = 0
    for j in range(n):
        shift = offsets[j]
        top = n
        for p in range(b_indptr[j], b_indptr[j + 1]):
            r = indices[p + shift]
            if mark[r] == j:
                continue
            mark[r] = j
            depth = 0
            stack[0] = r
            next_child[0] = l_indptr[pivot_of[r]] if pivot_of[r] >= 0 else 0
            while depth >= 0:
                row = stack[depth]
                column = pivot_of[row]
                position = next_child[depth]
                if column < 0 or position == l_indptr[column + 1]:
                    top -= 1
                    reach[top] = row  # finished: after every row it updates
                    depth -= 1
                    continue
                next_child[depth] = position + 1
                child = l_rows[position]
                if mark[child] == j:
                    continue
                mark[child] = j
                depth += 1
                stack[depth] = child
                next_child[depth] = l_indptr[pivot_of[child]] if pivot_of[child] >= 0 else 0
        for p in range(b_indptr[j], b_indptr[j + 1]):
            work[indices[p + shift]] += values[p] if in_factor_order else values[p + shift]
        largest = 0.0
        pivot_row = -1
        diagonal = column_of[j]
        for t in range(top, n):
            row = reach[t]
            column = pivot_of[row]
            x = work[row]
            if column < 0:
                if abs(x) > largest:  # NaN never is
                    largest = abs(x)
                    pivot_row = row
                continue
            u_entries += 1
            for q in range(l_indptr[column], l_indptr[column + 1]):
                work[l_rows[q]] -= l_values[q] * x
        if pivot_row >= 0:
            kept = held_row[j]
            if mark[kept] == j and pivot_of[kept] < 0 and abs(work[kept]) >= threshold * largest:
                pivot_row = kept
            elif mark[diagonal] == j and pivot_of[diagonal] < 0 and abs(work[diagonal]) == largest:
                pivot_row = diagonal
        if pivot_row < 0 or not largest < math.inf:
            for t in range(top, n):
                work[reach[t]] = 0.0
            return pivot_of, j, l_indptr[j], u_entries
        pivot_of[pivot_row] = j
        inverse = 1.0 / work[pivot_row]
        start = l_indptr[j]
        if start + (n - top) > l_rows.size:
            size = max(2 * l_rows.size, start + n - top)
            grown_rows, grown_values = np.empty(size, dtype=index), np.empty(size)
            grown_rows[:start], grown_values[:start] = l_rows[:start], l_values[:start]
            l_rows, l_values = grown_rows, grown_values
        end = start
        for t in range(top, n):
            row = reach[t]
            if pivot_of[row] < 0:
                l_rows[end] = row
                l_values[end] = work[row] * inverse
                end += 1
            work[row] = 0.0
        l_indptr[j + 1] = end
    return pivot_of, -1, l_indptr[n], u_entries
