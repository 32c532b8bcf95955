"""When and how `sparsekin.engine.linalg.RefactorSolver` solves without its factors' zeros.

The compaction (`sparsekin.engine._compact_lu_kernels`) costs about 0.8 of a solve and saves
about 0.13 of each solve after it (the 10^4-body chain's saddle matrix; docs/design-notes.md,
"Compact factors"): a factorization is compacted at its solve after `COMPACT_AFTER_SOLVES`,
which a kinematic step's (one refactorization, two solves) never reaches and forward
dynamics' held iteration matrix (a hundred solves and more) always does.
"""

from __future__ import annotations

import numpy as np

from ._compact_lu_kernels import compact_in_place, compact_relative_in_place, offsets_fit
from ._relative_lu_kernels import relative_pattern

__all__ = ["COMPACT_AFTER_SOLVES", "compacted", "relative_patterns"]

#: Solves of one factorization on its structural factors before it is compacted.
COMPACT_AFTER_SOLVES = 8


def relative_patterns(lower: tuple, upper: tuple):
    """L's and U's structural patterns, each ``(indptr, indices)``, as relative ones
    (`sparsekin.engine._relative_lu_kernels`): ``((l_counts, l_offsets), (u_counts,
    u_offsets))``, or None where a row is too far from its column or a column too long.
    The four arrays are views of one block: apart, at 10^6 bodies each is under glibc's
    largest mmap threshold (32 MB) and comes from the heap, which keeps a flat crossing's
    freed ones resident and grows for the new pivots' larger ones."""
    if not all(offsets_fit(indptr, indices) for indptr, indices in (lower, upper)):
        return None
    sizes = [size for indptr, indices in (lower, upper) for size in (indptr.size - 1, indices.size)]
    block = np.empty(sum(sizes), dtype=np.uint8)  # one allocation: mapped, not from the heap
    ends = np.cumsum(sizes)
    views = [block[end - size : end] for size, end in zip(sizes, ends)]
    patterns = ((views[0], views[1].view(np.int8)), (views[2], views[3].view(np.int8)))
    for (indptr, indices), (counts, offsets) in zip((lower, upper), patterns):
        relative_pattern(indptr, indices, counts, offsets)
    return patterns


def compacted(lower: tuple, upper: tuple, arrays, relative: bool = False):
    """Compact L's and U's values in place, ``lower`` and ``upper`` each ``(indptr, indices,
    values)`` on the structural pattern.

    Parameters
    ----------
    arrays : tuple or None
        The arrays this function returned for the same pattern before, or None.
    relative : bool
        The patterns are relative ones (`relative_patterns`): ``(counts, offsets, values)``.

    Returns
    -------
    ((l_counts, l_offsets), (u_counts, u_offsets)) or False
        The compact factors' counts and offsets (filled), or False, the values untouched,
        if the pattern's offsets or counts do not fit in a byte (`offsets_fit`).
    """
    if arrays is None:
        if not (relative or all(offsets_fit(indptr, indices) for indptr, indices, _ in (lower, upper))):
            return False
        arrays = tuple((np.zeros(indptr.size - (not relative), dtype=np.uint8), np.zeros(indices.size, dtype=np.int8))
                       for indptr, indices, _ in (lower, upper))  # fmt: skip
    kernel = compact_relative_in_place if relative else compact_in_place
    for (indptr, indices, values), (counts, offsets) in zip((lower, upper), arrays):
        kernel(indptr, indices, values, counts, offsets)
    return arrays
