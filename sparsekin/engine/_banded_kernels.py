"""numba kernels of a banded LU with partial pivoting, for the compiled dynamics loop.

A chain-like model's saddle matrix, its unknowns put in reverse Cuthill–McKee order once,
has all its entries within a narrow band about the diagonal: ``kl`` below, ``ku`` above
(the IFToMM N-four-bar at N = 40: 485 unknowns, ``kl = ku = 9``).  Its LU with partial
pivoting stays in a band: L keeps ``kl`` entries below the diagonal, and the row
interchanges widen U to ``kl + ku`` above.  The storage is LAPACK's ``gbtrf`` layout,
column-major, with ``ldab = 2 kl + ku + 1`` rows: entry ``A[i, j]`` of the band at
``band[kl + ku + i - j, j]``, the top ``kl`` rows left for the fill of the interchanges.

Symbols (for these kernels only):

* ``order`` — the unknowns' order: unknown ``order[i]`` of the saddle matrix is unknown
  ``i`` of the banded one (rows and columns alike).
* ``band_slot`` — shape (2, nnz): entry ``s`` of the saddle matrix's CSR values goes to
  ``band[band_slot[0, s], band_slot[1, s]]``
  (`sparsekin.solve._saddle_factorization.band_slots` computes it).
* ``pivots`` — as LAPACK's ``gbtrf`` but 0-based: at step j, rows j and ``pivots[j] >= j``
  of the banded matrix were swapped.
* ``factors`` — ``(pointers, rows, values)``: the nonzero entries of L (below the
  diagonal, row 0 of each array) and of U (above it, row 1) by columns, as CSC: column j's
  entries of L are ``rows[0, pointers[0, j]:pointers[0, j + 1]]`` (rows of the banded
  matrix) with their ``values[0, …]``.  `compress_factors` fills them from the band.

`factor_band` refills the band from the CSR values, factors it in place on the fixed band
and compresses its factors; `solve_band` solves with them.  Neither allocates (the time
loop that calls them is compiled without reference counting).  The compressed solve
skips the exact zeros of the band, which are most of it on a saddle matrix (A02: 2 595
nonzeros in L and U against 13 095 places in their band), and rounds as the banded solve
does (`banded_lu_solve`, kept as the reference).
"""

from __future__ import annotations

import math

from numba import njit

from .._jit import JIT as _JIT

__all__ = ["band_schedule", "banded_lu", "banded_lu_solve", "compress_factors", "compressed_lu_solve", "factor_band",
           "factor_band_held", "refactor_band", "solve_band"]


@njit(**_JIT)
def banded_lu(band, lower, upper, pivots, extent):
    """LU with partial pivoting of a banded matrix in place (LAPACK's ``gbtf2``); True
    unless a pivot fails.

    Exact zeros are skipped, as `sparsekin.engine._lu_kernels.dense_lu_factor` skips them:
    the updates of column j run over its multipliers down to the last nonzero one only,
    and a zero entry of the pivot row updates nothing.  A saddle matrix's band is mostly
    zeros even after the factorization (A02: a quarter of L's and U's band holds
    nonzeros), so `extent` records, per column, how far L and U reach for the solves.

    Parameters
    ----------
    band : ndarray, shape (2 lower + upper + 1, n), float64, Fortran order
        The matrix in rows ``lower`` … (its top `lower` rows zero); overwritten by U (rows
        0 … ``lower + upper``) and L's multipliers (the rows below).
    lower, upper : int
        The bandwidths below and above the diagonal.
    pivots : ndarray, shape (n,), int64
        Filled with the row interchanges (module docstring).
    extent : ndarray, shape (2, n), int64
        Filled with, for column j, the storage row of U's first nonzero above the diagonal
        (``lower + upper`` if none) and the count of L's multipliers down to its last
        nonzero one: what `banded_lu_solve` runs over.

    Returns
    -------
    bool
        False if a pivot is exactly zero or not finite (the matrix is singular, or holds an
        inf or NaN in a pivot's column); `band`, `pivots` and `extent` are then only partly
        filled.
    """
    n = band.shape[1]
    kv = lower + upper
    last = 0  # the last column the interchanges and updates so far reach
    for j in range(n):
        below = min(lower, n - 1 - j)
        best = 0
        largest = abs(band[kv, j])
        for i in range(1, below + 1):
            magnitude = abs(band[kv + i, j])
            if magnitude > largest:
                largest = magnitude
                best = i
        pivots[j] = j + best
        if not (largest > 0.0 and largest < math.inf):  # NaN fails both tests
            return False
        last = max(last, min(j + upper + best, n - 1))
        if best != 0:
            for c in range(j, last + 1):
                r = kv + j - c
                band[r + best, c], band[r, c] = band[r, c], band[r + best, c]
        inverse = 1.0 / band[kv, j]
        reach = 0
        for i in range(1, below + 1):
            band[kv + i, j] *= inverse
            if band[kv + i, j] != 0.0:
                reach = i
        extent[1, j] = reach
        for c in range(j + 1, last + 1):
            r = kv + j - c
            pivot_row = band[r, c]
            if pivot_row != 0.0:
                for i in range(1, reach + 1):
                    band[r + i, c] -= band[kv + i, j] * pivot_row
    for j in range(n):
        top = kv
        for r in range(max(0, kv - j), kv):
            if band[r, j] != 0.0:
                top = r
                break
        extent[0, j] = top
    return True


