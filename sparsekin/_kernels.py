"""numba kernels: arrays in, preallocated arrays filled in place, nothing returned.

Symbols (for these kernels only):

* ``q``, ``qd`` — coordinates and velocities, ``(x, y, angle)`` per body, with the ground
  appended as a last body whose entries are zero (see `sparsekin.pattern`).
* ``residual`` — g(q), the geometric part of each constraint equation (the assembler
  subtracts the targets).
* ``jac_data`` — the values of the CSR Jacobian dg/dq, one slot past its end for the
  entries of the ground's columns, which are discarded.
* ``gamma`` — the acceleration right-hand side: -d²g/ds²(q + s·qd) at s = 0, so that
  ``jacobian @ qdd = gamma + (second time derivative of the targets)``.
* ``turns`` — ``(cos, sin)`` of every body's angle, shape (n_bodies + 1, 2), the ground
  last; `fill_body_turns` fills it once per configuration, so that each body's angle goes
  through cos and sin once, not once per equation it takes part in.
* ``R(angle)`` rotates a local vector into the global frame; ``Omega`` turns a vector by
  +90°, so that ``d/dangle R s = Omega R s``.
"""

from __future__ import annotations

import math

from numba import njit

#: The one set of jit options for every kernel: cached, and no fastmath, so that
#: finiteness checks on the results keep working.
_JIT = dict(cache=True, nogil=True, error_model="numpy")


@njit(inline="always", **_JIT)
def _turned(cosine, sine, vector):
    """R(angle) @ vector for a local 2-vector, given cos and sin of the angle."""
    return cosine * vector[0] - sine * vector[1], sine * vector[0] + cosine * vector[1]


@njit(**_JIT)
def fill_body_turns(q, turns):
    """cos and sin of the angle of every body, the ground included: ``turns[b] = (cos, sin)``."""
    for b in range(turns.shape[0]):
        angle = q[3 * b + 2]
        turns[b, 0] = math.cos(angle)
        turns[b, 1] = math.sin(angle)


@njit(**_JIT)
def fill_point_coincidence(q, turns, body_i, body_j, local_i, local_j, row, slots, residual, jac_data):
    """Point s_i of body i coincides with point s_j of body j: 2 rows, 8 entries."""
    for k in range(row.size):
        i, j, r = 3 * body_i[k], 3 * body_j[k], row[k]
        cos_i, sin_i = turns[body_i[k], 0], turns[body_i[k], 1]
        cos_j, sin_j = turns[body_j[k], 0], turns[body_j[k], 1]
        # a = R_i s_i and b = R_j s_j, global vectors from the frames to the point
        ax, ay = _turned(cos_i, sin_i, local_i[k])
        bx, by = _turned(cos_j, sin_j, local_j[k])
        residual[r] = q[i] + ax - q[j] - bx
        residual[r + 1] = q[i + 1] + ay - q[j + 1] - by
        s = slots[k]
        jac_data[s[0]] = 1.0
        jac_data[s[1]] = -ay
        jac_data[s[2]] = -1.0
        jac_data[s[3]] = by
        jac_data[s[4]] = 1.0
        jac_data[s[5]] = ax
        jac_data[s[6]] = -1.0
        jac_data[s[7]] = -bx


@njit(**_JIT)
def fill_point_coincidence_gamma(q, qd, turns, body_i, body_j, local_i, local_j, row, gamma):
    """gamma = R_i s_i angle_i'² - R_j s_j angle_j'²."""
    for k in range(row.size):
        i, j, r = 3 * body_i[k], 3 * body_j[k], row[k]
        cos_i, sin_i = turns[body_i[k], 0], turns[body_i[k], 1]
        cos_j, sin_j = turns[body_j[k], 0], turns[body_j[k], 1]
        ax, ay = _turned(cos_i, sin_i, local_i[k])
        bx, by = _turned(cos_j, sin_j, local_j[k])
        wi2, wj2 = qd[i + 2] ** 2, qd[j + 2] ** 2
        gamma[r] = ax * wi2 - bx * wj2
        gamma[r + 1] = ay * wi2 - by * wj2


@njit(**_JIT)
def fill_projected_distance(q, turns, body_i, body_j, local_i, local_j, direction, row, slots, residual, jac_data):
    """g = n · (r_j + R_j s_j - r_i - R_i s_i) with n = R_i u, u fixed in body i: 1 row, 6 entries."""
    for k in range(row.size):
        i, j = 3 * body_i[k], 3 * body_j[k]
        cos_i, sin_i = turns[body_i[k], 0], turns[body_i[k], 1]
        cos_j, sin_j = turns[body_j[k], 0], turns[body_j[k], 1]
        nx, ny = _turned(cos_i, sin_i, direction[k])
        ax, ay = _turned(cos_i, sin_i, local_i[k])
        bx, by = _turned(cos_j, sin_j, local_j[k])
        # e = r_j + b - r_i: the end point seen from body i's frame origin
        ex = q[j] + bx - q[i]
        ey = q[j + 1] + by - q[i + 1]
        residual[row[k]] = nx * (ex - ax) + ny * (ey - ay)
        s = slots[k]
        jac_data[s[0]] = -nx
        jac_data[s[1]] = -ny
        jac_data[s[2]] = -ny * ex + nx * ey  # (Omega n) · e
        jac_data[s[3]] = nx
        jac_data[s[4]] = ny
        jac_data[s[5]] = -nx * by + ny * bx  # n · (Omega b)


@njit(**_JIT)
def fill_projected_distance_gamma(q, qd, turns, body_i, body_j, local_i, local_j, direction, row, gamma):
    """gamma = wi² n·(d - a) + wj² n·b - 2 wi (Omega n)·d', d = r_j + b - r_i - a."""
    for k in range(row.size):
        i, j = 3 * body_i[k], 3 * body_j[k]
        cos_i, sin_i = turns[body_i[k], 0], turns[body_i[k], 1]
        cos_j, sin_j = turns[body_j[k], 0], turns[body_j[k], 1]
        wi, wj = qd[i + 2], qd[j + 2]
        nx, ny = _turned(cos_i, sin_i, direction[k])
        ax, ay = _turned(cos_i, sin_i, local_i[k])
        bx, by = _turned(cos_j, sin_j, local_j[k])
        dx = q[j] + bx - q[i] - ax
        dy = q[j + 1] + by - q[i + 1] - ay
        # d' = r_j' + Omega b wj - r_i' - Omega a wi
        ddx = qd[j] - by * wj - qd[i] + ay * wi
        ddy = qd[j + 1] + bx * wj - qd[i + 1] - ax * wi
        gamma[row[k]] = (
            wi * wi * (nx * (dx - ax) + ny * (dy - ay))
            + wj * wj * (nx * bx + ny * by)
            - 2.0 * wi * (-ny * ddx + nx * ddy)
        )


@njit(**_JIT)
def fill_coordinate_difference(q, plus, minus, row, slots, residual, jac_data):
    """g = q[plus] - q[minus]: 1 row, 2 entries; its gamma is zero."""
    for k in range(row.size):
        residual[row[k]] = q[plus[k]] - q[minus[k]]
        jac_data[slots[k, 0]] = 1.0
        jac_data[slots[k, 1]] = -1.0
