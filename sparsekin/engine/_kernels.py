"""numba kernels: arrays in, preallocated arrays filled in place.

One pair of kernels per primitive equation of `sparsekin.model.primitives` (its residual and
Jacobian values; its gamma), and the wiring that calls them all on the same packed
`Primitives`: `residual_jacobian` and `acceleration_rhs` are inlined into the compiled
time loop (`sparsekin.solve._compiled`), and the assembler calls them from Python through
`fill_residual_jacobian` and `fill_gamma`; `fill_outputs`, which evaluates the elements'
own coordinates (the joint outputs) at every sample, runs the same primitive kernels
(`_fill_all`, `acceleration_rhs`) on the outputs' `Primitives`.

Symbols (for these kernels only):

* ``q``, ``qd`` — coordinates and velocities, ``(x, y, angle)`` per body, with the ground
  appended as a last body whose entries are zero (see `sparsekin.model.primitives`).
* ``residual`` — g(q) - target: the geometric part of each equation minus its target.
* ``jac_data`` — the values of the CSR Jacobian dg/dq, one slot past its end for the
  entries of the ground's columns, which are discarded.
* ``gamma`` — the acceleration right-hand side: -d²g/ds²(q + s·qd) at s = 0, so that
  ``jacobian @ qdd = gamma + (second time derivative of the targets)``.
* ``turns`` — ``(cos, sin)`` of every body's angle, shape (n_bodies + 1, 2), the ground
  last; `fill_body_turns` fills it once per configuration, so that each body's angle goes
  through cos and sin once, not once per equation it takes part in.
* ``R(angle)`` rotates a local vector into the global frame; ``Omega`` turns a vector by
  +90°, so that ``d/dangle R s = Omega R s``.  For a point of body i, ``a = R_i s_i`` and
  ``a' = Omega a w_i``, ``a'' = Omega a w_i' - a w_i²`` (w: the angular velocity).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT


@njit(inline="always", **JIT)
def _turned(cosine, sine, vector):
    """R(angle) @ vector for a local 2-vector, given cos and sin of the angle."""
    return cosine * vector[0] - sine * vector[1], sine * vector[0] + cosine * vector[1]


@njit(inline="always", **JIT)
def _two_sum(a, b):
    """``(s, e)`` with ``s = fl(a + b)`` and ``a + b = s + e`` exactly (Knuth's TwoSum)."""
    s = a + b
    b_part = s - a
    return s, (a - (s - b_part)) + (b - b_part)


@njit(inline="always", **JIT)
def _gap(position_i, arm_i, position_j, arm_j):
    """``position_i + arm_i - position_j - arm_j``, rounded once at the size of the result.

    A body far from the origin holds coordinates of, say, 5·10^4 m: summed left to right,
    the sum would round at their ulp (7e-12 m) however close the two points are, and that
    rounding, not a geometric error, is what Newton then corrects along a mechanism's
    nearly singular directions (a long chain at a flat crossing).  The two differences of
    like terms (two positions; a ground point and an arm) are formed with their exact
    errors, so only the final sum rounds: the result is exact to its own ulp whether the
    large terms are the positions (two bodies) or a position and a ground point.
    """
    position, position_error = _two_sum(position_i, -position_j)
    arm, arm_error = _two_sum(arm_i, -arm_j)
    return (position + arm) + (position_error + arm_error)


@njit(**JIT)
def fill_body_turns(q, turns):
    """cos and sin of the angle of every body, the ground included: ``turns[b] = (cos, sin)``."""
    for b in range(turns.shape[0]):
        angle = q[3 * b + 2]
        turns[b, 0] = math.cos(angle)
        turns[b, 1] = math.sin(angle)


@njit(**JIT)
def load_coordinates(coordinates, q, turns):
    """``q[:coordinates.size] = coordinates`` and `fill_body_turns` there, unless q holds them
    already (then `turns` is that of the fill that put them there: nothing is written)."""
    k = 0
    while k < coordinates.size and q[k] == coordinates[k]:
        k += 1
    if k == coordinates.size:
        return
    for j in range(k, coordinates.size):
        q[j] = coordinates[j]
    fill_body_turns(q, turns)


# ---------------------------------------------------------------------- point coincidence
@njit(inline="always", **JIT)
def fill_coincidence_at(c, k, q, turns, residual, jac_data, constants=True):
    """The k-th coincidence of `fill_coincidence`: its two rows of Φ and eight entries of
    Φq (without `constants`, the four that turn with the bodies only: the ±1 on their x and
    y columns are left as an earlier fill of `jac_data` wrote them); returns ``(i, j, r, ax,
    ay, bx, by)``: its bodies' first columns, its first row, and its two arms (for kernels
    that go on with the same joint)."""
    bi, bj = c.body_i[k], c.body_j[k]
    i, j, r = 3 * bi, 3 * bj, c.row[k]
    ax, ay = _turned(turns[bi, 0], turns[bi, 1], c.local_i[k])  # a = R_i s_i
    bx, by = _turned(turns[bj, 0], turns[bj, 1], c.local_j[k])  # b = R_j s_j
    residual[r] = _gap(q[i], ax, q[j], bx)
    residual[r + 1] = _gap(q[i + 1], ay, q[j + 1], by)
    s = c.slots[k]
    if constants:
        jac_data[s[0]] = 1.0
        jac_data[s[2]] = -1.0
        jac_data[s[4]] = 1.0
        jac_data[s[6]] = -1.0
    jac_data[s[1]] = -ay
    jac_data[s[3]] = by
    jac_data[s[5]] = ax
    jac_data[s[7]] = -bx
    return i, j, r, ax, ay, bx, by


@njit(**JIT)
def fill_coincidence(q, turns, c, residual, jac_data):
    """g = r_i + R_i s_i - r_j - R_j s_j: 2 rows, 8 entries."""
    for k in range(c.row.size):
        fill_coincidence_at(c, k, q, turns, residual, jac_data)


@njit(**JIT)
def fill_coincidence_gamma(qd, turns, c, gamma):
    """gamma = a w_i² - b w_j²."""
    for k in range(c.row.size):
        bi, bj, r = c.body_i[k], c.body_j[k], c.row[k]
        ax, ay = _turned(turns[bi, 0], turns[bi, 1], c.local_i[k])
        bx, by = _turned(turns[bj, 0], turns[bj, 1], c.local_j[k])
        wi2, wj2 = qd[3 * bi + 2] ** 2, qd[3 * bj + 2] ** 2
        gamma[r] = ax * wi2 - bx * wj2
        gamma[r + 1] = ay * wi2 - by * wj2


# ---------------------------------------------------------------------- projected distance
@njit(**JIT)
def fill_projection(q, turns, p, residual, jac_data):
    """g = n · (r_j + b - r_i - a) + rolling (angle_j - angle_i), n = R_i u: 1 row, 6 entries."""
    for k in range(p.row.size):
        bi, bj = p.body_i[k], p.body_j[k]
        i, j = 3 * bi, 3 * bj
        cos_i, sin_i = turns[bi, 0], turns[bi, 1]
        nx, ny = _turned(cos_i, sin_i, p.direction[k])
        ax, ay = _turned(cos_i, sin_i, p.local_i[k])
        bx, by = _turned(turns[bj, 0], turns[bj, 1], p.local_j[k])
        # d = r_j + b - r_i - a, and e = d + a: the end point seen from body i's frame origin
        dx = _gap(q[j], bx, q[i], ax)
        dy = _gap(q[j + 1], by, q[i + 1], ay)
        ex, ey = dx + ax, dy + ay
        rolling = p.rolling[k]
        residual[p.row[k]] = nx * dx + ny * dy + rolling * (q[j + 2] - q[i + 2])
        s = p.slots[k]
        jac_data[s[0]] = -nx
        jac_data[s[1]] = -ny
        jac_data[s[2]] = -ny * ex + nx * ey - rolling  # (Omega n) · e - rolling
        jac_data[s[3]] = nx
        jac_data[s[4]] = ny
        jac_data[s[5]] = -nx * by + ny * bx + rolling  # n · (Omega b) + rolling


@njit(**JIT)
def fill_projection_gamma(q, qd, turns, p, gamma):
    """gamma = w_i² n·(d - a) + w_j² n·b - 2 w_i (Omega n)·d', d = r_j + b - r_i - a.

    The rolling term is linear in q: it adds nothing.
    """
    for k in range(p.row.size):
        bi, bj = p.body_i[k], p.body_j[k]
        i, j = 3 * bi, 3 * bj
        cos_i, sin_i = turns[bi, 0], turns[bi, 1]
        wi, wj = qd[i + 2], qd[j + 2]
        nx, ny = _turned(cos_i, sin_i, p.direction[k])
        ax, ay = _turned(cos_i, sin_i, p.local_i[k])
        bx, by = _turned(turns[bj, 0], turns[bj, 1], p.local_j[k])
        dx = _gap(q[j], bx, q[i], ax)
        dy = _gap(q[j + 1], by, q[i + 1], ay)
        # d' = r_j' + Omega b w_j - r_i' - Omega a w_i
        ddx = qd[j] - by * wj - qd[i] + ay * wi
        ddy = qd[j + 1] + bx * wj - qd[i + 1] - ax * wi
        gamma[p.row[k]] = (
            wi * wi * (nx * (dx - ax) + ny * (dy - ay))
            + wj * wj * (nx * bx + ny * by)
            - 2.0 * wi * (-ny * ddx + nx * ddy)
        )


# ---------------------------------------------------------------------- linear combination
@njit(**JIT)
def fill_combination(q, m, residual, jac_data):
    """g = sum of coefficient · q[column] over the row's terms."""
    for k in range(m.row.size):
        total = 0.0
        for e in range(m.start[k], m.start[k + 1]):
            total += m.coefficient[e] * q[m.column[e]]
            jac_data[m.slots[e]] = m.coefficient[e]
        residual[m.row[k]] = total


@njit(**JIT)
def fill_combination_gamma(m, gamma):
    """g is linear in q: gamma = 0."""
    for k in range(m.row.size):
        gamma[m.row[k]] = 0.0


# ---------------------------------------------------------------------- distance
@njit(inline="always", **JIT)
def point_separation(q, turns, body_i, body_j, local_i, local_j):
    """Arms ``a = R_i s_i``, ``b = R_j s_j`` and ``d = r_j + b - r_i - a`` with its length:
    ``(ax, ay, bx, by, dx, dy, length)``."""
    i, j = 3 * body_i, 3 * body_j
    ax, ay = _turned(turns[body_i, 0], turns[body_i, 1], local_i)
    bx, by = _turned(turns[body_j, 0], turns[body_j, 1], local_j)
    dx = _gap(q[j], bx, q[i], ax)
    dy = _gap(q[j + 1], by, q[i + 1], ay)
    return ax, ay, bx, by, dx, dy, math.hypot(dx, dy)


@njit(inline="always", **JIT)
def separation_rate(qd, body_i, body_j, ax, ay, bx, by):
    """``d' = r_j' + Omega b w_j - r_i' - Omega a w_i`` of `point_separation`'s d."""
    i, j = 3 * body_i, 3 * body_j
    wi, wj = qd[i + 2], qd[j + 2]
    return qd[j] - by * wj - qd[i] + ay * wi, qd[j + 1] + bx * wj - qd[i + 1] - ax * wi


@njit(**JIT)
def fill_distance(q, turns, d, residual, jac_data):
    """g = |d|, d = r_j + b - r_i - a: 1 row, 6 entries, with e = d / |d|."""
    for k in range(d.row.size):
        ax, ay, bx, by, dx, dy, length = point_separation(q, turns, d.body_i[k], d.body_j[k], d.local_i[k], d.local_j[k])
        ex, ey = dx / length, dy / length
        residual[d.row[k]] = length
        s = d.slots[k]
        jac_data[s[0]] = -ex
        jac_data[s[1]] = -ey
        jac_data[s[2]] = ex * ay - ey * ax  # -e · (Omega a)
        jac_data[s[3]] = ex
        jac_data[s[4]] = ey
        jac_data[s[5]] = -ex * by + ey * bx  # e · (Omega b)


@njit(**JIT)
def fill_distance_gamma(q, qd, turns, d, gamma):
    """gamma = e·(b w_j² - a w_i²) - (|d'|² - (e·d')²) / |d|."""
    for k in range(d.row.size):
        bi, bj = d.body_i[k], d.body_j[k]
        wi, wj = qd[3 * bi + 2], qd[3 * bj + 2]
        ax, ay, bx, by, dx, dy, length = point_separation(q, turns, bi, bj, d.local_i[k], d.local_j[k])
        ex, ey = dx / length, dy / length
        ddx, ddy = separation_rate(qd, bi, bj, ax, ay, bx, by)
        along = ex * ddx + ey * ddy
        gamma[d.row[k]] = (
            ex * (bx * wj * wj - ax * wi * wi) + ey * (by * wj * wj - ay * wi * wi)
            - (ddx * ddx + ddy * ddy - along * along) / length
        )


# ---------------------------------------------------------------------- the wiring
@njit(inline="always", **JIT)
def _fill_all(primitives, q, turns, residual, jac_data):
    fill_body_turns(q, turns)
    fill_coincidence(q, turns, primitives.coincidence, residual, jac_data)
    fill_projection(q, turns, primitives.projection, residual, jac_data)
    fill_combination(q, primitives.combination, residual, jac_data)
    fill_distance(q, turns, primitives.distance, residual, jac_data)


@njit(inline="always", **JIT)
def residual_jacobian(primitives, q, turns, target, weights, residual, jac_data):
    """Residual g(q) - target and the Jacobian values at q; returns the weighted norm.

    The norm is max |residual| · weights, NaN when any entry is not finite; every row
    is g(q) - target even then.  `turns` receives the cos and sin of every body's angle
    at q.  (Inlined into the compiled time loop; `fill_residual_jacobian` calls it from
    Python.)
    """
    _fill_all(primitives, q, turns, residual, jac_data)
    return residual_norm(residual, target, weights)


@njit(inline="always", **JIT)
def residual_norm(residual, target, weights):
    """``residual −= target`` and its weighted norm (max |residual| · weights, NaN when any
    entry is not finite)."""
    norm, finite = 0.0, True
    for r in range(residual.size):
        residual[r] -= target[r]
        weighted = abs(residual[r]) * weights[r]
        if not weighted <= norm:  # larger, or NaN
            if math.isfinite(weighted):
                norm = weighted
            else:
                finite = False
    return norm if finite else math.nan


@njit(**JIT)
def fill_residual_jacobian(primitives, q, turns, target, weights, residual, jac_data):
    """`residual_jacobian`, called from Python."""
    return residual_jacobian(primitives, q, turns, target, weights, residual, jac_data)


@njit(inline="always", **JIT)
def acceleration_rhs(primitives, q, qd, turns, gamma):
    """gamma at (q, qd), `turns` already filled at q."""
    fill_coincidence_gamma(qd, turns, primitives.coincidence, gamma)
    fill_projection_gamma(q, qd, turns, primitives.projection, gamma)
    fill_combination_gamma(primitives.combination, gamma)
    fill_distance_gamma(q, qd, turns, primitives.distance, gamma)


@njit(**JIT)
def fill_gamma(primitives, q, qd, turns, gamma):
    """`acceleration_rhs`, called from Python."""
    acceleration_rhs(primitives, q, qd, turns, gamma)


@njit(**JIT)
def fill_outputs(primitives, indptr, indices, coordinates, velocities, accelerations, value, rate, acceleration):
    """Own coordinates of elements at every sample: value g, rate J qd, acceleration J qdd - gamma.

    `coordinates`, `velocities` and `accelerations` have shape (n_times, n_coordinates);
    the outputs (n_times, n_rows).
    """
    n_rows, n = value.shape[1], coordinates.shape[1]
    q = np.zeros(n + 3)  # the ground appended
    qd = np.zeros(n + 3)
    turns = np.zeros((n // 3 + 1, 2))
    jac_data = np.zeros(indptr[n_rows] + 1)
    gamma = np.zeros(n_rows)
    for k in range(coordinates.shape[0]):
        for c in range(n):
            q[c] = coordinates[k, c]
            qd[c] = velocities[k, c]
        _fill_all(primitives, q, turns, value[k], jac_data)
        acceleration_rhs(primitives, q, qd, turns, gamma)
        for r in range(n_rows):
            first, second = 0.0, 0.0
            for s in range(indptr[r], indptr[r + 1]):
                first += jac_data[s] * velocities[k, indices[s]]
                second += jac_data[s] * accelerations[k, indices[s]]
            rate[k, r] = first
            acceleration[k, r] = second - gamma[r]
