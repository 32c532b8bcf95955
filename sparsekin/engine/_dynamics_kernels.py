"""numba kernels of forward dynamics: mass blocks, load tangents, the derivative of Φqᵀλ.

The iteration matrix of an implicit step (`sparsekin.engine.saddle`) is

    S = [[a M + b C_t + c K_t, Φqᵀ], [Φq, 0]]

with ``M`` the mass matrix, ``C_t = ∂f/∂qd`` and ``K_t = ∂f/∂q`` the tangents of the
forces ``f(q, qd, qdd, λ, t) = M qdd + h − Q + Φqᵀ λ`` that the equations of motion set to
zero (h: the centripetal terms; Q: gravity and loads).  Every kernel here writes its part
of ``a M + b C_t + c K_t`` as *triplets*: for entry e, ``rows[e]``, ``cols[e]`` (a
coordinate index, ``3 · body + k``; the ground's, ``n .. n + 2``, are discarded by the
assembler; equations follow at ``n + 3``) and ``vals[e]``, from ``start`` on, and returns the next free position.  The
order of the entries depends only on the model, never on the values, so one run at the
drawing fixes the pattern (`sparsekin.engine.saddle.SaddlePattern`) and every later run
refills the same positions.

Symbols as in `sparsekin.engine._kernels` (``q``, ``qd``, ``qdd`` with the ground appended,
``turns`` the (cos, sin) of every angle, ``Omega`` the +90° turn).  For body b with its
centre of mass at ``A = R s`` from its frame origin, angular velocity ω and acceleration
α, the inertial force ``M qdd + h`` is

    f_x = m (x'' − α A_y − ω² A_x),  f_y = m (y'' + α A_x − ω² A_y),
    f_θ = m (A_x y'' − A_y x'') + (I + m |A|²) α,

so ``M = [[m, 0, −m A_y], [0, m, m A_x], [−m A_y, m A_x, I + m |A|²]]``, its derivative in
θ at fixed accelerations (``A' = Omega A``) is ``(m (ω² A_y − α A_x), −m (α A_y + ω² A_x),
−m A · r'')`` and in ω ``(−2 m ω A_x, −2 m ω A_y, 0)``.  Gravity's moment ``A × m g``
gives ``∂(−Q_θ)/∂θ = m A · g``; a force F at arm A the same with F.

A constraint row g (or an actuator's coordinate s) contributes ``w ∇²g`` (w = λ, or −F for
an actuator pushing along s): the Hessians of the primitives, derived in each kernel's
docstring and checked against differences in tests/test_dynamics_engine.py.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT
from ._kernels import _turned, fill_body_turns, point_separation, separation_rate


@njit(inline="always", **JIT)
def _put(rows, cols, vals, e, row, col, value):
    rows[e] = row
    cols[e] = col
    vals[e] = value


# ---------------------------------------------------------------------- masses, gravity
@njit(**JIT)
def fill_inertia_triplets(masses, gravity, qd, qdd, turns, a, b, c, rows, cols, vals, start):
    """Each body's 3×3 block of ``a M + b C + c K`` from its mass, inertia and gravity:
    9 entries per body, row-major, massless bodies included (zeros)."""
    e = start
    for body in range(masses.mass.size):
        x, y, angle = 3 * body, 3 * body + 1, 3 * body + 2
        mass, x_angle, y_angle, angle_x, angle_y, angle_angle = inertia_block(masses, gravity, qd, qdd, turns, a, b,
                                                                              c, body)  # fmt: skip
        _put(rows, cols, vals, e, x, x, mass)
        _put(rows, cols, vals, e + 1, x, y, 0.0)
        _put(rows, cols, vals, e + 2, x, angle, x_angle)
        _put(rows, cols, vals, e + 3, y, x, 0.0)
        _put(rows, cols, vals, e + 4, y, y, mass)
        _put(rows, cols, vals, e + 5, y, angle, y_angle)
        _put(rows, cols, vals, e + 6, angle, x, angle_x)
        _put(rows, cols, vals, e + 7, angle, y, angle_y)
        _put(rows, cols, vals, e + 8, angle, angle, angle_angle)
        e += 9
    return e


@njit(inline="always", **JIT)
def inertia_block(masses, gravity, qd, qdd, turns, a, b, c, body):
    """The six values of `body`'s 3×3 block of ``a M + b C + c K`` that are not fixed zeros:
    ``(a m, xθ, yθ, θx, θy, θθ)``, the block ``[[a m, 0, xθ], [0, a m, yθ], [θx, θy, θθ]]``."""
    m, inertia = masses.mass[body], masses.inertia[body]
    ax, ay = _turned(turns[body, 0], turns[body, 1], masses.com[body])
    omega, alpha = qd[3 * body + 2], qdd[3 * body + 2]
    xdd, ydd = qdd[3 * body], qdd[3 * body + 1]
    # column θ: stiffness (inertial at fixed accelerations, and gravity) and damping
    k_x = m * (omega * omega * ay - alpha * ax)
    k_y = -m * (alpha * ay + omega * omega * ax)
    k_t = -m * (ax * xdd + ay * ydd) + m * (ax * gravity[0] + ay * gravity[1])
    c_x, c_y = -2.0 * m * omega * ax, -2.0 * m * omega * ay
    return (a * m, -a * m * ay + b * c_x + c * k_x, a * m * ax + b * c_y + c * k_y, -a * m * ay, a * m * ax,
            a * (inertia + m * (ax * ax + ay * ay)) + c * k_t)  # fmt: skip


# ---------------------------------------------------------------------- loads
@njit(**JIT)
def fill_point_force_triplets(force, turns, law_values, c, rows, cols, vals, start):
    """A force F at arm A: ``Q_θ = A × F``, ``∂(−Q_θ)/∂θ = A · F``; one entry per force."""
    e = start
    for k in range(force.body.size):
        body = force.body[k]
        ax, ay = _turned(turns[body, 0], turns[body, 1], force.local[k])
        fx, fy = law_values[force.law[k]], law_values[force.law[k] + 1]
        _put(rows, cols, vals, e, 3 * body + 2, 3 * body + 2, c * (ax * fx + ay * fy))
        e += 1
    return e


@njit(inline="always", **JIT)
def _separation_gradient(aix, aiy, ajx, ajy, ex, ey, gradient):
    """∇L = Dᵀ e over (x_i, y_i, θ_i, x_j, y_j, θ_j), D = [−I, −Omega A, I, Omega B]."""
    gradient[0], gradient[1] = -ex, -ey
    gradient[2] = ex * aiy - ey * aix
    gradient[3], gradient[4] = ex, ey
    gradient[5] = -ex * ajy + ey * ajx


@njit(inline="always", **JIT)
def _separation_jacobian(aix, aiy, ajx, ajy, d):
    """D = ∂d/∂(x_i, y_i, θ_i, x_j, y_j, θ_j), 2×6."""
    d[0, 0], d[1, 0] = -1.0, 0.0
    d[0, 1], d[1, 1] = 0.0, -1.0
    d[0, 2], d[1, 2] = aiy, -aix
    d[0, 3], d[1, 3] = 1.0, 0.0
    d[0, 4], d[1, 4] = 0.0, 1.0
    d[0, 5], d[1, 5] = -ajy, ajx


@njit(inline="always", **JIT)
def _distance_hessian(aix, aiy, ajx, ajy, ex, ey, length, d, hessian):
    """∇²L = Dᵀ (I − e eᵀ) D / L, plus e · ∂²d on θ_iθ_i (e · A) and θ_jθ_j (−e · B)."""
    _separation_jacobian(aix, aiy, ajx, ajy, d)
    for u in range(6):
        pu = d[0, u] - ex * (ex * d[0, u] + ey * d[1, u])  # (P D)[:, u]
        qu = d[1, u] - ey * (ex * d[0, u] + ey * d[1, u])
        for v in range(6):
            hessian[u, v] = (pu * d[0, v] + qu * d[1, v]) / length
    hessian[2, 2] += ex * aix + ey * aiy
    hessian[5, 5] -= ex * ajx + ey * ajy


@njit(inline="always", **JIT)
def _put_pair_block(body_i, body_j, block, rows, cols, vals, start):
    """A 6×6 block over the coordinates of bodies i and j, row-major: 36 entries."""
    e = start
    for u in range(6):
        row = 3 * (body_i if u < 3 else body_j) + u % 3
        for v in range(6):
            _put(rows, cols, vals, e, row, 3 * (body_i if v < 3 else body_j) + v % 3, block[u, v])
            e += 1
    return e


@njit(**JIT)
def fill_spring_triplets(spring, q, qd, turns, b, c, gradient, rate_gradient, d, hessian, block, rows, cols, vals,
                         start):  # fmt: skip
    """Spring-dampers, 36 entries each.  ``f = −Q = T ∇L`` with ``T = k (L − L0) + c_d L'``,
    ``L' = e · d'``, so ``C = c_d ∇L ∇Lᵀ`` and ``K = ∇L (k ∇L + c_d ∇L')ᵀ + T ∇²L``, where
    ``∇L' = Dᵀ (I − e eᵀ) d' / L`` plus ``ω_i e · A`` on θ_i and ``−ω_j e · B`` on θ_j
    (``∂d'/∂θ_i = A ω_i``, ``∂d'/∂θ_j = −B ω_j``).  `gradient`, `rate_gradient` (6,), `d`
    (2, 6), `hessian`, `block` (6, 6): scratch."""
    e = start
    for k in range(spring.body_i.size):
        i, j = spring.body_i[k], spring.body_j[k]
        aix, aiy, ajx, ajy, dx, dy, length = point_separation(q, turns, i, j, spring.local_i[k], spring.local_j[k])
        ex, ey = dx / length, dy / length
        vx, vy = separation_rate(qd, i, j, aix, aiy, ajx, ajy)
        along = ex * vx + ey * vy
        stiffness, damping = spring.stiffness[k], spring.damping[k]
        tension = stiffness * (length - spring.free_length[k]) + damping * along
        _separation_gradient(aix, aiy, ajx, ajy, ex, ey, gradient)
        _distance_hessian(aix, aiy, ajx, ajy, ex, ey, length, d, hessian)
        px, py = (vx - ex * along) / length, (vy - ey * along) / length  # (I − e eᵀ) d' / L
        for v in range(6):
            rate_gradient[v] = d[0, v] * px + d[1, v] * py
        rate_gradient[2] += qd[3 * i + 2] * (ex * aix + ey * aiy)
        rate_gradient[5] -= qd[3 * j + 2] * (ex * ajx + ey * ajy)
        for u in range(6):
            for v in range(6):
                block[u, v] = (b * damping * gradient[u] * gradient[v]
                               + c * (gradient[u] * (stiffness * gradient[v] + damping * rate_gradient[v])
                                      + tension * hessian[u, v]))  # fmt: skip
        e = _put_pair_block(i, j, block, rows, cols, vals, e)
    return e


@njit(**JIT)
def fill_torsion_triplets(torsion, b, c, rows, cols, vals, start):
    """Rotational spring-dampers: ``f_θi = −f_θj = k (θ_i − θ_j − θ0) + c_d (ω_i − ω_j)``,
    4 entries each (θ_iθ_i, θ_iθ_j, θ_jθ_i, θ_jθ_j)."""
    e = start
    for k in range(torsion.body_i.size):
        i, j = 3 * torsion.body_i[k] + 2, 3 * torsion.body_j[k] + 2
        value = b * torsion.damping[k] + c * torsion.stiffness[k]
        _put(rows, cols, vals, e, i, i, value)
        _put(rows, cols, vals, e + 1, i, j, -value)
        _put(rows, cols, vals, e + 2, j, i, -value)
        _put(rows, cols, vals, e + 3, j, j, value)
        e += 4
    return e


# ---------------------------------------------------------------------- Σ w ∇²g per primitive
@njit(**JIT)
def fill_coincidence_hessian(coincidence, turns, weights, c, rows, cols, vals, start):
    """``g = r_i + A − r_j − B`` (rows x, y): ``∂²g_x/∂θ_i² = −A_x``, ``∂²g_y/∂θ_i² = −A_y``,
    ``+B`` on θ_j; 2 entries each (θ_iθ_i, θ_jθ_j)."""
    e = start
    for k in range(coincidence.row.size):
        bi, bj, r = coincidence.body_i[k], coincidence.body_j[k], coincidence.row[k]
        ax, ay = _turned(turns[bi, 0], turns[bi, 1], coincidence.local_i[k])
        bx, by = _turned(turns[bj, 0], turns[bj, 1], coincidence.local_j[k])
        wx, wy = weights[r], weights[r + 1]
        _put(rows, cols, vals, e, 3 * bi + 2, 3 * bi + 2, -c * (wx * ax + wy * ay))
        _put(rows, cols, vals, e + 1, 3 * bj + 2, 3 * bj + 2, c * (wx * bx + wy * by))
        e += 2
    return e


@njit(**JIT)
def fill_projection_hessian(projection, q, turns, weights, c, rows, cols, vals, start):
    """``g = n · (r_j + B − r_i) − u · s_i + rolling (θ_j − θ_i)``, n = R_i u: with
    ``E = r_j + B − r_i``, ``∂g/∂θ_i = (Omega n) · E``, so ``∂²g/∂θ_i² = −n · E``,
    ``∂²g/∂θ_i∂r_i = −Omega n``, ``∂²g/∂θ_i∂r_j = Omega n``, ``∂²g/∂θ_i∂θ_j = n · B``,
    ``∂²g/∂θ_j² = −n · B``; 12 entries each (both triangles)."""
    e = start
    for k in range(projection.row.size):
        bi, bj = projection.body_i[k], projection.body_j[k]
        i, j = 3 * bi, 3 * bj
        w = c * weights[projection.row[k]]
        nx, ny = _turned(turns[bi, 0], turns[bi, 1], projection.direction[k])
        bx, by = _turned(turns[bj, 0], turns[bj, 1], projection.local_j[k])
        big_ex = q[j] + bx - q[i]
        big_ey = q[j + 1] + by - q[i + 1]
        nb = nx * bx + ny * by
        ti, tj = i + 2, j + 2
        _put(rows, cols, vals, e, ti, ti, -w * (nx * big_ex + ny * big_ey))
        _put(rows, cols, vals, e + 1, ti, i, w * ny)  # −(Omega n)_x
        _put(rows, cols, vals, e + 2, i, ti, w * ny)
        _put(rows, cols, vals, e + 3, ti, i + 1, -w * nx)  # −(Omega n)_y
        _put(rows, cols, vals, e + 4, i + 1, ti, -w * nx)
        _put(rows, cols, vals, e + 5, ti, j, -w * ny)
        _put(rows, cols, vals, e + 6, j, ti, -w * ny)
        _put(rows, cols, vals, e + 7, ti, j + 1, w * nx)
        _put(rows, cols, vals, e + 8, j + 1, ti, w * nx)
        _put(rows, cols, vals, e + 9, ti, tj, w * nb)
        _put(rows, cols, vals, e + 10, tj, ti, w * nb)
        _put(rows, cols, vals, e + 11, tj, tj, -w * nb)
        e += 12
    return e


@njit(**JIT)
def fill_distance_hessian(distance, q, turns, weights, c, d, hessian, rows, cols, vals, start):
    """``g = |d|``: ``∇²g`` of `_distance_hessian`, 36 entries each."""
    e = start
    for k in range(distance.row.size):
        bi, bj = distance.body_i[k], distance.body_j[k]
        aix, aiy, ajx, ajy, dx, dy, length = point_separation(q, turns, bi, bj, distance.local_i[k],
                                                              distance.local_j[k])  # fmt: skip
        _distance_hessian(aix, aiy, ajx, ajy, dx / length, dy / length, length, d, hessian)
        w = c * weights[distance.row[k]]
        for u in range(6):
            for v in range(6):
                hessian[u, v] *= w
        e = _put_pair_block(bi, bj, hessian, rows, cols, vals, e)
    return e


@njit(**JIT)
def fill_primitive_hessians(primitives, q, turns, weights, c, d, hessian, rows, cols, vals, start):
    """``c Σ_r weights[r] ∇²g_r`` over every primitive (combinations are linear: nothing)."""
    e = fill_coincidence_hessian(primitives.coincidence, turns, weights, c, rows, cols, vals, start)
    e = fill_projection_hessian(primitives.projection, q, turns, weights, c, rows, cols, vals, e)
    return fill_distance_hessian(primitives.distance, q, turns, weights, c, d, hessian, rows, cols, vals, e)


@njit(**JIT)
def hessian_entries(primitives):
    """How many triplets `fill_primitive_hessians` writes."""
    return 2 * primitives.coincidence.row.size + 12 * primitives.projection.row.size + 36 * primitives.distance.row.size


# ---------------------------------------------------------------------- assembly and forces
#: Rows of the saddle pattern with more entries than this are sorted by `np.argsort`
#: (a hub's coordinate, coupled to many equations), shorter ones by insertion.
INSERTION_SORT_MAX = 32


@njit(**JIT)
def _saddle_row(index, n):
    """Triplet index → row of S: coordinates as they are, the ground's (n .. n + 2) and
    left-out equations (negative) −1, kept equations shifted by the ground's three."""
    if index < n:
        return index
    if index < n + 3:
        return -1
    return index - 3


@njit(**JIT)
def saddle_pattern(rows, cols, n, indptr, slots):
    """The CSR pattern of the saddle matrix from the triplets' indices, in linear time.

    Triplet e goes to row ``_saddle_row(rows[e])``, column ``_saddle_row(cols[e])``; fills
    `indptr` (size + 1) and `slots` (each triplet's position in the CSR values; ``nnz``,
    the discard slot, for the ground's and left-out equations' triplets) and returns the
    column indices, sorted and unique within rows.  A counting sort by row, each row's
    entries sorted by column, duplicates merged: a few arrays of the triplets' size
    (np.unique on 64-bit keys took several times that).
    """
    size = indptr.size - 1
    start = np.zeros(size + 1, dtype=np.int64)
    for e in range(rows.size):
        r, c = _saddle_row(rows[e], n), _saddle_row(cols[e], n)
        if r >= 0 and c >= 0:
            start[r + 1] += 1
    for r in range(size):
        start[r + 1] += start[r]
    columns = np.empty(start[size], dtype=np.int64)
    entries = np.empty(start[size], dtype=np.int64)
    fill = start[:size].copy()
    for e in range(rows.size):
        r, c = _saddle_row(rows[e], n), _saddle_row(cols[e], n)
        if r >= 0 and c >= 0:
            columns[fill[r]] = c
            entries[fill[r]] = e
            fill[r] += 1
        else:
            slots[e] = -1
    nnz = 0
    for r in range(size):
        first, end = start[r], start[r + 1]
        if end - first > INSERTION_SORT_MAX:
            order = np.argsort(columns[first:end], kind="mergesort")
            columns[first:end] = columns[first:end][order]
            entries[first:end] = entries[first:end][order]
        else:
            for position in range(first + 1, end):
                column, moved = columns[position], entries[position]
                before = position - 1
                while before >= first and columns[before] > column:
                    columns[before + 1], entries[before + 1] = columns[before], entries[before]
                    before -= 1
                columns[before + 1], entries[before + 1] = column, moved
        indptr[r] = nnz
        for position in range(first, end):
            if position == first or columns[position] != columns[position - 1]:
                columns[nnz] = columns[position]  # nnz <= position: compaction in place
                nnz += 1
            slots[entries[position]] = nnz - 1
    indptr[size] = nnz
    for e in range(rows.size):
        if slots[e] < 0:
            slots[e] = nnz
    return columns[:nnz].copy()


@njit(**JIT)
def load_motion(coordinates, velocities, accelerations, q, qd, qdd, filled, filled_turns, turns):
    """``q, qd, qdd = coordinates, velocities, accelerations`` (the ground's last three
    entries left as they are) and ``turns`` the cos and sin of q's angles: copied from
    `filled_turns` when `filled` (the constraints' last coordinates) is q, else computed."""
    if load_shared(coordinates, velocities, accelerations, q, qd, qdd, filled, filled_turns, turns):
        for k in range(coordinates.size):
            q[k] = coordinates[k]
        for b in range(turns.shape[0]):
            turns[b, 0] = filled_turns[b, 0]
            turns[b, 1] = filled_turns[b, 1]


@njit(**JIT)
def load_shared(coordinates, velocities, accelerations, q, qd, qdd, filled, filled_turns, turns, copy_rates=True):
    """`load_motion`, but where `filled` is q already (the constraints' last fill was at these
    coordinates) neither q nor the turns are copied: returns True, and the caller reads
    `filled` and `filled_turns` (equal, entry for entry, to what `load_motion` would copy).
    Without `copy_rates`, qd and qdd are left as they are (a caller that reads the
    velocities and accelerations themselves)."""
    differ = False  # (no early exit: a test per entry that does not wait on the one before, 0.6x the time)
    for k in range(coordinates.size):
        if copy_rates:
            qd[k] = velocities[k]
            qdd[k] = accelerations[k]
        differ |= filled[k] != coordinates[k]
    for k in range(coordinates.size, q.size):
        differ |= filled[k] != q[k]
    if differ:
        for k in range(coordinates.size):
            q[k] = coordinates[k]
        fill_body_turns(q, turns)
    return not differ


@njit(**JIT)
def scatter_add(vals, slots, data):
    """``data[:] = 0``, then ``data[slots[e]] += vals[e]``; the last entry of `data` is the
    discard slot."""
    for k in range(data.size):
        data[k] = 0.0
    for e in range(vals.size):
        data[slots[e]] += vals[e]


@njit(**JIT)
def scatter_saddle(vals, jacobian, diagonal, block_slots, jacobian_slots, diagonal_slots, data):
    """``data[:] = 0``, then the coordinate block's triplets `vals` at `block_slots`, each
    Jacobian value at its two slots (Φq, Φqᵀ: ``jacobian_slots[2 s]``, ``[2 s + 1]``) and
    `diagonal` at `diagonal_slots`: `scatter_add` of every triplet of S in the same order,
    without Φq's triplets.  The last entry of `data` is the discard slot."""
    for k in range(data.size):
        data[k] = 0.0
    for e in range(vals.size):
        data[block_slots[e]] += vals[e]
    for s in range(jacobian.size):
        data[jacobian_slots[2 * s]] += jacobian[s]
        data[jacobian_slots[2 * s + 1]] += jacobian[s]
    for k in range(diagonal_slots.size):
        data[diagonal_slots[k]] += diagonal


@njit(**JIT)
def scatter_saddle_derived(vals, jacobian, diagonal, block_slots, transposed_slots, jacobian_rows, data):
    """`scatter_saddle` where Φq's slots and the diagonal's are not held but derived
    (`derived_multiplier_slots`: a kept equation's row of S is its Jacobian row, columns in
    order, then its diagonal): the same additions in the same order.  `jacobian_rows` is
    ``(indptr, indices, kept_row, n, saddle_indptr)``; the last entry of `data` is the
    discard slot."""
    indptr, indices, kept_row, n, saddle_indptr = jacobian_rows
    discard = data.size - 1
    for k in range(data.size):
        data[k] = 0.0
    for e in range(vals.size):
        data[block_slots[e]] += vals[e]
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        first = saddle_indptr[n + kept] - indptr[r] if kept >= 0 else 0
        for s in range(indptr[r], indptr[r + 1]):
            lower = first + s if kept >= 0 and indices[s] < n else discard
            data[lower] += jacobian[s]
            data[transposed_slots[s]] += jacobian[s]
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        if kept >= 0:
            data[saddle_indptr[n + kept + 1] - 1] += diagonal


@njit(**JIT)
def derived_multiplier_slots(jacobian_rows, discard, lower, diagonal):
    """The slots `scatter_saddle_derived` derives: Φq's (`lower`, one per Jacobian entry)
    and the diagonal's (`diagonal`, one per kept equation), to check them against the
    pattern's."""
    indptr, indices, kept_row, n, saddle_indptr = jacobian_rows
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        first = saddle_indptr[n + kept] - indptr[r] if kept >= 0 else 0
        for s in range(indptr[r], indptr[r + 1]):
            lower[s] = first + s if kept >= 0 and indices[s] < n else discard
        if kept >= 0:
            diagonal[kept] = saddle_indptr[n + kept + 1] - 1


@njit(**JIT)
def add_transposed_product(indptr, indices, values, weights, out):
    """``out += Jᵀ weights`` for a CSR J: the generalized force of row weights (actuators:
    ``F ∇s``; constraints: ``Φqᵀ λ``)."""
    for r in range(indptr.size - 1):
        w = weights[r]
        if w != 0.0:
            for s in range(indptr[r], indptr[r + 1]):
                out[indices[s]] += values[s] * w


@njit(**JIT)
def fill_row_products(indptr, indices, values, x, out):
    """``out = J x`` for a CSR J."""
    for r in range(indptr.size - 1):
        total = 0.0
        for s in range(indptr[r], indptr[r + 1]):
            total += values[s] * x[indices[s]]
        out[r] = total


@njit(**JIT)
def drift_left_norm(indptr, indices, values, kept_row, x, drift, weights):
    """The weighted norm (`weighted_norm`) of ``drift − J x`` on the kept rows of a CSR J
    (``kept_row[r]``: the row's index among them in `drift`, −1 if left out; `weights` of
    every row), in one pass without storing it: the drift a projection's change leaves."""
    norm, probe = 0.0, 0.0
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        if kept < 0:
            continue
        total = 0.0
        for s in range(indptr[r], indptr[r + 1]):
            total += values[s] * x[indices[s]]
        left = abs(drift[kept] - total) * weights[r]
        probe += 0.0 * left
        norm = max(norm, left)
    return norm if probe == 0.0 else math.nan


@njit(**JIT)
def drift_left_norms(indptr, indices, values, kept_row, first, first_drift, second, second_drift, weights, third,
                     third_drift, with_third):  # fmt: skip
    """`drift_left_norm` of ``(first, first_drift)``, of ``(second, second_drift)`` and, when
    `with_third`, of ``(third, third_drift)`` (else 0 in its place) in one pass over J, each
    bit for bit its own call: the two projections' tests after a paired solve, and the
    velocities' drift ‖Φq q̇ − (−Φt)‖ a sample publishes (`sparsekin.solve.projections`)."""
    norm0, norm1, norm2, probe0, probe1, probe2 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        if kept < 0:
            continue
        total0, total1, total2 = 0.0, 0.0, 0.0
        if with_third:
            for s in range(indptr[r], indptr[r + 1]):
                value, column = values[s], indices[s]
                total0 += value * first[column]
                total1 += value * second[column]
                total2 += value * third[column]
            left2 = abs(third_drift[kept] - total2) * weights[r]
            probe2 += 0.0 * left2
            norm2 = max(norm2, left2)
        else:
            for s in range(indptr[r], indptr[r + 1]):
                value, column = values[s], indices[s]
                total0 += value * first[column]
                total1 += value * second[column]
        left0 = abs(first_drift[kept] - total0) * weights[r]
        left1 = abs(second_drift[kept] - total1) * weights[r]
        probe0 += 0.0 * left0
        probe1 += 0.0 * left1
        norm0 = max(norm0, left0)
        norm1 = max(norm1, left1)
    return (norm0 if probe0 == 0.0 else math.nan, norm1 if probe1 == 0.0 else math.nan,
            norm2 if probe2 == 0.0 else math.nan)  # fmt: skip


@njit(**JIT)
def fill_drift_pair(indptr, indices, values, first, first_target, first_out, second, second_target, second_out,
                    second_product):  # fmt: skip
    """``first_out = J first − first_target`` and ``second_out = J second − second_target``
    for a CSR J in one pass, each bit for bit `fill_row_products` and the subtraction; and
    ``second_product = J second`` (the projections' targets: Φq q̇ + Φt and Φq q̈ − γ, and Φq q̈
    for a later γ)."""
    for r in range(indptr.size - 1):
        total0, total1 = 0.0, 0.0
        for s in range(indptr[r], indptr[r + 1]):
            value, column = values[s], indices[s]
            total0 += value * first[column]
            total1 += value * second[column]
        first_out[r] = total0 - first_target[r]
        second_out[r] = total1 - second_target[r]
        second_product[r] = total1


@njit(**JIT)
def fill_multiplier_triplets(indptr, indices, values, kept_row, first, rows, cols, vals, start):
    """Φq and Φqᵀ of the kept rows (``kept_row[r]``: the row's index among them, −1 if
    left out) at rows/columns ``first + kept_row[r]``; 2 entries per Jacobian entry."""
    e = start
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        for s in range(indptr[r], indptr[r + 1]):
            row = first + kept if kept >= 0 else -1
            _put(rows, cols, vals, e, row, indices[s], values[s])
            _put(rows, cols, vals, e + 1, indices[s], row, values[s])
            e += 2
    return e


@njit(**JIT)
def saddle_product(rows, cols, vals, count, n, indptr, indices, values, kept_row, x, out):
    """``out = S x`` for the saddle matrix of the first `count` triplets (coordinate block;
    the ground's entries, from `n` on, left out) and the CSR Jacobian (`indptr`, `indices`,
    `values`; row r at ``n + kept_row[r]``, left out if −1), without assembling S."""
    for k in range(out.size):
        out[k] = 0.0
    for e in range(count):
        row, col = rows[e], cols[e]
        if row < n and col < n:
            out[row] += vals[e] * x[col]
    for r in range(indptr.size - 1):
        kept = kept_row[r]
        if kept < 0:
            continue
        weight, total = x[n + kept], 0.0
        for s in range(indptr[r], indptr[r + 1]):
            out[indices[s]] += values[s] * weight
            total += values[s] * x[indices[s]]
        out[n + kept] = total


@njit(**JIT)
def fill_diagonal_triplets(first, count, value, rows, cols, vals, start):
    """``value`` on the diagonal of rows ``first .. first + count − 1``."""
    for k in range(count):
        _put(rows, cols, vals, start + k, first + k, first + k, value)
    return start + count


# ---------------------------------------------------------------------- generalized-α's vector updates
# (sparsekin.solve.dynamics: the same expressions, in the same order, as NumPy's, fused)
@njit(**JIT)
def predict(coordinates, velocities, accelerations, pseudo, alpha_m, alpha_f, gamma, beta, h, q, v, a, start,
            previous, ratio):  # fmt: skip
    """The predictor of a step of size h: ``a`` = Newton's last accelerations `start`
    (before their projection), extrapolated ``start + ratio (start − previous)``
    (`previous` those of the step before, `ratio` this step's size over that one's) unless
    `ratio` is 0, ã from them and the last (projected) `accelerations`, and q, v by the
    generalized-α formulas."""
    hh = h * h
    for k in range(q.size):
        a[k] = start[k] + ratio * (start[k] - previous[k]) if ratio != 0.0 else start[k]
        predicted = ((1.0 - alpha_f) * a[k] + alpha_f * accelerations[k] - alpha_m * pseudo[k]) / (1.0 - alpha_m)
        q[k] = coordinates[k] + h * velocities[k] + hh * ((0.5 - beta) * pseudo[k] + beta * predicted)
        v[k] = velocities[k] + h * ((1.0 - gamma) * pseudo[k] + gamma * predicted)


@njit(**JIT)
def newton_rhs(force, scale, residual, kept_rows, all_kept, rhs):
    """``rhs = [scale · force; −Φ of the kept rows]``; whether every entry of `force` is finite."""
    n = force.size
    probe = 0.0
    for k in range(n):
        rhs[k] = force[k] * scale
        probe += 0.0 * force[k]
    for k in range(rhs.size - n):
        rhs[n + k] = -residual[k if all_kept else kept_rows[k]]
    return probe == 0.0


@njit(**JIT)
def fill_rounding_probe(row_weights, rounding, n, out):
    """A residual of the constraints' rounding for Newton's matrix (`rounding_response`):
    zero forces, and on kept row k ``± rounding / row_weights[k]`` (`rounding`, relative to
    the coordinates' weighted size, in the row's own unit), the signs from a fixed hash of k
    (no pattern a chain's modes could be orthogonal to; the same on every path and run)."""
    for c in range(n):
        out[c] = 0.0
    for k in range(row_weights.size):
        sign = 1.0 if ((k * 2654435761) >> 16) & 1 else -1.0
        out[n + k] = sign * rounding / row_weights[k]


@njit(inline="always", **JIT)
def _updated(delta, gamma_prime, beta_prime, weights, q, v, a, k):
    """Entry k of `newton_update`: ``(|δq| w, |q| w)`` after the update."""
    d = delta[k]
    q[k] += d
    v[k] += gamma_prime * d
    a[k] += beta_prime * d
    return abs(d) * weights[k], abs(q[k]) * weights[k]


@njit(**JIT)
def newton_update(delta, gamma_prime, beta_prime, kept_rows, all_kept, weights, q, v, a, multipliers):
    """``q += δq``, ``v += γ′ δq``, ``a += β′ δq``, ``λ_kept += β′ δλ``; returns the weighted
    norms (`weighted_norm`) of δq and of the new q, in the same pass.  Four lanes of running
    maxima and finiteness probes, as `weighted_norm` (a maximum and a sum of zeros do not
    depend on the order: the same results without a serial chain through every entry)."""
    n = q.size
    c0 = c1 = c2 = c3 = s0 = s1 = s2 = s3 = 0.0
    p0 = p1 = p2 = p3 = 0.0
    end = n - n % 4
    for k in range(0, end, 4):
        d0, q0 = _updated(delta, gamma_prime, beta_prime, weights, q, v, a, k)
        d1, q1 = _updated(delta, gamma_prime, beta_prime, weights, q, v, a, k + 1)
        d2, q2 = _updated(delta, gamma_prime, beta_prime, weights, q, v, a, k + 2)
        d3, q3 = _updated(delta, gamma_prime, beta_prime, weights, q, v, a, k + 3)
        p0 += 0.0 * d0 + 0.0 * q0
        p1 += 0.0 * d1 + 0.0 * q1
        p2 += 0.0 * d2 + 0.0 * q2
        p3 += 0.0 * d3 + 0.0 * q3
        c0, c1, c2, c3 = max(c0, d0), max(c1, d1), max(c2, d2), max(c3, d3)
        s0, s1, s2, s3 = max(s0, q0), max(s1, q1), max(s2, q2), max(s3, q3)
    for k in range(end, n):
        d0, q0 = _updated(delta, gamma_prime, beta_prime, weights, q, v, a, k)
        p0 += 0.0 * d0 + 0.0 * q0
        c0, s0 = max(c0, d0), max(s0, q0)
    for k in range(delta.size - n):
        row = k if all_kept else kept_rows[k]
        multipliers[row] += beta_prime * delta[n + k]
    if p0 + p1 + p2 + p3 != 0.0:
        return math.nan, math.nan
    return max(max(c0, c1), max(c2, c3)), max(max(s0, s1), max(s2, s3))


@njit(**JIT)
def pseudo_accelerations(q, coordinates, velocities, pseudo, h, beta, out):
    """ã of the step that ends at q: ``(q − q_n − h v_n − h² (½ − β) ã_n) / (h² β)``."""
    hh = h * h
    lead = hh * (0.5 - beta)
    scale = hh * beta
    for k in range(q.size):
        out[k] = (q[k] - coordinates[k] - h * velocities[k] - lead * pseudo[k]) / scale


@njit(**JIT)
def kinetic_potential_elastic(masses, gravity, spring, torsion, q, qd, turns):
    """Kinetic energy ½ qdᵀ M qd, gravitational potential −Σ m g · r_com, and the elastic
    energy of springs ½ k (L − L0)² and rotational springs ½ k (Δθ − θ0)², J."""
    kinetic, potential, elastic = 0.0, 0.0, 0.0
    gx, gy = gravity[0], gravity[1]
    for body in range(masses.mass.size):
        m = masses.mass[body]
        ax, ay = _turned(turns[body, 0], turns[body, 1], masses.com[body])
        omega = qd[3 * body + 2]
        vx, vy = qd[3 * body] - omega * ay, qd[3 * body + 1] + omega * ax
        kinetic += 0.5 * (m * (vx * vx + vy * vy) + masses.inertia[body] * omega * omega)
        potential -= m * (gx * (q[3 * body] + ax) + gy * (q[3 * body + 1] + ay))
    for k in range(spring.body_i.size):
        length = point_separation(q, turns, spring.body_i[k], spring.body_j[k], spring.local_i[k], spring.local_j[k])[6]
        elastic += 0.5 * spring.stiffness[k] * (length - spring.free_length[k]) ** 2
    for k in range(torsion.body_i.size):
        turn = q[3 * torsion.body_i[k] + 2] - q[3 * torsion.body_j[k] + 2] - torsion.free_angle[k]
        elastic += 0.5 * torsion.stiffness[k] * turn * turn
    return kinetic, potential, elastic


@njit(**JIT)
def damping_power(spring, torsion, qd, q, turns):
    """Power dissipated by the dampers, c L'² and c (Δω)², W."""
    power = 0.0
    for k in range(spring.body_i.size):
        i, j = spring.body_i[k], spring.body_j[k]
        aix, aiy, ajx, ajy, dx, dy, length = point_separation(q, turns, i, j, spring.local_i[k], spring.local_j[k])
        vx, vy = separation_rate(qd, i, j, aix, aiy, ajx, ajy)
        along = (dx * vx + dy * vy) / length
        power += spring.damping[k] * along * along
    for k in range(torsion.body_i.size):
        rate = qd[3 * torsion.body_i[k] + 2] - qd[3 * torsion.body_j[k] + 2]
        power += torsion.damping[k] * rate * rate
    return power


@njit(**JIT)
def applied_power(loads, qd, turns, law_values):
    """Power of the point forces and torques (not springs: their energy is elastic), W."""
    power = 0.0
    force = loads.force
    for k in range(force.body.size):
        body = force.body[k]
        ax, ay = _turned(turns[body, 0], turns[body, 1], force.local[k])
        omega = qd[3 * body + 2]
        vx, vy = qd[3 * body] - omega * ay, qd[3 * body + 1] + omega * ax
        power += law_values[force.law[k]] * vx + law_values[force.law[k] + 1] * vy
    torque = loads.torque
    for k in range(torque.body.size):
        power += law_values[torque.law[k]] * qd[3 * torque.body[k] + 2]
    return power


@njit(**JIT)
def weighted_norm(values, weights):
    """max |values| · weights, NaN if not finite.  Four independent running maxima and
    finiteness probes (``0 · v`` is 0 unless v is inf or NaN): no test and no serial
    dependence per entry, 1.7× faster on long vectors (the large path takes ~25 a step)."""
    n0 = n1 = n2 = n3 = 0.0
    p0 = p1 = p2 = p3 = 0.0
    size = values.size
    end = size - size % 4
    for k in range(0, end, 4):
        v0 = abs(values[k]) * weights[k]
        v1 = abs(values[k + 1]) * weights[k + 1]
        v2 = abs(values[k + 2]) * weights[k + 2]
        v3 = abs(values[k + 3]) * weights[k + 3]
        p0 += 0.0 * v0
        p1 += 0.0 * v1
        p2 += 0.0 * v2
        p3 += 0.0 * v3
        n0 = max(n0, v0)
        n1 = max(n1, v1)
        n2 = max(n2, v2)
        n3 = max(n3, v3)
    for k in range(end, size):
        v0 = abs(values[k]) * weights[k]
        p0 += 0.0 * v0
        n0 = max(n0, v0)
    norm = max(max(n0, n1), max(n2, n3))
    return norm if p0 + p1 + p2 + p3 == 0.0 else math.nan
