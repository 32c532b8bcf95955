"""The forward-dynamics references (tests/dynamics_reference.py) checked against themselves by
independent routes: closed forms against ODE integrations, reduced models against the full
Lagrange-multiplier equations, published equations against the geometry, energy balances.

None of this touches sparsekin; the integrator's tests compare sparsekin against these.
"""

import dense_planar_dae as dae
import dynamics_reference as ref
import numpy as np
import pytest
from scipy.integrate import solve_ivp

# --- A01: simple pendulum ---------------------------------------------------------------------


def test_pendulum_period_tends_to_the_small_amplitude_period_as_the_series_says():
    small = 2 * np.pi * np.sqrt(1.0 / ref.GRAVITY)
    for amplitude in (1e-3, 0.1, 0.3):
        series = small * (1 + amplitude**2 / 16 + 11 * amplitude**4 / 3072)  # next term ~ amplitude^6
        assert ref.pendulum_period(1.0, amplitude) == pytest.approx(series, rel=amplitude**6)
    # A01 released horizontal: 18 % longer than the small-amplitude period (K(1/2) / (pi/2))
    assert ref.pendulum_period() / small == pytest.approx(1.1803405990161, rel=1e-12)


def test_pendulum_angle_turns_at_the_period_marks_and_conserves_energy():
    period = ref.pendulum_period()
    angle, rate = ref.pendulum_angle([0.0, period / 4, period / 2, 3 * period / 4, period])
    np.testing.assert_allclose(angle, [np.pi / 2, 0.0, -np.pi / 2, 0.0, np.pi / 2], atol=1e-12)
    assert abs(rate[0]) < 1e-12 and abs(rate[2]) < 1e-12 and rate[1] < 0 < rate[3]
    times = np.linspace(0.0, 10.0, 2001)
    angle, rate = ref.pendulum_angle(times)
    energy = ref.pendulum_energy(angle, rate)
    assert np.abs(energy - energy[0]).max() < 1e-12 * ref.GRAVITY
    # rate is the derivative of angle (central differences, error ~ h^2 theta''' / 6)
    h = 1e-5
    plus, _ = ref.pendulum_angle(times + h)
    minus, _ = ref.pendulum_angle(times - h)
    np.testing.assert_allclose((plus - minus) / (2 * h), rate, atol=1e-8)


