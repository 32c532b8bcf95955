"""numba kernels of the large path's constraint projections (`sparsekin.solve.projections`):
the passes of their iterative refinement fused, each the same operations in the same order
on every entry as the NumPy expressions and kernels they replace (bit for bit).

* `fill_inertia_values` and `saddle_residuals` — the refinement's residuals ``[0; drift]
  − S x`` of one or two columns in one pass over S, each body's inertia block held as its
  six values (not nine triplets of 16 bytes each);
* `move_acceleration_drift` — the acceleration drift Φq q̈ − γ at moved velocities from γ
  and the kept Φq q̈, and how far it moved, in one pass;
* `add_increments` — after a solve, each column's solution moved by its increment, the
  increments' sizes and the velocities moved, in one call (five NumPy and kernel calls).

Symbols as in `sparsekin.engine._dynamics_kernels`: S the saddle matrix [[A, Φqᵀ], [Φq, 0]],
its leading block A as the bodies' inertia blocks and triplets (``rows``, ``cols``,
``vals``; the ground's entries, from ``n`` on, left out), Φq as the CSR Jacobian
(``indptr``, ``indices``, ``values``) whose row r is S's row ``n + kept_row[r]`` (−1: left
out).
"""

from __future__ import annotations

import math

from numba import njit

from .._jit import JIT
from ._dynamics_kernels import inertia_block, weighted_norm


@njit(**JIT)
def fill_inertia_values(masses, gravity, qd, qdd, turns, a, b, c, inertia):
    """Each body's 3×3 block of ``a M + b C + c K`` as its six values that are not fixed zeros
    (`_dynamics_kernels.inertia_block`, as `_dynamics_kernels.fill_inertia_triplets` fills
    them); returns the triplets it stands for, 9 per body."""
    for body in range(masses.mass.size):
        values = inertia_block(masses, gravity, qd, qdd, turns, a, b, c, body)
        for k in range(6):
            inertia[body, k] = values[k]
    return 9 * masses.mass.size


@njit(inline="always", **JIT)
def _inertia_residuals(inertia, x, out, body):
    """``out = −B x`` on `body`'s rows for its inertia block B (`fill_inertia_values`), the
    subtractions of its nine triplets row after row (zeros included: bit for bit)."""
    i = 3 * body
    mass, x_angle, y_angle = inertia[body, 0], inertia[body, 1], inertia[body, 2]
    xx, xy, xt = x[i], x[i + 1], x[i + 2]
    out[i] = ((0.0 - mass * xx) - 0.0 * xy) - x_angle * xt
    out[i + 1] = ((0.0 - 0.0 * xx) - mass * xy) - y_angle * xt
    out[i + 2] = ((0.0 - inertia[body, 3] * xx) - inertia[body, 4] * xy) - inertia[body, 5] * xt


@njit(**JIT)
def saddle_residuals(inertia, rows, cols, vals, start, count, n, indptr, indices, values, kept_row, x0, drift0, out0,
                     x1, drift1, out1, both):  # fmt: skip
    """``out0 = [0; drift0] − S x0`` and, when `both`, ``out1 = [0; drift1] − S x1`` in one
    pass over S (`drift0`, `drift1` of the kept rows): the residuals of the two projections'
    iterative refinement.  S's leading block is the bodies' inertia blocks (`inertia`, of
    `fill_inertia_values`) and the triplets from `start` to `count` (`fill_block_compact`);
    the same subtractions in the same order as over the triplets of `fill_block_triplets`
    (bit for bit).  A run of triplets on one row is summed in registers and stored once: no
    wait on a store to load the next.  Each entry of `out0` and `out1` is written before it
    is read, not zeroed first: a body's rows from ``0 − B x`` (`_inertia_residuals`, both
    columns in one sweep), the coordinates without a block zeroed, each kept equation's row
    once, at its end (every entry from `n` on is one, `kept_row` numbering them): at 10^6
    bodies two passes of 2 × 48 MB fewer."""
    for k in range(3 * inertia.shape[0], n):  # (the coordinates without an inertia block; none on a chain)
        out0[k] = 0.0
        if both:
            out1[k] = 0.0
    for body in range(inertia.shape[0]):
        _inertia_residuals(inertia, x0, out0, body)
        if both:
            _inertia_residuals(inertia, x1, out1, body)
    current, total0, total1 = -1, 0.0, 0.0
    for e in range(start, count):
        row, col = rows[e], cols[e]
        if row < n and col < n:
            if row != current:
                if current >= 0:
                    out0[current] = total0
                    if both:
                        out1[current] = total1
                current, total0 = row, out0[row]
                total1 = out1[row] if both else 0.0
            total0 -= vals[e] * x0[col]
            if both:
                total1 -= vals[e] * x1[col]
    if current >= 0:
        out0[current] = total0
        if both:
            out1[current] = total1
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        if kept < 0:
            continue
        weight0, total0 = x0[n + kept], 0.0
        weight1, total1 = x1[n + kept] if both else 0.0, 0.0
        for s in range(indptr[r], indptr[r + 1]):
            value, c = values[s], indices[s]
            out0[c] -= value * weight0
            total0 += value * x0[c]
            if both:
                out1[c] -= value * weight1
                total1 += value * x1[c]
        out0[n + kept] = drift0[kept] - total0
        if both:
            out1[n + kept] = drift1[kept] - total1


@njit(**JIT)
def move_acceleration_drift(product, gamma, target_acceleration, out, weights, measure):
    """``gamma += target_acceleration`` (the acceleration right-hand side γ + the targets'
    second derivative) and ``out = product − gamma`` (the acceleration drift Φq q̈ − γ, from
    Φq q̈ = `product`), every equation; with `measure` returns the weighted norm of the move
    ``out_new − out_old`` (NaN if not finite), else 0."""
    norm, probe = 0.0, 0.0
    for r in range(out.size):
        rhs = gamma[r] + target_acceleration[r]
        gamma[r] = rhs
        drift = product[r] - rhs
        if measure:
            moved = abs(drift - out[r]) * weights[r]
            probe += 0.0 * moved
            norm = max(norm, moved)
        out[r] = drift
    return norm if probe == 0.0 else math.nan


@njit(**JIT)
def add_increments(solution0, increment0, first0, solution1, increment1, first1, both, weights, n, velocities, moves):
    """After a solve of the refinement's columns: ``solution0 += increment0`` (``0 + increment0``
    where `first0`, its first solve from zero), the weighted size of ``increment0[:n]``
    (`weighted_norm` with the coordinates' `weights`), the same for column 1 when `both`,
    and with `moves` (column 0 is the velocities') ``velocities -= increment0[:n]``: the
    NumPy expressions' numbers, one call.  Returns the two sizes (the second 0 unless `both`)."""
    _add_increment(solution0, increment0, first0)
    size0 = weighted_norm(increment0[:n], weights)
    size1 = 0.0
    if both:
        _add_increment(solution1, increment1, first1)
        size1 = weighted_norm(increment1[:n], weights)
    if moves:
        for k in range(n):
            velocities[k] -= increment0[k]
    return size0, size1


@njit(inline="always", **JIT)
def _add_increment(solution, increment, first):
    if first:
        for k in range(solution.size):
            solution[k] = 0.0 + increment[k]
    else:
        for k in range(solution.size):
            solution[k] += increment[k]