@njit(**_JIT)
def banded_lu_solve(band, lower, upper, pivots, extent, b):
    """Solve ``matrix @ x = b`` in place in `b` (shape (n,)) from `banded_lu`'s output
    (LAPACK's ``gbtrs``, over the `extent` of L's and U's columns): the interchanges and L
    column by column, then U."""
    n = band.shape[1]
    kv = lower + upper
    for j in range(n):
        swap = pivots[j]
        if swap != j:
            b[j], b[swap] = b[swap], b[j]
        x_j = b[j]
        if x_j != 0.0:
            for i in range(1, extent[1, j] + 1):
                b[j + i] -= band[kv + i, j] * x_j
    for j in range(n - 1, -1, -1):
        x_j = b[j] / band[kv, j]
        b[j] = x_j
        if x_j != 0.0:
            for r in range(extent[0, j], kv):
                b[j - kv + r] -= band[r, j] * x_j


@njit(**_JIT)
def compress_factors(band, lower, upper, extent, factors):
    """The nonzero entries of `banded_lu`'s L and U (off the diagonal) into `factors`
    (module docstring; capacity ``n (lower + upper)`` each)."""
    pointers, rows, values = factors
    n = band.shape[1]
    kv = lower + upper
    lower_count = upper_count = 0
    for j in range(n):
        pointers[0, j] = lower_count
        for i in range(1, extent[1, j] + 1):
            value = band[kv + i, j]
            if value != 0.0:
                rows[0, lower_count] = j + i
                values[0, lower_count] = value
                lower_count += 1
        pointers[1, j] = upper_count
        for r in range(extent[0, j], kv):
            value = band[r, j]
            if value != 0.0:
                rows[1, upper_count] = j - kv + r
                values[1, upper_count] = value
                upper_count += 1
    pointers[0, n] = lower_count
    pointers[1, n] = upper_count


@njit(**_JIT)
def compressed_lu_solve(band, lower, upper, pivots, factors, b, reciprocals=None):
    """`banded_lu_solve` on the compressed `factors` (`compress_factors`): the same
    operations on the nonzero entries only, so the same result; with `reciprocals` (U's
    diagonal inverted, `refactor_band`) multiplied instead of divided (the last bit of
    each unknown may differ; 1.1× faster on A02: the division was on the back
    substitution's chain of dependences)."""
    pointers, rows, values = factors
    n = band.shape[1]
    kv = lower + upper
    for j in range(n):
        swap = pivots[j]
        if swap != j:
            b[j], b[swap] = b[swap], b[j]
        x_j = b[j]
        if x_j != 0.0:
            for p in range(pointers[0, j], pointers[0, j + 1]):
                b[rows[0, p]] -= values[0, p] * x_j
    for j in range(n - 1, -1, -1):
        x_j = b[j] / band[kv, j] if reciprocals is None else b[j] * reciprocals[j]
        b[j] = x_j
        if x_j != 0.0:
            for p in range(pointers[1, j], pointers[1, j + 1]):
                b[rows[1, p]] -= values[1, p] * x_j


@njit(**_JIT)
def factor_band(values, band_slot, band, lower, upper, pivots, extent, factors):
    """Refill `band` from the CSR `values` of the saddle matrix (through `band_slot`),
    factor it (`banded_lu`) and compress its factors into `factors`; True unless a pivot
    fails."""
    _refill(values, band_slot, band)
    if not banded_lu(band, lower, upper, pivots, extent):
        return False
    compress_factors(band, lower, upper, extent, factors)
    return True


