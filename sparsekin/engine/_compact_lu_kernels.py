"""numba kernel that takes the zeros out of a refactorization's factors, for the solves.

The structural patterns of L and U (`_lu_kernels.analyse_lu_pattern`) hold every entry that
can be nonzero with the pivot sequence fixed.  On a linkage's saddle matrix about a quarter
of them are exactly zero at every configuration met (the 10^4-body N-four-bar chain's
held iteration matrix: 110 000 of 415 000 off the diagonal; exact cancellations of the
joints' constant coefficients and of the mass matrix's blocks), and a solve multiplies and
subtracts each of them all the same.  A solve of a chain's saddle matrix is bound by the
work per entry, not by its chain of dependent additions nor by memory at 10^4 unknowns
(docs/design-notes.md, "Compact factors"): `compact_in_place` after each numeric
refactorization gives the solves the factors without their zeros.

`refactor_lu` writes every entry to its structural place and reads only what it wrote in
the same call (L's columns before the current one), so the values array can be compacted in
place between refactorizations: only the compact rows need an array of their own.  Symbols
as in `sparsekin.engine._lu_kernels`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._jit import JIT as _JIT

_wide = np.int64  # a loop bound read from an int32 array, counted in int64


@njit(**_JIT)
def compact_in_place(indptr, indices, values, out_indptr, out_indices):
    """A compressed-column factor without its exactly zero entries: the nonzero `values`
    moved to the front of `values` (in order), their rows to `out_indices` and the new
    column pointers to `out_indptr` (shape (n + 1,), as `indptr`'s dtype); `indptr` and
    `indices` (the structural pattern) are left as they are.  NaN entries are kept.  A
    solve on ``(out_indptr, out_indices, values)`` gives the structural factor's solution
    (``w - 0 * x`` is ``w``, to the sign of a zero)."""
    kept = 0
    out_indptr[0] = 0
    for j in range(indptr.size - 1):
        for p in range(_wide(indptr[j]), _wide(indptr[j + 1])):
            value = values[p]
            out_indices[kept] = indices[p]  # written always, kept if nonzero: no branch to mispredict
            values[kept] = value
            kept += value != 0.0
        out_indptr[j + 1] = kept
