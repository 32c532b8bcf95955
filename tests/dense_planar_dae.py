"""A dense Lagrange-multiplier formulation of planar rigid-body mechanisms, for cross-checks.

Written from the textbook equations (Nikravesh, Haug) with NumPy and SciPy only; it shares
nothing with sparsekin's kernels.  tests/dynamics_reference.py builds the N-four-bar and
Andrews' mechanism with it to check its reduced and published models.

Coordinates q_k = (x_k, y_k, phi_k): the centre of mass of body k and its angle.  A point with
body-fixed offset s (from the centre of mass, in the body frame) is at r_k + R(phi_k) s, and
its acceleration is a_k + R'(phi_k) s phi_k'' - R(phi_k) s phi_k'^2 (R' = dR/dphi).  Hence for
a revolute joining s_i on body i to s_j on body j (or a fixed point c of the ground):
    Phi   = r_i + R_i s_i - r_j - R_j s_j
    Phi_q = [I, R_i' s_i | -I, -R_j' s_j]
    gamma = R_i s_i phi_i'^2 - R_j s_j phi_j'^2
Equations of motion, with M = diag(m_k, m_k, J_k) (J_k about the centre of mass):
    [M  Phi_q^T] [a]        [Q    ]
    [Phi_q   0 ] [lambda] = [gamma]
Q: gravity m_k g on r_k; a torque tau on phi_k; a spring of stiffness c and free length l0
from s on body k to a ground point p: F = -c (l - l0)/l (P - p), P = r_k + R_k s, l = |P - p|,
acting on r_k with the moment (R_k' s) . F on phi_k.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp


@dataclass(frozen=True)
class PlanarSystem:
    """Bodies, revolutes and loads of a planar mechanism in centre-of-mass coordinates.

    Attributes
    ----------
    masses, inertias : ndarray, shape (n_bodies,)
        kg and kg m^2 (about the centre of mass); both must be positive.
    revolutes : tuple of (body_i, offset_i, body_j, offset_j)
        ``body_j = -1`` is the ground, and ``offset_j`` is then a global point; offsets are
        body-fixed vectors from the centre of mass, in the body frame (m).
    springs : tuple of (body, offset, ground_point, stiffness, free_length)
    torques : tuple of (body, torque)
        A constant torque (N m, counter-clockwise positive) on a body.
    gravity : (gx, gy)
    """

    masses: np.ndarray
    inertias: np.ndarray
    revolutes: tuple
    springs: tuple = ()
    torques: tuple = ()
    gravity: tuple = (0.0, 0.0)

    @property
    def n_bodies(self) -> int:
        return len(self.masses)


def rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _rotation_derivative(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[-s, -c], [c, -s]])


def planar_constraints(system: PlanarSystem, q: np.ndarray, v: np.ndarray | None = None):
    """(Phi, Phi_q, gamma) of the revolutes at q (and v, for gamma; None gives gamma = 0).

    Shapes: (2 n_joints,), (2 n_joints, 3 n_bodies), (2 n_joints,).
    """
    n_rows = 2 * len(system.revolutes)
    residual = np.zeros(n_rows)
    jacobian = np.zeros((n_rows, 3 * system.n_bodies))
    gamma = np.zeros(n_rows)
    for row, (body_i, offset_i, body_j, offset_j) in enumerate(system.revolutes):
        rows = slice(2 * row, 2 * row + 2)
        for body, offset, sign in ((body_i, offset_i, 1.0), (body_j, offset_j, -1.0)):
            offset = np.asarray(offset, dtype=float)
            if body < 0:
                residual[rows] += sign * offset
                continue
            angle = q[3 * body + 2]
            residual[rows] += sign * (q[3 * body : 3 * body + 2] + rotation(angle) @ offset)
            jacobian[rows, 3 * body : 3 * body + 2] += sign * np.eye(2)
            jacobian[rows, 3 * body + 2] += sign * (_rotation_derivative(angle) @ offset)
            if v is not None:
                gamma[rows] += sign * (rotation(angle) @ offset) * v[3 * body + 2] ** 2
    return residual, jacobian, gamma


def planar_forces(system: PlanarSystem, q: np.ndarray) -> np.ndarray:
    """Generalized applied forces Q (gravity, springs, torques), shape (3 n_bodies,)."""
    forces = np.zeros(3 * system.n_bodies)
    forces[0::3] = system.masses * system.gravity[0]
    forces[1::3] = system.masses * system.gravity[1]
    for body, offset, anchor, stiffness, free_length in system.springs:
        angle = q[3 * body + 2]
        point = q[3 * body : 3 * body + 2] + rotation(angle) @ np.asarray(offset, dtype=float)
        stretch = point - np.asarray(anchor, dtype=float)
        length = np.hypot(*stretch)
        force = -stiffness * (length - free_length) / length * stretch
        forces[3 * body : 3 * body + 2] += force
        forces[3 * body + 2] += (_rotation_derivative(angle) @ np.asarray(offset, dtype=float)) @ force
    for body, torque in system.torques:
        forces[3 * body + 2] += torque
    return forces


def planar_accelerations(system: PlanarSystem, q: np.ndarray, v: np.ndarray):
    """Accelerations and multipliers from the dense saddle-point system: ``(a, lambda)``."""
    _, jacobian, gamma = planar_constraints(system, q, v)
    n, m = 3 * system.n_bodies, jacobian.shape[0]
    matrix = np.zeros((n + m, n + m))
    matrix[:n, :n] = np.diag(np.column_stack([system.masses, system.masses, system.inertias]).ravel())
    matrix[:n, n:] = jacobian.T
    matrix[n:, :n] = jacobian
    solution = np.linalg.solve(matrix, np.concatenate([planar_forces(system, q), gamma]))
    return solution[:n], solution[n:]


def planar_energy(system: PlanarSystem, q: np.ndarray, v: np.ndarray) -> float:
    """Kinetic + gravitational + spring energy (J) at one state (torques excluded)."""
    q, v = np.asarray(q), np.asarray(v)
    kinetic = 0.5 * (system.masses @ (v[0::3] ** 2 + v[1::3] ** 2) + system.inertias @ v[2::3] ** 2)
    potential = -(system.masses @ (q[0::3] * system.gravity[0] + q[1::3] * system.gravity[1]))
    elastic = 0.0
    for body, offset, anchor, stiffness, free_length in system.springs:
        point = q[3 * body : 3 * body + 2] + rotation(q[3 * body + 2]) @ np.asarray(offset, dtype=float)
        elastic += 0.5 * stiffness * (np.hypot(*(point - np.asarray(anchor))) - free_length) ** 2
    return kinetic + potential + elastic


def integrate_planar_dae(system: PlanarSystem, q0, v0, times, rtol: float = 1e-12, atol: float = 1e-12):
    """Integrate the index-1 (acceleration-level) form with DOP853 from a consistent (q0, v0).

    No stabilization: the drift of Phi and Phi_q v is that of the integration error and is
    returned so that callers can check it.  Returns ``(q, v, drift)``, shapes (n_t, 3 n_bodies)
    twice and (n_t, 2): the largest |Phi| and |Phi_q v| at each time.
    """
    times = np.asarray(times, dtype=float)
    n = 3 * system.n_bodies

    def rhs(_t, state):
        a, _ = planar_accelerations(system, state[:n], state[n:])
        return np.concatenate([state[n:], a])

    state0 = np.concatenate([np.asarray(q0, dtype=float), np.asarray(v0, dtype=float)])
    solution = solve_ivp(rhs, (times[0], times[-1]), state0, method="DOP853", rtol=rtol, atol=atol, t_eval=times)
    if not solution.success:
        raise RuntimeError(f"reference DAE integration failed: {solution.message}")
    q, v = solution.y[:n].T, solution.y[n:].T
    drift = np.empty((len(times), 2))
    for k in range(len(times)):
        residual, jacobian, _ = planar_constraints(system, q[k])
        drift[k] = np.abs(residual).max(), np.abs(jacobian @ v[k]).max()
    return q, v, drift
