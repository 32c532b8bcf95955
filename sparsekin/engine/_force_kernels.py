"""numba kernels of the forces: the applied and inertial forces, and the forces of elements.

With the motion known, the Lagrange multipliers ``lam`` of the constraints solve

    Phi_q^T lam = b,    b = Q(q, qd, t) - M(q) qdd - h(q, qd),

the generalized forces of gravity and the loads minus the inertial forces (absolute
coordinates: Q, M q̈ + h per body frame ``(x, y, angle)``).  The constraints then apply
``-Phi_q^T lam`` to the bodies.  `fill_applied_forces` fills b; `fill_force_outputs`
turns ``lam`` into what ``forces.csv`` reports: each driver's force (``-lam`` of each of
its rows: the force along the quantity it drives) and power, each joint's reaction on
``bodies[0]`` from ``bodies[1]`` with its torque about the joint's point.

Symbols as in `sparsekin.engine._kernels`: ``q``, ``qd``, ``qdd`` with the ground appended as a
last body of zeros, ``turns`` the (cos, sin) of every body's angle.  For a body with
centre of mass at ``a = R s`` from its frame origin, the acceleration of the centre is
``r'' + angle'' Omega a - angle'² a``.
"""

from __future__ import annotations

from numba import njit

from .._jit import JIT
from ._kernels import _turned, point_separation, separation_rate


@njit(inline="always", **JIT)
def _arm(turns, body, local):
    """R(angle_body) @ local."""
    return _turned(turns[body, 0], turns[body, 1], local)


@njit(inline="always", **JIT)
def _add_force(out, body, arm_x, arm_y, fx, fy):
    """A force (fx, fy) at the point ``r_body + arm``: its generalized force on the body frame."""
    out[3 * body] += fx
    out[3 * body + 1] += fy
    out[3 * body + 2] += arm_x * fy - arm_y * fx


@njit(**JIT)
def fill_applied_forces(loads, q, qd, qdd, turns, law_values, inertial, out):
    """``out`` (3 · (n_bodies + 1)) = gravity and loads, minus the inertial forces if
    `inertial` (else the quasi-static right-hand side); the ground's entries are discarded."""
    for c in range(out.size):
        out[c] = 0.0
    masses = loads.masses
    gx, gy = loads.gravity[0], loads.gravity[1]
    for b in range(masses.mass.size):
        m, inertia = masses.mass[b], masses.inertia[b]
        if m == 0.0 and inertia == 0.0:
            continue
        ax, ay = _arm(turns, b, masses.com[b])
        fx, fy, torque = m * gx, m * gy, 0.0
        if inertial:
            omega, alpha = qd[3 * b + 2], qdd[3 * b + 2]
            fx -= m * (qdd[3 * b] - alpha * ay - omega * omega * ax)
            fy -= m * (qdd[3 * b + 1] + alpha * ax - omega * omega * ay)
            torque = -inertia * alpha
        _add_force(out, b, ax, ay, fx, fy)
        out[3 * b + 2] += torque
    force = loads.force
    for k in range(force.body.size):
        b = force.body[k]
        ax, ay = _arm(turns, b, force.local[k])
        _add_force(out, b, ax, ay, law_values[force.law[k]], law_values[force.law[k] + 1])
    torque = loads.torque
    for k in range(torque.body.size):
        out[3 * torque.body[k] + 2] += law_values[torque.law[k]]
    spring = loads.spring
    for k in range(spring.body_i.size):
        i, j = spring.body_i[k], spring.body_j[k]
        aix, aiy, ajx, ajy, dx, dy, length = point_separation(q, turns, i, j, spring.local_i[k], spring.local_j[k])
        ex, ey = dx / length, dy / length
        vx, vy = separation_rate(qd, i, j, aix, aiy, ajx, ajy)
        tension = spring.stiffness[k] * (length - spring.free_length[k]) + spring.damping[k] * (ex * vx + ey * vy)
        _add_force(out, i, aix, aiy, tension * ex, tension * ey)
        _add_force(out, j, ajx, ajy, -tension * ex, -tension * ey)
    torsion = loads.torsion
    for k in range(torsion.body_i.size):
        i, j = torsion.body_i[k], torsion.body_j[k]
        moment = torsion.stiffness[k] * (q[3 * i + 2] - q[3 * j + 2] - torsion.free_angle[k]) + torsion.damping[k] * (
            qd[3 * i + 2] - qd[3 * j + 2]
        )
        out[3 * i + 2] -= moment
        out[3 * j + 2] += moment


@njit(**JIT)
def fill_force_outputs(outputs, values, multipliers, q, turns, rates, work, out):
    """The forces of the selected drivers and joints from the multipliers, into `out`.

    Parameters
    ----------
    outputs : ForceOutputArrays
        Which rows and Jacobian entries make each column (`sparsekin.engine.forces`).
    values : ndarray
        The Jacobian's values at the configuration; entry e of a reaction is
        ``values[outputs.entry_position[e]]``.
    multipliers : ndarray, shape (n_equations,)
    rates : ndarray, shape (n_equations,)
        The rate of each driven quantity (the laws' first derivatives) on driven rows.
    work : ndarray, shape (n_joints_selected, 3)
        Scratch.
    out : ndarray, shape (n_columns,)
    """
    for d in range(outputs.driver_row.size):
        r, column = outputs.driver_row[d], outputs.driver_column[d]
        power = 0.0
        for e in range(outputs.driver_rows[d]):
            force = -multipliers[r + e]
            out[column + e] = force
            power += force * rates[r + e]
        out[column + outputs.driver_rows[d]] = power
    for k in range(work.shape[0]):
        work[k, 0], work[k, 1], work[k, 2] = 0.0, 0.0, 0.0
    for e in range(outputs.entry_position.size):
        work[outputs.entry_joint[e], outputs.entry_component[e]] += (
            values[outputs.entry_position[e]] * multipliers[outputs.entry_row[e]]
        )
    for k in range(outputs.joint_side.size):
        # -Phi_q^T lam on the side body's frame: force, and moment about its origin
        fx, fy, moment = -work[k, 0], -work[k, 1], -work[k, 2]
        side, carrier = outputs.joint_side[k], outputs.joint_point_body[k]
        px, py = _arm(turns, carrier, outputs.joint_point_local[k])
        arm_x = q[3 * carrier] + px - q[3 * side]
        arm_y = q[3 * carrier + 1] + py - q[3 * side + 1]
        moment -= arm_x * fy - arm_y * fx  # about the joint's point
        sign = 1.0 if outputs.joint_side_is_first[k] else -1.0  # on bodies[0], from bodies[1]
        column = outputs.joint_column[k]
        out[column] = sign * fx
        out[column + 1] = sign * fy
        if outputs.joint_torque[k]:
            out[column + 2] = sign * moment