@njit(**_JIT)
def solve_band(band, lower, upper, pivots, factors, order, scratch, b, reciprocals=None):
    """Solve the saddle matrix's system in place in `b` from `factor_band`'s factors: `b`
    into the banded order (through `scratch`, shape (n,)), `compressed_lu_solve` (with
    `reciprocals`), and back."""
    n = order.size
    for i in range(n):
        scratch[i] = b[order[i]]
    compressed_lu_solve(band, lower, upper, pivots, factors, scratch, reciprocals)
    for i in range(n):
        b[order[i]] = scratch[i]


# ---------------------------------------------------------------------- held pivots
#: ``schedule`` (`band_schedule`, `refactor_band`): ``(flat, pointers, held, swaps, multipliers,
#: updates, upper_positions, structure, reciprocals)``: ``flat`` the band's storage as one vector (a view, column by
#: column); ``pointers`` shape (4, n + 1): where column j's swaps, multipliers, updates and U
#: entries start in the three lists and `upper_positions`, and ``pointers[0, n]`` … their
#: ends; ``pointers[3, 0]`` is −1 while no schedule is held; ``held`` the pivots it was made
#: for; ``swaps`` shape (2, capacity) the pairs of positions in ``flat`` that the row
#: interchange of column j exchanges; ``multipliers`` the positions of L's entries of column
#: j; ``updates`` shape (3, capacity): target, multiplier and pivot-row positions of one
#: update ``flat[t] -= flat[l] * flat[u]``; ``upper_positions`` U's entries by columns (the
#: order of `compress_factors`); ``structure`` scratch, bool, shape (n, rows of the band): entry
#: (c, r) for the band's (r, c); ``reciprocals`` 1 / U's diagonal (`compressed_lu_solve`).  Empty
#: lists (capacity 0): no schedule is made.
_SWAPS, _MULTIPLIERS, _UPDATES, _UPPER = range(4)


@njit(**_JIT)
def band_schedule(band_slot, lower, upper, pivots, schedule, factors):
    """The operations of `banded_lu` with the row interchanges `pivots`, on every entry the
    saddle pattern (`band_slot`) can make nonzero, into `schedule`; and the positions of L's
    and U's entries into ``factors`` (pointers and rows).  False if the schedule's capacity
    is too small (it is then not held, and ``factors`` must be compressed again).

    An entry that is not in the pattern nor filled by an update from one is an exact zero
    that `banded_lu` skips, and an entry of the pattern that is zero at the pose updates
    nothing (x − 0 · y = x): the scheduled factorization is `banded_lu`'s bit for bit, for
    the same pivots."""
    _, pointers, held, swaps, multipliers, updates, upper_positions, structure, _ = schedule
    factor_pointers, factor_rows, _ = factors
    pointers[_UPPER, 0] = -1
    n, rows_ = structure.shape
    kv = lower + upper
    for c in range(n):
        for r in range(rows_):
            structure[c, r] = False
    for s in range(band_slot.shape[1]):
        structure[band_slot[1, s], band_slot[0, s]] = True
    n_swaps = n_multipliers = n_updates = 0
    last = 0
    for j in range(n):
        held[j] = pivots[j]
        pointers[_SWAPS, j], pointers[_MULTIPLIERS, j], pointers[_UPDATES, j] = n_swaps, n_multipliers, n_updates
        below = min(lower, n - 1 - j)
        best = pivots[j] - j
        last = max(last, min(j + upper + best, n - 1))
        if best != 0:
            for c in range(j, last + 1):
                r = kv + j - c
                if structure[c, r + best] or structure[c, r]:
                    if n_swaps >= swaps.shape[1]:
                        return False
                    swaps[0, n_swaps], swaps[1, n_swaps] = r + best + c * rows_, r + c * rows_
                    n_swaps += 1
                    structure[c, r + best], structure[c, r] = structure[c, r], structure[c, r + best]
        factor_pointers[0, j] = n_multipliers
        first = n_multipliers
        for i in range(1, below + 1):
            if structure[j, kv + i]:
                if n_multipliers >= multipliers.size:
                    return False
                multipliers[n_multipliers] = kv + i + j * rows_
                factor_rows[0, n_multipliers] = j + i
                n_multipliers += 1
        for c in range(j + 1, last + 1):
            r = kv + j - c
            if structure[c, r]:
                for m in range(first, n_multipliers):
                    i = multipliers[m] - j * rows_ - kv
                    if n_updates >= updates.shape[1]:
                        return False
                    updates[0, n_updates] = r + i + c * rows_
                    updates[1, n_updates] = multipliers[m]
                    updates[2, n_updates] = r + c * rows_
                    n_updates += 1
                    structure[c, r + i] = True
    pointers[_SWAPS, n], pointers[_MULTIPLIERS, n], pointers[_UPDATES, n] = n_swaps, n_multipliers, n_updates
    factor_pointers[0, n] = n_multipliers
    n_upper = 0
    for j in range(n):
        pointers[_UPPER, j] = n_upper
        factor_pointers[1, j] = n_upper
        for r in range(max(0, kv - j), kv):
            if structure[j, r]:
                if n_upper >= upper_positions.size:
                    pointers[_UPPER, 0] = -1
                    return False
                upper_positions[n_upper] = r + j * rows_
                factor_rows[1, n_upper] = j - kv + r
                n_upper += 1
    pointers[_UPPER, n] = factor_pointers[1, n] = n_upper
    return True


