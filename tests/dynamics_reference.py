"""Exact and published references for forward dynamics (issue 25), from NumPy and SciPy only.

Nothing here imports sparsekin: every answer comes from a closed form, from a one-degree-of-
freedom ODE derived below and integrated by SciPy at tolerances near round-off, or from a
published reference solution.  Three IFToMM multibody benchmarks:

A01, simple pendulum
    ``pendulum_period``, ``pendulum_angle``, ``pendulum_point``: a point mass m on a massless
    link of length L, pinned at the origin, released from rest at an angle theta0 from the
    downward vertical (the benchmark: m = 1 kg, L = 1 m, theta0 = pi/2, g = 9.81 m/s^2).
A02, N-four-bar mechanism
    ``n_four_bar_constants``, ``n_four_bar_motion``, ``n_four_bar_b0``, ``n_four_bar_energy``:
    2N + 1 uniform bars; the motion reduces exactly to one ODE in the common crank angle.
A03, Andrews' squeezing mechanism
    ``ANDREWS``, ``ANDREWS_INITIAL_ANGLES``, ``ANDREWS_REFERENCE_ANGLES`` (the published
    solution at t = 0.03 s), ``andrews_relative_motion`` (the published seven-angle equations,
    integrated here), ``andrews_geometry`` (the same mechanism as points, bodies, masses,
    centres of mass, inertias, ten revolutes, a spring and a torque: a sparsekin model).

and, to cross-check them, ``n_four_bar_system`` and ``andrews_system``: the same mechanisms
as bodies and revolutes for the dense Lagrange-multiplier formulation of
tests/dense_planar_dae.py (absolute coordinates, written from the textbook equations, sharing
nothing with sparsekin's kernels).

Symbols: q coordinates, v = dq/dt, M mass matrix, Phi constraints, Phi_q their Jacobian,
gamma = -d(Phi_q)/dt v the right-hand side of the acceleration equation Phi_q a = gamma,
lambda the multipliers.  e(alpha) = (cos alpha, sin alpha).  SI units throughout.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipk, ellipkinc

from dense_planar_dae import PlanarSystem, rotation

#: Standard gravity of the IFToMM benchmarks, m/s^2 (acting along -y).
GRAVITY = 9.81

#: Tolerances of the reference integrations (DOP853), near the round-off of the states.
REFERENCE_RTOL = 1e-13
REFERENCE_ATOL = 1e-13


def unit(angle):
    """e(angle) = (cos angle, sin angle), stacked on the last axis."""
    angle = np.asarray(angle, dtype=float)
    return np.stack([np.cos(angle), np.sin(angle)], axis=-1)


# ---------------------------------------------------------------------------------------------
# A01: simple pendulum
# ---------------------------------------------------------------------------------------------
#
# Angle theta from the downward vertical, point at L (sin theta, -cos theta).  Energy:
#     (1/2) m L^2 theta'^2 - m g L cos theta = -m g L cos theta0
# so theta'^2 = 2 (g/L)(cos theta - cos theta0) = 4 w0^2 (k^2 - sin^2(theta/2)),
# with w0 = sqrt(g/L) and k = sin(theta0/2).  Substituting sin(theta/2) = k sin(psi) gives
# psi' = w0 sqrt(1 - k^2 sin^2 psi), so w0 t = F(psi | m) with the parameter m = k^2 (SciPy's
# convention: ellipk(m), ellipj(u, m) take m = k^2, not the modulus k).  Hence
#     sin(theta/2) = k sn(u | m),  theta' = 2 k w0 cn(u | m) du/dt,
# and starting at rest at theta0 (sn = 1, u = K) with theta decreasing: u = K(m) - w0 t,
#     theta(t) = 2 arcsin(k sn(K - w0 t | m)),  theta'(t) = -2 k w0 cn(K - w0 t | m)
# (using dn = sqrt(1 - k^2 sn^2) in the derivative of arcsin).  The period is the time of
# four quarter swings, T = 4 K(m) / w0 = 4 sqrt(L/g) K(sin^2(theta0/2)); as theta0 -> 0 it
# tends to 2 pi sqrt(L/g).


def pendulum_period(length: float = 1.0, initial_angle: float = np.pi / 2, gravity: float = GRAVITY) -> float:
    """Period (s) of the planar pendulum released from rest at `initial_angle` (rad from the
    downward vertical, 0 < |initial_angle| < pi): 4 sqrt(L/g) K(m), m = sin^2(initial_angle/2).

    >>> round(pendulum_period(), 6)        # A01: 1 m, released horizontal
    2.367842
    """
    parameter = np.sin(initial_angle / 2.0) ** 2
    return float(4.0 * np.sqrt(length / gravity) * ellipk(parameter))


def pendulum_angle(times, length: float = 1.0, initial_angle: float = np.pi / 2, gravity: float = GRAVITY):
    """Exact angle and angular velocity of the pendulum released from rest.

    Parameters
    ----------
    times : array_like, shape (n,)
        Times, s (t = 0 is the release).
    length, initial_angle, gravity
        L (m), theta0 (rad from the downward vertical, 0 < theta0 < pi), g (m/s^2).

    Returns
    -------
    angle, rate : ndarray, shape (n,)
        theta (rad from the downward vertical, positive counter-clockwise, so the point is at
        L (sin theta, -cos theta)) and d theta/dt (rad/s).
    """
    times = np.asarray(times, dtype=float)
    k = np.sin(initial_angle / 2.0)
    natural = np.sqrt(gravity / length)
    sn, cn, _, _ = ellipj(ellipk(k * k) - natural * times, k * k)
    return 2.0 * np.arcsin(k * sn), -2.0 * k * natural * cn


def pendulum_point(times, length: float = 1.0, initial_angle: float = np.pi / 2, gravity: float = GRAVITY):
    """Exact position and velocity of the pendulum's point (pivot at the origin, g along -y).

    Returns ``(position, velocity)``, each an ndarray of shape (n, 2), m and m/s.  For A01 the
    point starts at (L, 0), swings through (0, -L) to (-L, 0) and back.
    """
    angle, rate = pendulum_angle(times, length, initial_angle, gravity)
    position = length * np.stack([np.sin(angle), -np.cos(angle)], axis=-1)
    velocity = length * rate[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    return position, velocity


def pendulum_energy(angle, rate, length: float = 1.0, mass: float = 1.0, gravity: float = GRAVITY):
    """Kinetic + gravitational energy (J, zero potential at the pivot's height)."""
    angle, rate = np.asarray(angle), np.asarray(rate)
    return 0.5 * mass * (length * rate) ** 2 - mass * gravity * length * np.cos(angle)


# ---------------------------------------------------------------------------------------------
# A02: N-four-bar mechanism
# ---------------------------------------------------------------------------------------------
#
# Reading of the benchmark (IFToMM library, problem A02; the specification: 2N + 1 links of
# 1 m with a uniformly distributed mass of 1 kg, gravity 9.81 N/kg along -y, 20 s, N = 40, the
# x-velocity of B0 is 1 m/s at the start, reference: position and velocity of B0, high precision
# 1e-3): crank i (i = 0 ... N) is pinned to the ground at A_i = (i L, 0) and carries B_i at its
# other end; coupler i (i = 1 ... N) joins B_{i-1} to B_i.  At t = 0 the cranks are vertical
# (B_i = (i L, L)) and the couplers horizontal.  The pivot spacing equals the coupler length
# and all cranks are equally long, so every window is a parallelogram.
#
# Why the family is an exact test at every N.  With every crank at the same angle theta (from
# +x), B_i = (i L + L cos theta, L sin theta): consecutive tips stay L apart, so every coupler
# constraint holds identically and each coupler translates (angle 0) with B0's velocity.  This
# one-parameter family is the mechanism's configuration manifold away from the horizontal
# (there the Jacobian has full rank and the manifold is locally one-dimensional).  On it:
#     cranks:   N+1 bars pivoting at an end:  T = (N+1) (1/2)(m L^2/3) theta'^2,
#               V = (N+1) m g (L/2) sin theta
#     couplers: N bars translating with |v| = L |theta'|:  T = N (1/2) m L^2 theta'^2,
#               V = N m g L sin theta
# so, with I(N) = m L^2 ((N+1)/3 + N) and C(N) = m g L ((N+1)/2 + N),
#     I(N) theta'' = -C(N) cos theta                                      (*)
# (Lagrange's equation for T = I theta'^2 / 2, V = C sin theta; the constraint forces do no
# work on the manifold.)  The motion of (*) is analytic and satisfies the full constrained
# equations, multipliers included, also where the windows are flat (theta = k pi) and the
# degrees of freedom jump from 1 to N + 1: a solver on the right branch must keep every crank
# at theta(t), and a branch switch or a lag between cranks is an error.  Both I and C grow
# linearly in N, so the same exact answer checks a chain of any length: one closed ODE, not a
# large reference simulation.  Start: theta(0) = pi/2 and the tip velocity
# L theta' (-sin theta, cos theta) = (1, 0) m/s gives theta'(0) = -v0 / L (clockwise).
#
# Closed form of the period (a check of the integration): energy gives
# theta'^2 = w0^2 + 4 a sin^2(psi/2), psi = pi/2 - theta, w0 = v0/L, a = C/I, so
# t(psi) = (2 / w0) F(psi/2 | -4 a / w0^2) and one revolution (psi += 2 pi, two flat crossings)
# takes 4 K(-4 a / w0^2) / w0 (the parameter is negative: the cranks circulate).


@dataclass(frozen=True)
class FourBarChainConstants:
    """Reduced model (*) of the N-four-bar: I(N) theta'' = -C(N) cos theta.

    Attributes
    ----------
    n_loops : int
        N (2N + 1 bars: N + 1 cranks, N couplers).
    effective_inertia : float
        I(N) = m L^2 ((N+1)/3 + N), kg m^2.
    gravity_moment : float
        C(N) = m g L ((N+1)/2 + N), N m (potential energy C sin theta).
    initial_angle, initial_rate : float
        theta(0) = pi/2 (cranks vertical), theta'(0) = -v0/L (rad/s).
    length : float
        L, m (crank, coupler, pivot spacing).
    """

    n_loops: int
    effective_inertia: float
    gravity_moment: float
    initial_angle: float
    initial_rate: float
    length: float

    @property
    def revolution_period(self) -> float:
        """Time (s) of one full turn of the cranks, from the elliptic integral K(m), m < 0."""
        rate0 = abs(self.initial_rate)
        parameter = -4.0 * self.gravity_moment / self.effective_inertia / rate0**2
        return 4.0 * float(ellipk(parameter)) / rate0

    def time_at_angle(self, angle):
        """Time (s) at which the cranks first reach `angle` (rad, unwrapped, <= pi/2): the
        closed form t = (2/w0) F(psi/2 | m), psi = pi/2 - angle; independent of the ODE solver."""
        rate0 = abs(self.initial_rate)
        parameter = -4.0 * self.gravity_moment / self.effective_inertia / rate0**2
        return 2.0 / rate0 * ellipkinc((np.pi / 2 - np.asarray(angle)) / 2.0, parameter)


def n_four_bar_constants(
    n_loops: int = 40, initial_speed: float = 1.0, length: float = 1.0, mass: float = 1.0, gravity: float = GRAVITY
) -> FourBarChainConstants:
    """Constants of the reduced model for N windows of bars of `length` (m) and `mass` (kg),
    B0 starting at `initial_speed` m/s along +x from the vertical position."""
    if n_loops < 1:
        raise ValueError(f"`n_loops` must be at least 1, got {n_loops}")
    n = float(n_loops)
    return FourBarChainConstants(
        n_loops=int(n_loops),
        effective_inertia=mass * length**2 * ((n + 1.0) / 3.0 + n),
        gravity_moment=mass * gravity * length * ((n + 1.0) / 2.0 + n),
        initial_angle=np.pi / 2,
        initial_rate=-initial_speed / length,
        length=length,
    )


@dataclass(frozen=True)
class FourBarChainMotion:
    """Exact motion of the N-four-bar at the requested times (every crank at `angle`).

    Attributes: ``constants`` (FourBarChainConstants), ``times`` (n,), ``angle`` (n,) rad from
    +x, unwrapped, ``rate`` (n,) rad/s, ``acceleration`` (n,) rad/s^2.
    """

    constants: FourBarChainConstants
    times: np.ndarray
    angle: np.ndarray
    rate: np.ndarray
    acceleration: np.ndarray = field(repr=False)


@functools.lru_cache(maxsize=16)
def _integrate_n_four_bar(constants: FourBarChainConstants, t_end: float):
    ratio = constants.gravity_moment / constants.effective_inertia

    def rhs(_t, state):
        return [state[1], -ratio * np.cos(state[0])]

    solution = solve_ivp(
        rhs,
        (0.0, t_end),
        [constants.initial_angle, constants.initial_rate],
        method="DOP853",
        rtol=REFERENCE_RTOL,
        atol=REFERENCE_ATOL,
        dense_output=True,
    )
    if not solution.success:
        raise RuntimeError(f"reference integration of the N-four-bar failed: {solution.message}")
    return solution.sol


def n_four_bar_motion(times, n_loops: int = 40, initial_speed: float = 1.0, length: float = 1.0,
                      mass: float = 1.0, gravity: float = GRAVITY) -> FourBarChainMotion:
    """Crank angle, rate and acceleration of the N-four-bar at `times` (s, >= 0), from the
    reduced ODE (*) integrated by DOP853 at rtol = atol = 1e-13 (error ~1e-12 rad over 20 s)."""
    times = np.asarray(times, dtype=float)
    constants = n_four_bar_constants(n_loops, initial_speed, length, mass, gravity)
    t_end = float(times.max(initial=0.0))
    if t_end <= 0.0:
        angle = np.full_like(times, constants.initial_angle)
        rate = np.full_like(times, constants.initial_rate)
    else:
        # Round the horizon up so that repeated calls share one cached integration.
        dense = _integrate_n_four_bar(constants, float(np.ceil(t_end)))
        angle, rate = dense(times)
    acceleration = -constants.gravity_moment / constants.effective_inertia * np.cos(angle)
    return FourBarChainMotion(constants, times, angle, rate, acceleration)


def n_four_bar_point(times, tip: int = 0, n_loops: int = 40, initial_speed: float = 1.0, length: float = 1.0,
                     mass: float = 1.0, gravity: float = GRAVITY):
    """Exact position and velocity of B_tip (the free end of crank `tip`, pivot (tip L, 0)).

    Returns ``(position, velocity)``, each an ndarray of shape (n, 2), m and m/s.
    """
    motion = n_four_bar_motion(times, n_loops, initial_speed, length, mass, gravity)
    position = length * unit(motion.angle) + np.array([tip * length, 0.0])
    velocity = length * motion.rate[:, None] * unit(motion.angle + np.pi / 2)
    return position, velocity


def n_four_bar_b0(times, n_loops: int = 40, initial_speed: float = 1.0, length: float = 1.0, mass: float = 1.0,
                  gravity: float = GRAVITY):
    """The benchmark's output: position and velocity of B0, shape (n, 2) each.

    >>> position, velocity = n_four_bar_b0([0.0])
    >>> (position.round(12) + 0.0).tolist(), (velocity.round(12) + 0.0).tolist()
    ([[0.0, 1.0]], [[1.0, 0.0]])
    """
    return n_four_bar_point(times, 0, n_loops, initial_speed, length, mass, gravity)


def n_four_bar_energy(angle, rate, n_loops: int = 40, length: float = 1.0, mass: float = 1.0,
                      gravity: float = GRAVITY):
    """Kinetic and gravitational energy (J, zero at the pivots' height) of the whole chain with
    every crank at `angle` turning at `rate`: ``(kinetic, potential)``."""
    constants = n_four_bar_constants(n_loops, 1.0, length, mass, gravity)
    kinetic = 0.5 * constants.effective_inertia * np.asarray(rate) ** 2
    potential = constants.gravity_moment * np.sin(angle)
    return kinetic, potential


def n_four_bar_system(n_loops: int = 1, length: float = 1.0, mass: float = 1.0, gravity: float = GRAVITY):
    """The N-four-bar as a PlanarSystem: ``(system, state)``, where ``state(angle, rate)`` gives
    the full coordinates and velocities ``(q, v)`` with every crank at `angle` turning at `rate`.

    Bodies: cranks 0 ... N (indices 0 ... N), then couplers 1 ... N (indices N+1 ... 2N).
    Uniform slender bars, J = m L^2 / 12; a crank's body x axis points from its pivot to its
    tip.  The initial state of the benchmark is ``state(pi/2, -1.0)``.
    """
    n_bodies = 2 * n_loops + 1
    end = (length / 2, 0.0)
    start = (-length / 2, 0.0)
    revolutes = [(i, start, -1, (i * length, 0.0)) for i in range(n_loops + 1)]
    for i in range(1, n_loops + 1):  # coupler i joins B_{i-1} to B_i
        revolutes.append((n_loops + i, start, i - 1, end))
        revolutes.append((n_loops + i, end, i, end))
    system = PlanarSystem(
        masses=np.full(n_bodies, mass),
        inertias=np.full(n_bodies, mass * length**2 / 12.0),
        revolutes=tuple(revolutes),
        gravity=(0.0, -gravity),
    )

    def state(angle: float, rate: float):
        q, v = np.zeros(3 * n_bodies), np.zeros(3 * n_bodies)
        tip, tip_velocity = length * unit(angle), length * rate * unit(angle + np.pi / 2)
        for i in range(n_loops + 1):  # crank centre of mass halfway to the tip
            q[3 * i : 3 * i + 3] = i * length + tip[0] / 2, tip[1] / 2, angle
            v[3 * i : 3 * i + 3] = *(tip_velocity / 2), rate
        for i in range(1, n_loops + 1):  # coupler: translates with the tips, angle 0
            k = n_loops + i
            q[3 * k : 3 * k + 3] = (i - 0.5) * length + tip[0], tip[1], 0.0
            v[3 * k : 3 * k + 3] = *tip_velocity, 0.0
        return q, v

    return system, state


# ---------------------------------------------------------------------------------------------
# A03: Andrews' squeezing mechanism
# ---------------------------------------------------------------------------------------------
#
# Hairer & Wanner, Solving ODEs II, section VII.7, and the Test Set for IVP Solvers (Mazzia,
# Magherini et al., problem "andrews"; IFToMM A03).  Seven bodies in a plane, no gravity:
#   1 crank O-F       angle beta, pinned to the ground at O = (0, 0), driven by the torque mom
#   2 link F-E        angle beta + Theta
#   3 triangle B-D-E  angle gamma, pinned at B; the spring (c0, l0) joins D to the ground at C
#   4 link G-E        angle Phi + delta
#   5 triangle A-G    angle delta, pinned at A
#   6 link H-E        angle Omega + epsilon
#   7 triangle A-H    angle epsilon, pinned at A
# The seven angles (beta, Theta, gamma, Phi, delta, Omega, epsilon) are the coordinates; the
# point E closes three loops (six equations):
#   E = rr e(beta) - d e(beta + Theta)
#     = B + ss e(gamma - pi/2)
#     = A + zt e(delta) + e e(Phi + delta - pi/2)
#     = A + u e(epsilon - pi/2) + zf e(Omega + epsilon)
# Published values: the parameters below; the consistent initial angles; the angles at
# t = 0.03 s (the Test Set's reference, computed with PSIDE at tolerance 1e-14).

#: Parameters of the Test Set / Hairer-Wanner model (SI units: m, kg, kg m^2, N/m, N m).
ANDREWS = {
    "m1": 0.04325, "m2": 0.00365, "m3": 0.02373, "m4": 0.00706, "m5": 0.07050, "m6": 0.00706, "m7": 0.05498,
    "i1": 2.194e-6, "i2": 4.410e-7, "i3": 5.255e-6, "i4": 5.667e-7, "i5": 1.169e-5, "i6": 5.667e-7,
    "i7": 1.912e-5,
    "xa": -0.06934, "ya": -0.00227, "xb": -0.03635, "yb": 0.03273, "xc": 0.014, "yc": 0.072,
    "d": 28e-3, "da": 115e-4, "e": 2e-2, "ea": 1421e-5, "rr": 7e-3, "ra": 92e-5,
    "ss": 35e-3, "sa": 1874e-5, "sb": 1043e-5, "sc": 18e-3, "sd": 2e-2,
    "ta": 2308e-5, "tb": 916e-5, "u": 4e-2, "ua": 1228e-5, "ub": 449e-5,
    "zf": 2e-2, "zt": 4e-2, "fa": 1421e-5,
    "mom": 0.033, "c0": 4530.0, "l0": 0.07785,
}

#: Names of the seven angles, in the order of the published vectors.
ANDREWS_ANGLE_NAMES = ("beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon")

#: Consistent initial angles (rad), published with the problem; the start is at rest.
ANDREWS_INITIAL_ANGLES = np.array([
    -0.0617138900142764496358948458001,
    0.0,
    0.455279819163070380255912382449,
    0.222668390165885884674473185609,
    0.487364979543842550225598953530,
    -0.222668390165885884674473185609,
    1.23054744454982119249735015568,
])

#: Published consistent initial accelerations (rad/s^2) and multipliers (N) at t = 0
#: (convention M a + G^T lambda = f): all others are zero.
ANDREWS_INITIAL_ACCELERATIONS = np.array([14222.4439199541138705911625887, -10666.8329399655854029433719415,
                                          0.0, 0.0, 0.0, 0.0, 0.0])
ANDREWS_INITIAL_MULTIPLIERS = np.array([98.5668703962410896057654982170, -6.12268834425566265503114393122,
                                        0.0, 0.0, 0.0, 0.0])

#: The Test Set's reference solution at t = 0.03 s: the seven angles (rad).
ANDREWS_REFERENCE_TIME = 0.03
ANDREWS_REFERENCE_ANGLES = np.array([
    0.1581077119629904e2,
    -0.1575637105984298e2,
    0.4082224013073101e-1,
    -0.5347301163226948,
    0.5244099658805304,
    0.5347301163226948,
    0.1048080741042263e1,
])

#: ... and the angular velocities there (rad/s), from the same reference.
ANDREWS_REFERENCE_RATES = np.array([
    0.1139920302151208e4,
    -0.1424379294994111e4,
    0.1103291221937134e2,
    0.1929337464421385e2,
    0.5735699284790808,
    -0.1929337464421385e2,
    0.3231791658026955,
])

# The loop terms of E: (sign, length key, angle coefficients on the seven angles, phase).
_LOOP_TERMS = (
    ((1, "rr", (1, 0, 0, 0, 0, 0, 0), 0.0), (-1, "d", (1, 1, 0, 0, 0, 0, 0), 0.0)),
    ((1, "ss", (0, 0, 1, 0, 0, 0, 0), -np.pi / 2),),
    ((1, "zt", (0, 0, 0, 0, 1, 0, 0), 0.0), (1, "e", (0, 0, 0, 1, 1, 0, 0), -np.pi / 2)),
    ((1, "u", (0, 0, 0, 0, 0, 0, 1), -np.pi / 2), (1, "zf", (0, 0, 0, 0, 0, 1, 1), 0.0)),
)
_LOOP_ORIGINS = ((0.0, 0.0), ("xb", "yb"), ("xa", "ya"), ("xa", "ya"))


def _loop_vectors(angles, rates=None):
    """E along each of the four paths, and the centripetal part of its acceleration."""
    p = ANDREWS
    positions, centripetal = [], []
    for origin, terms in zip(_LOOP_ORIGINS, _LOOP_TERMS):
        point = np.array([p[origin[0]], p[origin[1]]]) if isinstance(origin[0], str) else np.zeros(2)
        inward = np.zeros(2)
        for sign, key, coefficients, phase in terms:
            angle = np.dot(coefficients, angles) + phase
            point = point + sign * p[key] * unit(angle)
            if rates is not None:
                inward = inward - sign * p[key] * unit(angle) * np.dot(coefficients, rates) ** 2
        positions.append(point)
        centripetal.append(inward)
    return positions, centripetal


def andrews_constraints(angles) -> np.ndarray:
    """g(angles), shape (6,): E by the crank path minus E by paths 3, 4 and 5 (Test Set order)."""
    positions, _ = _loop_vectors(np.asarray(angles, dtype=float))
    return np.concatenate([positions[0] - positions[k] for k in (1, 2, 3)])


def andrews_constraint_jacobian(angles) -> np.ndarray:
    """G = dg/d(angles), shape (6, 7), as published (Hairer & Wanner, eq. 7.11 ff.)."""
    p = ANDREWS
    be, th, ga, ph, de, om, ep = angles
    s_be, c_be = np.sin(be), np.cos(be)
    s_bt, c_bt = np.sin(be + th), np.cos(be + th)
    s_pd, c_pd = np.sin(ph + de), np.cos(ph + de)
    s_oe, c_oe = np.sin(om + ep), np.cos(om + ep)
    jacobian = np.zeros((6, 7))
    crank_x = (-p["rr"] * s_be + p["d"] * s_bt, p["d"] * s_bt)
    crank_y = (p["rr"] * c_be - p["d"] * c_bt, -p["d"] * c_bt)
    for row in (0, 2, 4):
        jacobian[row, :2] = crank_x
        jacobian[row + 1, :2] = crank_y
    jacobian[0, 2] = -p["ss"] * np.cos(ga)
    jacobian[1, 2] = -p["ss"] * np.sin(ga)
    jacobian[2, 3:5] = -p["e"] * c_pd, -p["e"] * c_pd + p["zt"] * np.sin(de)
    jacobian[3, 3:5] = -p["e"] * s_pd, -p["e"] * s_pd - p["zt"] * np.cos(de)
    jacobian[4, 5:7] = p["zf"] * s_oe, p["zf"] * s_oe - p["u"] * np.cos(ep)
    jacobian[5, 5:7] = -p["zf"] * c_oe, -p["zf"] * c_oe - p["u"] * np.sin(ep)
    return jacobian


def andrews_mass_matrix(angles) -> np.ndarray:
    """M(angles), shape (7, 7), as published (Hairer & Wanner)."""
    p = ANDREWS
    _, th, _, ph, _, om, _ = angles
    m = np.zeros((7, 7))
    m[0, 0] = p["m1"] * p["ra"] ** 2 + p["m2"] * (p["rr"] ** 2 - 2 * p["da"] * p["rr"] * np.cos(th) + p["da"] ** 2)
    m[0, 0] += p["i1"] + p["i2"]
    m[1, 0] = p["m2"] * (p["da"] ** 2 - p["da"] * p["rr"] * np.cos(th)) + p["i2"]
    m[1, 1] = p["m2"] * p["da"] ** 2 + p["i2"]
    m[2, 2] = p["m3"] * (p["sa"] ** 2 + p["sb"] ** 2) + p["i3"]
    lever4 = p["e"] - p["ea"]
    m[3, 3] = p["m4"] * lever4**2 + p["i4"]
    m[4, 3] = p["m4"] * (lever4**2 + p["zt"] * lever4 * np.sin(ph)) + p["i4"]
    m[4, 4] = p["m4"] * (p["zt"] ** 2 + 2 * p["zt"] * lever4 * np.sin(ph) + lever4**2)
    m[4, 4] += p["m5"] * (p["ta"] ** 2 + p["tb"] ** 2) + p["i4"] + p["i5"]
    lever6 = p["zf"] - p["fa"]
    m[5, 5] = p["m6"] * lever6**2 + p["i6"]
    m[6, 5] = p["m6"] * (lever6**2 - p["u"] * lever6 * np.sin(om)) + p["i6"]
    m[6, 6] = p["m6"] * (lever6**2 - 2 * p["u"] * lever6 * np.sin(om) + p["u"] ** 2)
    m[6, 6] += p["m7"] * (p["ua"] ** 2 + p["ub"] ** 2) + p["i6"] + p["i7"]
    return np.tril(m) + np.tril(m, -1).T


def andrews_spring_point(gamma: float) -> np.ndarray:
    """D, the spring's end on body 3: B + sd e(gamma) + sc e(gamma - pi/2)."""
    p = ANDREWS
    return np.array([p["xb"], p["yb"]]) + p["sd"] * unit(gamma) + p["sc"] * unit(gamma - np.pi / 2)


def andrews_forces(angles, rates) -> np.ndarray:
    """f(angles, rates), shape (7,): torque, velocity-product terms and the spring, as published."""
    p = ANDREWS
    be, th, ga, ph, de, om, ep = angles
    bep, thp, _, php, dep, omp, epp = rates
    spring_end = andrews_spring_point(ga)
    stretch = spring_end - np.array([p["xc"], p["yc"]])
    length = np.hypot(*stretch)
    force = -p["c0"] * (length - p["l0"]) / length * stretch
    lever4, lever6 = p["e"] - p["ea"], p["zf"] - p["fa"]
    return np.array([
        p["mom"] - p["m2"] * p["da"] * p["rr"] * thp * (thp + 2 * bep) * np.sin(th),
        p["m2"] * p["da"] * p["rr"] * bep**2 * np.sin(th),
        force @ (p["sd"] * unit(ga + np.pi / 2) + p["sc"] * unit(ga)),  # F . dD/dgamma
        p["m4"] * p["zt"] * lever4 * dep**2 * np.cos(ph),
        -p["m4"] * p["zt"] * lever4 * php * (php + 2 * dep) * np.cos(ph),
        -p["m6"] * p["u"] * lever6 * epp**2 * np.cos(om),
        p["m6"] * p["u"] * lever6 * omp * (omp + 2 * epp) * np.cos(om),
    ])


def andrews_gamma(angles, rates) -> np.ndarray:
    """gamma = -dG/dt rates, shape (6,): each term l e(alpha) of a loop contributes
    -l e(alpha) alpha'^2 to E's acceleration besides G a, so gamma is minus that difference."""
    _, centripetal = _loop_vectors(np.asarray(angles, dtype=float), np.asarray(rates, dtype=float))
    return -np.concatenate([centripetal[0] - centripetal[k] for k in (1, 2, 3)])


def andrews_relative_accelerations(angles, rates):
    """Angular accelerations and the six multipliers from [M G^T; G 0] [a; lambda] = [f; gamma]."""
    matrix = np.zeros((13, 13))
    jacobian = andrews_constraint_jacobian(angles)
    matrix[:7, :7] = andrews_mass_matrix(angles)
    matrix[:7, 7:] = jacobian.T
    matrix[7:, :7] = jacobian
    solution = np.linalg.solve(matrix, np.concatenate([andrews_forces(angles, rates), andrews_gamma(angles, rates)]))
    return solution[:7], solution[7:]


@functools.lru_cache(maxsize=4)
def _integrate_andrews(t_end: float, rtol: float):
    def rhs(_t, state):
        accelerations, _ = andrews_relative_accelerations(state[:7], state[7:])
        return np.concatenate([state[7:], accelerations])

    state0 = np.concatenate([ANDREWS_INITIAL_ANGLES, np.zeros(7)])
    solution = solve_ivp(rhs, (0.0, t_end), state0, method="DOP853", rtol=rtol, atol=rtol, dense_output=True)
    if not solution.success:
        raise RuntimeError(f"reference integration of Andrews' mechanism failed: {solution.message}")
    return solution.sol


def andrews_relative_motion(times, rtol: float = 1e-12):
    """The seven angles and their rates at `times` (s, 0 ... 0.03 or beyond), by integrating
    the published index-1 (acceleration-level) equations with DOP853 at `rtol` = atol.

    A recomputation: agrees with ANDREWS_REFERENCE_ANGLES to about 1e-9 rad (see the tests);
    use the published values for t = 0.03 s and this for other times.
    Returns ``(angles, rates)``, each of shape (n, 7).
    """
    times = np.asarray(times, dtype=float)
    dense = _integrate_andrews(float(times.max()), rtol)
    state = dense(times)
    return state[:7].T, state[7:].T


def andrews_geometry(angles=ANDREWS_INITIAL_ANGLES) -> dict:
    """Andrews' mechanism at the given seven angles, as a model in absolute coordinates.

    Body frames: each body's origin is a named point and its frame angle is the absolute angle
    of the Hairer-Wanner model, so the sparsekin body angles map back to the published angles as
    beta = a1, Theta = a2 - a1, gamma = a3, Phi = a4 - a5, delta = a5, Omega = a6 - a7,
    epsilon = a7 (``andrews_angles_from_bodies``).

    ==========  ======  ==============  ============================  ========================
    body        origin  frame angle     points                        centre of mass
    ==========  ======  ==============  ============================  ========================
    b1 crank    O       beta            O, F = O + rr e(a1)           O + ra e(a1)
    b2 link     F       beta + Theta    F, E = F - d e(a2)            F - da e(a2)
    b3 triangle B       gamma           B, D, E = B + ss e(a3 - pi/2)  B + sa e(a3) + sb e(a3 - pi/2) (*)
    b4 link     G       Phi + delta     G, E = G + e e(a4 - pi/2)     G + (e - ea) e(a4 - pi/2)
    b5 triangle A       delta           A, G = A + zt e(a5)           A + ta e(a5) + tb e(a5 + pi/2) (*)
    b6 link     H       Omega + eps     H, E = H + zf e(a6)           H + (zf - fa) e(a6)
    b7 triangle A       epsilon         A, H = A + u e(a7 - pi/2)     A + ua e(a7) + ub e(a7 + pi/2) (*)
    ==========  ======  ==============  ============================  ========================

    D = B + sd e(a3) + sc e(a3 - pi/2).  Masses m1 ... m7 and inertias i1 ... i7 (about the
    centre of mass) as published.  (*) The published model gives only the distance of these
    centres of mass from the fixed pivot (sqrt(sa^2 + sb^2), ...): they enter the equations only
    through m (sa^2 + sb^2) + i, so their direction in the body is a free choice (there is no
    gravity) and is chosen here as in the Hairer-Wanner figure's reading above.
    Joints: ten revolutes: b1-ground at O, b1-b2 at F, b3-ground at B, b5-ground at A,
    b7-ground at A, b4-b5 at G, b6-b7 at H, and b2-b3, b2-b4, b2-b6 at E.  Loads: a spring
    c0 = 4530 N/m, free length l0 = 0.07785 m, from D on b3 to the ground point C = (xc, yc);
    a torque mom = 0.033 N m on b1 (counter-clockwise, relative to the ground).  No gravity.

    Returns a dict: ``points`` {name: (x, y)}, ``bodies`` {name: {origin, angle, points, mass,
    inertia, com (x, y)}}, ``joints`` [(body_i, body_j, point)], ``spring`` {bodies, points,
    stiffness, free_length}, ``torque`` {body, value}.  E is where b2 puts it (the other three
    paths agree to round-off at consistent angles).
    """
    p = ANDREWS
    a = np.asarray(angles, dtype=float)
    frame = (a[0], a[0] + a[1], a[2], a[3] + a[4], a[4], a[5] + a[6], a[6])
    origin, pivot_a, pivot_b = np.zeros(2), np.array([p["xa"], p["ya"]]), np.array([p["xb"], p["yb"]])
    point_f = origin + p["rr"] * unit(frame[0])
    point_e = point_f - p["d"] * unit(frame[1])
    point_g = pivot_a + p["zt"] * unit(frame[4])
    point_h = pivot_a + p["u"] * unit(frame[6] - np.pi / 2)
    points = {
        "O": origin, "F": point_f, "E": point_e, "B": pivot_b, "D": andrews_spring_point(frame[2]),
        "A": pivot_a, "G": point_g, "H": point_h, "C": np.array([p["xc"], p["yc"]]),
    }
    coms = (
        origin + p["ra"] * unit(frame[0]),
        point_f - p["da"] * unit(frame[1]),
        pivot_b + p["sa"] * unit(frame[2]) + p["sb"] * unit(frame[2] - np.pi / 2),
        point_g + (p["e"] - p["ea"]) * unit(frame[3] - np.pi / 2),
        pivot_a + p["ta"] * unit(frame[4]) + p["tb"] * unit(frame[4] + np.pi / 2),
        point_h + (p["zf"] - p["fa"]) * unit(frame[5]),
        pivot_a + p["ua"] * unit(frame[6]) + p["ub"] * unit(frame[6] + np.pi / 2),
    )
    layout = (("O", ("O", "F")), ("F", ("F", "E")), ("B", ("B", "D", "E")), ("G", ("G", "E")),
              ("A", ("A", "G")), ("H", ("H", "E")), ("A", ("A", "H")))
    bodies = {
        f"b{k + 1}": {
            "origin": body_origin, "angle": float(frame[k]), "points": body_points,
            "mass": p[f"m{k + 1}"], "inertia": p[f"i{k + 1}"], "com": coms[k],
        }
        for k, (body_origin, body_points) in enumerate(layout)
    }
    joints = [("b1", "ground", "O"), ("b1", "b2", "F"), ("b3", "ground", "B"), ("b5", "ground", "A"),
              ("b7", "ground", "A"), ("b4", "b5", "G"), ("b6", "b7", "H"), ("b2", "b3", "E"),
              ("b2", "b4", "E"), ("b2", "b6", "E")]
    return {
        "points": points, "bodies": bodies, "joints": joints,
        "spring": {"bodies": ("b3", "ground"), "points": ("D", "C"), "stiffness": p["c0"], "free_length": p["l0"]},
        "torque": {"body": "b1", "value": p["mom"]},
    }


def andrews_angles_from_bodies(body_angles) -> np.ndarray:
    """The seven published angles from the seven absolute body angles a1 ... a7 (last axis)."""
    a = np.asarray(body_angles, dtype=float)
    return np.stack([a[..., 0], a[..., 1] - a[..., 0], a[..., 2], a[..., 3] - a[..., 4], a[..., 4],
                     a[..., 5] - a[..., 6], a[..., 6]], axis=-1)


def andrews_system(geometry: dict | None = None):
    """andrews_geometry as a PlanarSystem (centre-of-mass coordinates), at rest: ``(system, q0)``.

    Built from the geometry alone (points, centres of mass, masses, inertias, joints, spring,
    torque), not from the published equations: integrating it and comparing with the published
    angles checks the geometry that the sparsekin model file states.
    """
    geometry = andrews_geometry() if geometry is None else geometry
    names = list(geometry["bodies"])
    q0 = np.zeros(3 * len(names))
    for k, name in enumerate(names):
        q0[3 * k : 3 * k + 3] = *geometry["bodies"][name]["com"], geometry["bodies"][name]["angle"]

    def offset(name, point):
        k = names.index(name)
        body_to_global = rotation(q0[3 * k + 2])
        return k, body_to_global.T @ (np.asarray(geometry["points"][point]) - q0[3 * k : 3 * k + 2])

    revolutes = []
    for body_i, body_j, point in geometry["joints"]:
        k_i, s_i = offset(body_i, point)
        k_j, s_j = (-1, np.asarray(geometry["points"][point])) if body_j == "ground" else offset(body_j, point)
        revolutes.append((k_i, s_i, k_j, s_j))
    spring = geometry["spring"]
    k_spring, s_spring = offset(spring["bodies"][0], spring["points"][0])
    system = PlanarSystem(
        masses=np.array([geometry["bodies"][n]["mass"] for n in names]),
        inertias=np.array([geometry["bodies"][n]["inertia"] for n in names]),
        revolutes=tuple(revolutes),
        springs=((k_spring, s_spring, geometry["points"][spring["points"][1]], spring["stiffness"],
                  spring["free_length"]),),
        torques=((names.index(geometry["torque"]["body"]), geometry["torque"]["value"]),),
    )
    return system, q0
