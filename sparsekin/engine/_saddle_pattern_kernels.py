"""numba kernels of the saddle matrix's CSR pattern made from its parts (`sparsekin.engine.saddle`).

`sparsekin.engine._dynamics_kernels.saddle_pattern` sorts every triplet of S: the coordinate
block's, Φq's and Φqᵀ's (two per Jacobian entry) and the diagonal's.  Only the block needs a
sort.  A kept equation's row of S is its Jacobian row (columns below n, already ascending)
and its diagonal; a coordinate's row is its block columns (sorted, each once) and then the
kept equations that hold it, in the Jacobian's row order.  Built that way the pattern is the
same, entry for entry, as the sort's, without 2 nnz(Φq) + m triplets (16 bytes each) and
their sort: `coordinate_block_rows` sorts the block, `saddle_rows` counts every row,
`fill_saddle_pattern` writes the columns and the slots.  They answer False where the
Jacobian's rows are not strictly ascending or the kept equations not in order (the caller
sorts every triplet then).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._jit import JIT
from ._dynamics_kernels import INSERTION_SORT_MAX

__all__ = ["coordinate_block_rows", "saddle_rows", "fill_saddle_pattern"]


@njit(**JIT)
def coordinate_block_rows(rows, cols, count, n):
    """The coordinate block's rows of S from its first `count` triplets (indices below n:
    coordinates; ``n .. n + 2``, the ground's, and negative ones: discarded).

    Returns ``(ok, start, columns)``: row r's columns, ascending and each once, are
    ``columns[start[r]:start[r + 1]]`` (of the triplets' index type).  ``ok`` is False
    (and the arrays empty) if an index is from ``n + 3`` on (an equation's: not a block
    triplet)."""
    start = np.zeros(n + 1, dtype=np.int64)
    for e in range(count):
        r, c = rows[e], cols[e]
        if r >= n + 3 or c >= n + 3:
            return False, start, np.zeros(0, dtype=cols.dtype)
        if 0 <= r < n and 0 <= c < n:
            start[r + 1] += 1
    for r in range(n):
        start[r + 1] += start[r]
    columns = np.empty(start[n], dtype=cols.dtype)
    fill = start[:n].copy()
    for e in range(count):
        r, c = rows[e], cols[e]
        if 0 <= r < n and 0 <= c < n:
            columns[fill[r]] = c
            fill[r] += 1
    unique = 0
    for r in range(n):
        first, end = start[r], start[r + 1]
        if end - first > INSERTION_SORT_MAX:
            columns[first:end] = np.sort(columns[first:end])
        else:
            for k in range(first + 1, end):
                column = columns[k]
                before = k - 1
                while before >= first and columns[before] > column:
                    columns[before + 1] = columns[before]
                    before -= 1
                columns[before + 1] = column
        start[r] = unique
        for k in range(first, end):
            if k == first or columns[k] != columns[k - 1]:
                columns[unique] = columns[k]  # unique <= k: compaction in place
                unique += 1
    start[n] = unique
    return True, start, columns[:unique]  # (a view: the caller drops it after the fill, no copy)


@njit(**JIT)
def saddle_rows(block_start, indptr, indices, kept_row, n, saddle_indptr):
    """Row pointers of S (`saddle_indptr`, size + 1): a coordinate's row holds its block
    columns (`block_start` of `coordinate_block_rows`) and one column per kept equation that
    holds it; a kept equation's row its Jacobian columns below n and its diagonal.  False
    if a Jacobian row (`indptr`, `indices`) is not strictly ascending or the kept equations'
    indices (`kept_row`, −1: left out) do not ascend with their rows.  `saddle_indptr` must be
    zero on entry (it holds the counts on the way)."""
    size = saddle_indptr.size - 1
    counts = saddle_indptr[1:]  # (row r's count in place of its end; zero on entry)
    for j in range(n):
        counts[j] = block_start[j + 1] - block_start[j]
    last_kept = -1
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        for s in range(indptr[r] + 1, indptr[r + 1]):
            if indices[s] <= indices[s - 1]:
                return False
        if kept < 0:
            continue
        if kept <= last_kept or n + kept >= size:
            return False
        last_kept = kept
        own = 1  # the diagonal
        for s in range(indptr[r], indptr[r + 1]):
            if indices[s] < n:
                counts[indices[s]] += 1
                own += 1
        counts[n + kept] = own
    saddle_indptr[0] = 0
    for row in range(size):
        saddle_indptr[row + 1] += saddle_indptr[row]
    return True


@njit(**JIT)
def fill_saddle_pattern(triplets, block_start, block_columns, jacobian, n, saddle_indptr, saddle_indices, block_slots,
                        transposed_slots):  # fmt: skip
    """S's column indices (`saddle_indices`, on `saddle_rows`' pointers) and the slots of
    the block's first ``block_slots.size`` triplets (``triplets = (rows, cols)``; their
    rows' columns from `coordinate_block_rows`) and of Φqᵀ's entry for each Jacobian entry
    (`transposed_slots`); ``nnz``, the discard slot, for the ground's and left-out
    equations'.  `jacobian` is ``(indptr, indices, kept_row)``."""
    rows, cols = triplets
    indptr, indices, kept_row = jacobian
    nnz = saddle_indptr[saddle_indptr.size - 1]
    following = np.empty(n, dtype=np.int64)  # the next free place of each coordinate's row
    for j in range(n):
        first = saddle_indptr[j]
        width = block_start[j + 1] - block_start[j]
        for k in range(width):
            saddle_indices[first + k] = block_columns[block_start[j] + k]
        following[j] = first + width
    for e in range(block_slots.size):
        r, c = rows[e], cols[e]
        if 0 <= r < n and 0 <= c < n:  # c among its row's block columns (ascending): bisection
            low, high = saddle_indptr[r], following[r] - 1
            while low < high:
                middle = (low + high) // 2
                if saddle_indices[middle] < c:
                    low = middle + 1
                else:
                    high = middle
            block_slots[e] = low
        else:
            block_slots[e] = nnz
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        if kept < 0:
            for s in range(indptr[r], indptr[r + 1]):
                transposed_slots[s] = nnz
            continue
        own = saddle_indptr[n + kept]
        for s in range(indptr[r], indptr[r + 1]):
            column = indices[s]
            if column < n:
                saddle_indices[own] = column
                own += 1
                saddle_indices[following[column]] = n + kept
                transposed_slots[s] = following[column]
                following[column] += 1
            else:
                transposed_slots[s] = nnz
        saddle_indices[own] = n + kept