@njit(**_JIT)
def refactor_band(lower, pivots, schedule, factors):
    """`banded_lu` on the band (refilled) with the pivots of the held `schedule`
    (`band_schedule`), and L's and U's values into ``factors``: 1, or 0 where partial
    pivoting would pick another row (the band is then partly factored: refill it), or −1
    where a pivot fails (singular, or not finite)."""
    flat, pointers, held, swaps, multipliers, updates, upper_positions, _, reciprocals = schedule
    values = factors[2]
    n = held.size
    rows_ = flat.size // n
    kv = rows_ - 1 - lower
    for j in range(n):
        below = min(lower, n - 1 - j)
        diagonal = kv + j * rows_
        best = 0
        largest = abs(flat[diagonal])
        for i in range(1, below + 1):
            magnitude = abs(flat[diagonal + i])
            if magnitude > largest:
                largest = magnitude
                best = i
        if not (largest > 0.0 and largest < math.inf):
            return -1
        if j + best != held[j]:
            return 0
        for s in range(pointers[_SWAPS, j], pointers[_SWAPS, j + 1]):
            a, b = swaps[0, s], swaps[1, s]
            flat[a], flat[b] = flat[b], flat[a]
        inverse = 1.0 / flat[diagonal]
        reciprocals[j] = inverse
        for m in range(pointers[_MULTIPLIERS, j], pointers[_MULTIPLIERS, j + 1]):
            flat[multipliers[m]] *= inverse
        for u in range(pointers[_UPDATES, j], pointers[_UPDATES, j + 1]):
            flat[updates[0, u]] -= flat[updates[1, u]] * flat[updates[2, u]]
    for j in range(n):
        pivots[j] = held[j]
    for m in range(pointers[_MULTIPLIERS, n]):
        values[0, m] = flat[multipliers[m]]
    for m in range(pointers[_UPPER, n]):
        values[1, m] = flat[upper_positions[m]]
    return 1


@njit(**_JIT)
def factor_band_held(values, band_slot, band, lower, upper, pivots, extent, factors, schedule):
    """`factor_band` on the held pivots of `schedule` where partial pivoting picks them
    again (`refactor_band`: only the operations on entries that can be nonzero), else
    `factor_band` afresh and a new schedule for its pivots; True unless a pivot fails.
    The factors are `factor_band`'s bit for bit (zeros aside: the schedule's lists keep
    entries that are zero at this pose)."""
    if schedule[1][_UPPER, 0] >= 0:
        _refill(values, band_slot, band)
        outcome = refactor_band(lower, pivots, schedule, factors)
        if outcome == 1:
            return True
        if outcome < 0:
            return False
    if not factor_band(values, band_slot, band, lower, upper, pivots, extent, factors):
        return False
    if schedule[5].shape[1] and band_schedule(band_slot, lower, upper, pivots, schedule, factors):
        refactor_values = factors[2]
        flat, pointers, _, _, multipliers, _, upper_positions, _, reciprocals = schedule
        n, kv = band.shape[1], lower + upper
        for m in range(pointers[_MULTIPLIERS, n]):
            refactor_values[0, m] = flat[multipliers[m]]
        for m in range(pointers[_UPPER, n]):
            refactor_values[1, m] = flat[upper_positions[m]]
        for j in range(n):
            reciprocals[j] = 1.0 / band[kv, j]
    elif schedule[5].shape[1]:  # the schedule did not fit: factor_band's factors again
        compress_factors(band, lower, upper, extent, factors)
    return True


@njit(**_JIT)
def _refill(values, band_slot, band):
    """The band zeroed and refilled from the CSR `values` (`factor_band`'s first half)."""
    for c in range(band.shape[1]):
        for r in range(band.shape[0]):
            band[r, c] = 0.0
    for s in range(band_slot.shape[1]):
        band[band_slot[0, s], band_slot[1, s]] += values[s]