def test_pendulum_path_matches_an_integration_of_the_equation_of_motion_over_the_benchmark_10_s():
    times = np.linspace(0.0, 10.0, 1001)
    position, velocity = ref.pendulum_point(times)
    solution = solve_ivp(
        lambda _t, y: [y[1], -ref.GRAVITY * np.sin(y[0])],
        (0, 10),
        [np.pi / 2, 0.0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
        t_eval=times,
    )
    integrated = np.stack([np.sin(solution.y[0]), -np.cos(solution.y[0])], axis=1)
    assert np.abs(position - integrated).max() < 1e-9  # the benchmark's bound is 1e-3 m
    np.testing.assert_allclose(position[0], [1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.hypot(*position.T), 1.0, rtol=1e-14)
    assert np.abs(np.einsum("ij,ij->i", position, velocity)).max() < 1e-12  # velocity tangent


# --- A02: N-four-bar ----------------------------------------------------------------------------

TIMES_A02 = np.linspace(0.0, 20.0, 401)  # the benchmark's outputs


@pytest.mark.parametrize("n_loops", [1, 40, 1000, 100_000])
def test_n_four_bar_conserves_energy_and_follows_the_closed_form_time_of_every_angle(n_loops):
    motion = ref.n_four_bar_motion(TIMES_A02, n_loops=n_loops)
    kinetic, potential = ref.n_four_bar_energy(motion.angle, motion.rate, n_loops=n_loops)
    energy = kinetic + potential
    assert np.abs(energy - energy[0]).max() < 1e-11 * abs(energy[0])
    # The time to reach each computed angle, from the elliptic integral F(psi/2 | m < 0)
    np.testing.assert_allclose(motion.constants.time_at_angle(motion.angle), TIMES_A02, atol=1e-9)
    one_turn = ref.n_four_bar_motion([motion.constants.revolution_period], n_loops=n_loops)
    assert one_turn.angle[0] == pytest.approx(np.pi / 2 - 2 * np.pi, abs=1e-10)


def test_n_four_bar_benchmark_crosses_the_flat_position_20_times_in_20_s():
    motion = ref.n_four_bar_motion(TIMES_A02)
    flat_crossings = np.floor((np.pi / 2 - motion.angle[-1]) / np.pi)
    assert flat_crossings == 20
    assert np.all(np.diff(motion.angle) < 0)  # the cranks circulate clockwise throughout
    position, velocity = ref.n_four_bar_b0(TIMES_A02)
    np.testing.assert_allclose(position[0], [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(velocity[0], [1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.hypot(*position.T), 1.0, rtol=1e-14)


@pytest.mark.parametrize("n_loops", [1, 2])
def test_n_four_bar_reduced_model_agrees_with_the_full_lagrange_multiplier_equations(n_loops):
    """The reduced ODE against all 2N + 1 bars integrated in absolute coordinates, on the two
    stretches between flat positions (the dense saddle-point matrix is singular where the
    windows are flat): from the start to theta = 0.2 and from theta = -0.2 to -pi + 0.2."""
    system, state = ref.n_four_bar_system(n_loops)
    constants = ref.n_four_bar_constants(n_loops)
    for start, stop in ((np.pi / 2, 0.2), (-0.2, -np.pi + 0.2)):
        times = np.linspace(constants.time_at_angle(start), constants.time_at_angle(stop), 11)
        motion = ref.n_four_bar_motion(times, n_loops=n_loops)
        q0, v0 = state(motion.angle[0], motion.rate[0])
        assert np.abs(dae.planar_constraints(system, q0)[0]).max() < 1e-15
        q, v, drift = dae.integrate_planar_dae(system, q0, v0, times)
        assert drift.max() < 1e-10
        cranks = slice(2, 3 * (n_loops + 1), 3)
        np.testing.assert_allclose(q[:, cranks], np.repeat(motion.angle[:, None], n_loops + 1, 1), atol=1e-10)
        np.testing.assert_allclose(v[:, cranks], np.repeat(motion.rate[:, None], n_loops + 1, 1), atol=1e-10)
        np.testing.assert_allclose(q[:, 3 * (n_loops + 1) + 2 :: 3], 0.0, atol=1e-10)  # couplers translate
        energy = [dae.planar_energy(system, q[k], v[k]) for k in range(len(times))]
        kinetic, potential = ref.n_four_bar_energy(motion.angle[0], motion.rate[0], n_loops=n_loops)
        np.testing.assert_allclose(energy, kinetic + potential, rtol=1e-10)


def test_dense_constraint_jacobian_and_gamma_match_finite_differences(rng):
    system, state = ref.n_four_bar_system(2)
    q, v = state(0.7, -1.3)
    q, v = q + 0.01 * rng.standard_normal(q.size), rng.standard_normal(v.size)  # off the manifold
    residual, jacobian, gamma = dae.planar_constraints(system, q, v)
    h = 1e-6
    columns = [
        (dae.planar_constraints(system, q + h * e)[0] - dae.planar_constraints(system, q - h * e)[0])
        / (2 * h)
        for e in np.eye(q.size)
    ]
    np.testing.assert_allclose(np.array(columns).T, jacobian, atol=1e-9)
    h = 1e-4  # d^2/ds^2 Phi(q + s v) = -gamma (no acceleration)
    second = (
        dae.planar_constraints(system, q + h * v)[0]
        - 2 * residual
        + dae.planar_constraints(system, q - h * v)[0]
    )
    np.testing.assert_allclose(second / h**2, -gamma, atol=1e-6)


# --- A03: Andrews' squeezing mechanism ------------------------------------------------------------


def test_andrews_published_initial_state_is_consistent_with_the_transcribed_equations():
    assert np.abs(ref.andrews_constraints(ref.ANDREWS_INITIAL_ANGLES)).max() < 1e-16
    accelerations, multipliers = ref.andrews_relative_accelerations(ref.ANDREWS_INITIAL_ANGLES, np.zeros(7))
    np.testing.assert_allclose(accelerations, ref.ANDREWS_INITIAL_ACCELERATIONS, rtol=1e-14, atol=1e-10)
    np.testing.assert_allclose(multipliers, ref.ANDREWS_INITIAL_MULTIPLIERS, rtol=1e-13, atol=1e-12)


def test_andrews_jacobian_and_gamma_match_finite_differences_of_the_loop_equations(rng):
    angles = ref.ANDREWS_REFERENCE_ANGLES + 0.05 * rng.standard_normal(7)
    rates = 100 * rng.standard_normal(7)
    h = 1e-7
    columns = [
        (ref.andrews_constraints(angles + h * e) - ref.andrews_constraints(angles - h * e)) / (2 * h)
        for e in np.eye(7)
    ]
    np.testing.assert_allclose(np.array(columns).T, ref.andrews_constraint_jacobian(angles), atol=1e-9)

    def second_difference(s):  # d^2/ds^2 g(angles + s rates) = -gamma (no acceleration)
        return (
            ref.andrews_constraints(angles + s * rates)
            - 2 * ref.andrews_constraints(angles)
            + ref.andrews_constraints(angles - s * rates)
        ) / s**2

    s = 1e-3 / np.abs(rates).max()
    richardson = (4 * second_difference(s / 2) - second_difference(s)) / 3
    gamma = ref.andrews_gamma(angles, rates)
    np.testing.assert_allclose(richardson, -gamma, atol=1e-7 * np.abs(gamma).max())


def test_andrews_recomputation_meets_the_published_solution_at_30_ms():
    angles, rates = ref.andrews_relative_motion([0.0, ref.ANDREWS_REFERENCE_TIME])
    np.testing.assert_allclose(angles[-1], ref.ANDREWS_REFERENCE_ANGLES, atol=1e-8)
    np.testing.assert_allclose(rates[-1], ref.ANDREWS_REFERENCE_RATES, rtol=1e-8, atol=1e-5)
    assert np.abs(ref.andrews_constraints(angles[-1])).max() < 1e-12


def test_andrews_geometry_closes_its_loops_and_reproduces_the_published_solution():
    """The model stated as points, bodies, masses, inertias, joints, spring and torque (what the
    sparsekin file says), integrated in absolute coordinates: the published angles at 30 ms.
    Also: the energy balance, kinetic + spring = work of the torque."""
    geometry = ref.andrews_geometry(ref.ANDREWS_REFERENCE_ANGLES)
    p = ref.ANDREWS
    for name, path in (("b3", ("B", p["ss"])), ("b4", ("G", p["e"])), ("b6", ("H", p["zf"]))):
        assert np.hypot(*(geometry["points"]["E"] - geometry["points"][path[0]])) == pytest.approx(
            path[1], rel=1e-12
        )
    system, q0 = ref.andrews_system()
    assert np.abs(dae.planar_constraints(system, q0)[0]).max() < 1e-16
    times = [0.0, 0.01, ref.ANDREWS_REFERENCE_TIME]
    q, v, drift = dae.integrate_planar_dae(system, q0, np.zeros_like(q0), times, rtol=1e-11, atol=1e-11)
    assert drift[:, 0].max() < 1e-12
    angles = ref.andrews_angles_from_bodies(q[-1, 2::3])
    np.testing.assert_allclose(angles, ref.ANDREWS_REFERENCE_ANGLES, atol=1e-8)
    torque_work = p["mom"] * (q[:, 2] - q0[2])
    energy = np.array([dae.planar_energy(system, q[k], v[k]) for k in range(len(times))]) - torque_work
    np.testing.assert_allclose(energy, energy[0], atol=1e-9 * torque_work[-1])
