"""Forward dynamics against exact and published references (issue 25).

* A01 (pendulum released horizontal): the period against the complete elliptic integral,
  the point's path against the Jacobi elliptic solution, the energy error ∝ h² and bounded
  over 10^4 steps without numerical damping, no constraint drift;
* A02 (N-four-bar): through its singular crossings on the exact one-parameter family (every
  crank at the angle of the reduced ODE), B0's error falling as h² through them with and
  without numerical damping;
* A03 (Andrews' squeezing mechanism): the published angles at t = 0.03 s, second-order
  convergence towards them;
* the round trip with inverse dynamics: Task 5's driver forces from `solve_kinematics`,
  applied as actuator spline loads with the drivers removed, give the motion back, the error
  falling as h²;
* a redundant model's multipliers: the minimum-norm ones (the pseudo-inverse's);
* a loose tolerance (the drift bound then decides where the projections act): the drift
  within its bound at every sample, B0 and the energy error still falling as h²;
* errors in one line, the command line's energy.csv.

The references (tests/dynamics_reference.py) are closed forms, SciPy integrations of the
reduced equations, and the Test Set's published values; none uses sparsekin.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from dynamics_reference import (
    ANDREWS_REFERENCE_ANGLES,
    andrews_angles_from_bodies,
    n_four_bar_b0,
    n_four_bar_motion,
    pendulum_period,
    pendulum_point,
)
from helpers import actuator_round_trip

import sparsekin as sk
from sparsekin.engine.discretization import discretize
from sparsekin.results.schema import DRIFT
from sparsekin.solve.dynamics import GeneralizedAlphaStepper, run_dynamics
from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions
from sparsekin.solve.policy import Thresholds
from sparsekin.testset import n_four_bar

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def pendulum():
    return sk.load_model(EXAMPLES / "dynamics" / "pendulum.toml")


@pytest.fixture(scope="module")
def pendulum_runs(pendulum):
    """10 s of A01 without numerical damping at 1 ms (10^4 steps) and 2 ms."""
    times = np.linspace(0.0, 10.0, 5001)
    return {h: sk.solve_dynamics(pendulum, times, max_step=h, rho_inf=1.0) for h in (1e-3, 2e-3)}


def test_pendulum_period_is_the_elliptic_integral(pendulum_runs):
    result = pendulum_runs[1e-3]
    rate = result.velocities[:, 2]
    # the angular velocity is zero at every half period: linear interpolation between samples
    k = np.flatnonzero(np.sign(rate[1:]) != np.sign(rate[:-1]))
    k = k[rate[k] != 0.0]
    crossings = result.times[k] - rate[k] * (result.times[k + 1] - result.times[k]) / (rate[k + 1] - rate[k])
    half_periods = np.diff(np.concatenate([[0.0], crossings]))
    assert half_periods.size >= 8
    np.testing.assert_allclose(2.0 * half_periods, pendulum_period(), rtol=0, atol=2e-5)


def test_pendulum_path_within_the_benchmarks_high_precision(pendulum_runs):
    result = pendulum_runs[1e-3]
    position, velocity = pendulum_point(result.times)
    motion = result.point("P")
    assert np.abs(motion.position - position).max() <= 1e-3  # IFToMM A01 "high precision", m
    assert np.abs(motion.velocity - velocity).max() <= 1e-2


def test_energy_error_falls_as_h_squared_and_stays_bounded(pendulum_runs):
    fine, coarse = (np.abs(pendulum_runs[h].energy.balance) for h in (1e-3, 2e-3))
    ratio = coarse.max() / fine.max()
    assert 3.5 < ratio < 4.5  # second order
    half = fine.size // 2
    assert fine[half:].max() <= 1.2 * fine[:half].max()  # no growth over 10^4 steps
    assert fine.max() <= 2e-5 * 9.81  # J, against the pendulum's energy range m g L


def test_no_drift_of_positions_or_velocities(pendulum_runs):
    energy = pendulum_runs[1e-3].energy
    assert energy.drift_position.max() <= 1e-10
    assert energy.drift_velocity.max() <= 1e-10


def test_n_four_bar_keeps_every_crank_on_the_exact_motion_through_singular_crossings():
    """A02 with N = 4 (the reduced ODE is exact at every N): 5 s, five flat crossings."""
    times = np.linspace(0.0, 5.0, 101)
    result = sk.solve_dynamics(n_four_bar(4), times, max_step=1e-3, forces=None)
    motion = n_four_bar_motion(times, n_loops=4)
    q = result.coordinates
    cranks = q[:, [2, *range(5, q.shape[1], 6)]]  # crank0, then each copy's crank
    assert np.sum(np.diff(np.floor(motion.angle / np.pi)) != 0) == 5
    np.testing.assert_allclose(cranks - motion.angle[:, None], 0.0, atol=1e-3)
    assert np.ptp(cranks, axis=1).max() <= 1e-9  # every crank at the same angle throughout
    position, _ = n_four_bar_b0(times, n_loops=4)
    b0 = result.point("B0")
    assert np.abs(b0.position - position).max() <= 1e-3
    assert result.energy.drift_position.max() <= 1e-9


def n_four_bar_b0_errors(n_loops: int, t_end: float, steps, rho_inf: float):
    """B0's largest position and velocity errors against the exact motion, per step size."""
    times = np.linspace(0.0, t_end, int(round(t_end / 0.05)) + 1)
    position, velocity = n_four_bar_b0(times, n_loops=n_loops)
    errors = []
    for h in steps:
        b0 = sk.solve_dynamics(n_four_bar(n_loops), times, max_step=h, rho_inf=rho_inf, forces=None).point("B0")
        errors.append((np.abs(b0.position - position).max(), np.abs(b0.velocity - velocity).max()))
    return np.array(errors)


@pytest.mark.parametrize("rho_inf", [0.9, 1.0])
def test_n_four_bar_error_falls_as_h_squared_through_singular_crossings(rho_inf):
    """A02 with N = 4 over 1.5 s (two flat crossings, 0.71 s and 1.23 s): B0's error falls by
    4 at each halving of the step down to 0.25 ms, with and without numerical damping.
    Newton errors of a bound per step that did not shrink with h added up to an error that
    fell by 4.66 and 4.91 instead at the last halving (a floor below which the 20 s error
    did not fall)."""
    assert np.sum(np.diff(np.floor(n_four_bar_motion(np.linspace(0.0, 1.5, 31), n_loops=4).angle / np.pi)) != 0) == 2
    errors = n_four_bar_b0_errors(4, 1.5, (1e-3, 5e-4, 2.5e-4), rho_inf)
    np.testing.assert_allclose(errors[:-1] / errors[1:], 4.0, rtol=0.05)
    assert errors[0, 0] <= 2e-5  # m, B0's position at 1 ms (1.7e-5)


def test_n_four_bar_without_numerical_damping_passes_every_crossing():
    """ρ∞ = 1 (no damping) through the first four crossings at 0.5 ms: the index-3
    multipliers' undamped (−1)ⁿ oscillation, amplified where Φq loses rank, stopped this
    run at the fourth (3.19 s) before the accelerations were projected."""
    errors = n_four_bar_b0_errors(4, 3.5, (5e-4,), 1.0)
    assert errors[0, 0] <= 1.2e-5 and errors[0, 1] <= 8e-5  # m, m/s (9.9e-6, 6.7e-5)


def test_andrews_mechanism_converges_to_the_published_angles():
    mechanism = sk.load_model(EXAMPLES / "dynamics" / "andrews.toml")
    errors = []
    for h in (2e-5, 1e-5):
        result = sk.solve_dynamics(mechanism, [0.0, 0.03], max_step=h, forces=None)
        errors.append(np.abs(andrews_angles_from_bodies(result.coordinates[-1, 2::3]) - ANDREWS_REFERENCE_ANGLES).max())
    assert 3.5 < errors[0] / errors[1] < 4.5  # second order
    assert errors[1] <= 1.5e-4


@pytest.fixture(scope="module")
def task5_round_trip():
    """Task 5 with masses: its driver forces (inverse dynamics) as actuator loads, drivers removed."""
    free, kinematic = actuator_round_trip(horizon=0.3, sampling=1e-3)
    return kinematic, free


def test_round_trip_with_inverse_dynamics_comes_back_as_h_squared(task5_round_trip):
    kinematic, free = task5_round_trip
    times = kinematic.times[::10]
    errors = []
    for h in (2e-3, 1e-3, 5e-4):
        result = sk.solve_dynamics(free, times, max_step=h)
        errors.append(np.abs(result.coordinates - kinematic.coordinates[::10]).max())
    assert errors[-1] <= 1e-8
    np.testing.assert_allclose(np.array(errors[:-1]) / np.array(errors[1:]), 4.0, rtol=0.05)


def test_drivers_are_prescribed_motions_whose_forces_match_inverse_dynamics():
    """Task 5 with its drivers: no degree of freedom left, the dynamic run is the kinematic
    one and its multipliers are the inverse-dynamics forces."""
    mechanism = sk.load_model(EXAMPLES / "task5_dynamics.toml")
    times = np.linspace(0.0, 0.2, 11)
    kinematic = sk.solve_kinematics(mechanism, times)
    dynamic = sk.solve_dynamics(mechanism, times, max_step=1e-3)
    np.testing.assert_allclose(dynamic.coordinates, kinematic.coordinates, rtol=0, atol=1e-9)
    force = kinematic.driver_force("cylinder1").force
    np.testing.assert_allclose(dynamic.driver_force("cylinder1").force, force, rtol=1e-5, atol=1e-5 * np.abs(force).max())
    balance = dynamic.energy.balance
    assert np.abs(balance).max() <= 1e-3 * np.abs(dynamic.energy.work).max()


# ------------------------------------------------------------------ errors and the command line
MISTAKES = {
    "actuator on an unknown joint": ('[[loads]]\ntype = "actuator"\njoint = "nope"\nvalue = 1.0',
                                     r'loads\[1\]\.joint: unknown joint "nope"'),
    "actuator on a revolute without a name": ('[[loads]]\ntype = "actuator"\nvalue = 1.0',
                                              r'loads\[1\]: missing key "joint"'),
    "negative rotational stiffness": ('[[loads]]\ntype = "rotational_spring"\nbodies = ["c1", "c2"]\nstiffness = -2.0',
                                      r"loads\[1\]\.stiffness"),
}


@pytest.mark.parametrize("case", MISTAKES)
def test_a_mistake_in_a_dynamics_load_is_one_line(tmp_path, case):
    table, message = MISTAKES[case]
    text = (EXAMPLES / "task5_dynamics.toml").read_text(encoding="utf-8").replace("[analysis]", f"{table}\n\n[analysis]")
    (tmp_path / "model.toml").write_text(text, encoding="utf-8")
    with pytest.raises(sk.ModelError, match=message) as error:
        sk.load_model(tmp_path / "model.toml")
    assert "\n" not in str(error.value)


@pytest.mark.parametrize(("line", "message"), [('type = "statics"', r'analysis\.type: expected one of "kinematics", '
                                                                     r'"dynamics"'),
                                                ("max_step = 0.0", r"analysis\.max_step: expected max_step > 0")])
def test_a_mistake_in_the_analysis_is_one_line(tmp_path, line, message):
    text = (EXAMPLES / "task5_dynamics.toml").read_text(encoding="utf-8").replace("[analysis]", f"[analysis]\n{line}")
    (tmp_path / "model.toml").write_text(text, encoding="utf-8")
    with pytest.raises(sk.ModelError, match=message):
        sk.load_model(tmp_path / "model.toml")


def test_a_body_velocity_needs_three_numbers():
    with pytest.raises(sk.ModelError, match=r"velocity: expected \[vx, vy, angular velocity\]"):
        sk.Body("b", origin=(0.0, 0.0), velocity=(1.0, 2.0))


def test_a_massless_free_body_is_named(pendulum):
    free = dataclasses.replace(pendulum, bodies=[dataclasses.replace(pendulum.bodies[0], mass=None)])
    with pytest.raises(sk.ModelError, match="the motion is not determined.*massless bodies: pendulum"):
        sk.solve_dynamics(free, [0.0, 0.1])


def test_run_dynamics_writes_energy_csv(tmp_path):
    from sparsekin.cli import main

    status = main(["run", str(EXAMPLES / "dynamics" / "pendulum.toml"), "--t-end", "0.5", "--steps", "11",
                   "--max-step", "0.005", "--out", str(tmp_path), "--quiet"])  # fmt: skip
    assert status == 0
    lines = (tmp_path / "energy.csv").read_text(encoding="utf-8").splitlines()
    assert lines[0] == "t,kinetic,potential,elastic,dissipated,work,balance,drift_position,drift_velocity"
    assert len(lines) == 12
    kinetic, potential = (float(value) for value in lines[-1].split(",")[1:3])
    assert kinetic > 1.0 and abs(kinetic + potential) < 1e-3  # released from rest at zero potential
    for name in ("points.csv", "joints.csv", "forces.csv"):
        assert (tmp_path / name).exists()


def test_max_step_without_dynamics_is_refused(tmp_path, capsys):
    from sparsekin.cli import main

    status = main(["run", str(EXAMPLES / "task5_dynamics.toml"), "--max-step", "0.01", "--out", str(tmp_path)])
    assert status != 0
    assert "--max-step is for forward dynamics" in capsys.readouterr().err


def test_an_actuator_takes_its_share_of_the_inverse_dynamics_force():
    """A kinematic run with an actuator along a driven joint: the driver holds the motion with
    the actuator's force less (the actuator's work counted once, by the load)."""
    mechanism = sk.load_model(EXAMPLES / "task5_dynamics.toml")
    helped = dataclasses.replace(mechanism, loads=[*mechanism.loads, sk.Actuator("actuator1", 150.0)])
    times = np.linspace(0.0, 0.5, 6)
    alone, with_actuator = (sk.solve_kinematics(m, times).driver_force("cylinder1").force for m in (mechanism, helped))
    np.testing.assert_allclose(with_actuator, alone - 150.0, rtol=0, atol=1e-8 * np.abs(alone).max())


def _tower(redundant: bool) -> sk.Mechanism:
    """Three parallelogram cells released under gravity, the first cell's bars turning: with
    a massless third bar per cell (one redundant equation each), or without it."""
    from sparsekin.testset import parallel_bar_chain

    tower = parallel_bar_chain(3, bars=3)
    bodies = []
    for body in tower.bodies:
        if body.name.startswith("b"):
            if redundant:
                bodies.append(body)  # massless: the motion is that of the tower without it
        elif body.name.startswith("p"):
            bodies.append(dataclasses.replace(body, mass=2.0, inertia=0.2, com=body.points[1]))
        else:
            x, y = tower.position(body.points[0])
            turning = (0.0, 0.0, -0.5) if body.name in ("a0", "c0") else None
            bodies.append(dataclasses.replace(body, mass=1.0, inertia=1.0 / 12.0, com=(x, y + 0.5), velocity=turning))
    kept = {body.name for body in bodies} | {"ground"}
    joints = [joint for joint in tower.joints if set(joint.bodies) <= kept]
    return dataclasses.replace(tower, bodies=bodies, joints=joints, drivers=[], gravity=(0.0, -9.81))


def test_redundant_equations_are_left_out_and_change_nothing():
    times = np.linspace(0.0, 1.0, 11)
    with pytest.warns(sk.RedundantConstraintWarning, match="3 redundant equations"):
        redundant = sk.solve_dynamics(_tower(True), times, max_step=1e-3, forces=None)
    plain = sk.solve_dynamics(_tower(False), times, max_step=1e-3, forces=None)
    assert len(redundant.redundant_equations) == 3 and plain.redundant_equations == ()
    names = redundant.mechanism.body_names
    both = [names.index(name) for name in plain.mechanism.body_names]
    moved = redundant.coordinates.reshape(times.size, -1, 3)[:, both]
    assert np.abs(plain.coordinates[-1] - plain.coordinates[0]).max() > 1.0  # the tower fell
    np.testing.assert_allclose(moved.reshape(times.size, -1), plain.coordinates, rtol=0, atol=1e-9)
    assert redundant.energy.drift_position.max() <= 1e-10


def test_redundant_multipliers_are_the_minimum_norm_ones():
    """The tower's three massless third bars are left out of the integration (λ = 0 there);
    the published λ has the same constraint forces Φqᵀλ and is the minimum-norm one, the
    pseudo-inverse's (an SVD of the whole Φq, independent of the code's normal equations)."""
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper

    stepper = GeneralizedAlphaStepper(_tower(True), 1e-3)
    with pytest.warns(sk.RedundantConstraintWarning, match="the minimum-norm ones are given"):
        stepper.start(0.0)
    stepper.advance(0.2)
    integrated, published = stepper.state.multipliers, stepper.linearization().multipliers
    jacobian = stepper.assembler.jacobian.toarray()
    forces = jacobian.T @ integrated
    assert stepper.redundant_rows.size == 3 and np.all(integrated[stepper.redundant_rows] == 0.0)
    np.testing.assert_allclose(jacobian.T @ published, forces, rtol=0, atol=1e-10 * np.abs(forces).max())
    expected = np.linalg.pinv(jacobian.T) @ forces
    np.testing.assert_allclose(published, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    assert np.linalg.norm(published) < 0.99 * np.linalg.norm(integrated)
    assert np.abs(published[stepper.redundant_rows]).min() > 1e-2 * np.abs(published).max()  # the third bars take load


def test_kept_equations_are_every_equation_but_the_redundant_ones():
    """The saddle's kept equations: ascending, each once, none of the redundant ones (given in
    any order, repeated or not), what a set difference gives; and the tower's system holds them."""
    from sparsekin.engine.reduced import kept_equations
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper

    rng = np.random.default_rng(7)
    for m, redundant in [(0, []), (5, []), (5, [4, 0]), (9, [3, 3, 8]), (40, rng.integers(0, 40, 12))]:
        redundant = np.asarray(redundant, dtype=np.int64)
        kept = kept_equations(m, redundant)
        assert kept.dtype == np.int64
        assert kept.tolist() == sorted(set(range(m)) - set(redundant.tolist()))
    stepper = GeneralizedAlphaStepper(_tower(True), 1e-3)
    with pytest.warns(sk.RedundantConstraintWarning):
        stepper.start(0.0)
    assert stepper.system.kept_rows.tolist() == sorted(set(range(stepper.pattern.n_equations))
                                                       - set(stepper.redundant_rows.tolist()))
    assert stepper.system.size == stepper.pattern.n_coordinates + stepper.pattern.n_equations - 3


def test_energy_and_drift_are_recorded_variables_streamed_bit_for_bit(pendulum, tmp_path):
    """The energy balance and drift are rows of the schema: a run streamed to Zarr holds
    them labelled, equal to the run in memory."""
    xarray = pytest.importorskip("xarray", reason='the Zarr test needs "sparsekin[zarr]"')
    from sparsekin.results.schema import DRIFT_TERMS, ENERGY_TERMS

    times = np.linspace(0.0, 0.2, 21)
    memory = sk.solve_dynamics(pendulum, times, max_step=1e-3)
    streamed = sk.solve_dynamics(pendulum, times, max_step=1e-3, store=tmp_path / "run.zarr")
    for name in (*ENERGY_TERMS, "drift_position", "drift_velocity"):
        np.testing.assert_array_equal(getattr(streamed.energy, name), getattr(memory.energy, name))
    dataset = xarray.open_zarr(tmp_path / "run.zarr")
    assert list(dataset["energy"].coords["energy_term"].values) == list(ENERGY_TERMS)
    assert list(dataset["drift"].coords["drift_term"].values) == list(DRIFT_TERMS)
    np.testing.assert_array_equal(memory.to_xarray()["energy"].values, dataset["energy"].values)
    assert memory.energy.balance[0] == 0.0


def test_the_saddle_plan_changes_the_linear_solver_not_the_motion(pendulum):
    from sparsekin.engine.discretization import discretize
    from sparsekin.solve.dynamics import run_dynamics
    from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions
    from sparsekin.solve.policy import Thresholds

    times = np.linspace(0.0, 0.2, 21)
    dense = run_dynamics(discretize(pendulum), times, SolveOptions(1e-10), DynamicsOptions(1e-3), Request(energy=True))
    sparse_options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
    sparse = run_dynamics(discretize(pendulum), times, sparse_options, DynamicsOptions(1e-3), Request(energy=True))
    assert (dense.linear_solver, sparse.linear_solver) == ("dense", "refactor")
    # the same integrator to the Newton tolerance (1e-10 relative, 1 m pendulum)
    np.testing.assert_allclose(sparse.coordinates, dense.coordinates, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize(("keywords", "message"), [
    ({"rho_inf": 1.5}, r"`rho_inf` must be a number in \[0, 1\], got 1.5"),
    ({"max_step": 0.0}, "`max_step` must be a positive number, got 0.0"),
])
def test_dynamics_options_are_checked_once(pendulum, keywords, message):
    with pytest.raises(ValueError, match=message):
        sk.solve_dynamics(pendulum, [0.0, 0.1], **keywords)


@pytest.mark.parametrize("path", ["default", "refactor"])
def test_n_four_bar_at_a_loose_tolerance_keeps_its_drift_bound_and_falls_as_h_squared(path):
    """A tolerance at which the drift bound decides (1e-3 on N = 4, 1.5 s, two flat crossings:
    the projections act on about 60 % of the steps and leave up to 0.97 of the bound at 1 ms):
    the velocity drift at every sample within the step's bound, tolerance · h · max(1, ‖q̇‖)
    (the cranks' rate; lengths over the model size), the positions still on Φ = 0, and B0's
    position and velocity errors and the energy error still falling by 4 at each halving —
    30 % and 46 % above the default tolerance's (2.20e-5 against 1.69e-5 m, 5.9e-4 against
    4.0e-4 of the initial kinetic energy at 1 ms; docs/dynamics-theory.md, "What the tolerance
    buys"). Not every loose tolerance keeps the fall: at 1e-4 (projections on 92–96 % of the
    steps) it is 3.9 at the last halving, which steps project changing with h."""
    tolerance = 1e-3
    times = np.linspace(0.0, 1.5, 31)
    position, velocity = n_four_bar_b0(times, n_loops=4)
    dense_max = {"default": None, "refactor": 0}[path]
    errors = []
    for h in (1e-3, 5e-4, 2.5e-4):
        result = _loose_run(times, h, tolerance, dense_max)
        b0 = result.point("B0")
        energy = result.energy
        errors.append((np.abs(b0.position - position).max(), np.abs(b0.velocity - velocity).max(),
                       np.abs(energy.balance).max() / energy.kinetic[0]))  # fmt: skip
        bound = tolerance * h * np.maximum(1.0, np.abs(result.velocities[:, 2::3]).max(axis=1))
        assert np.all(energy.drift_velocity <= bound)
        if h == 1e-3:
            assert (energy.drift_velocity / bound).max() > 0.5  # the bound decides (0.97)
        assert energy.drift_position.max() <= tolerance * h * h
    errors = np.array(errors)
    np.testing.assert_allclose(errors[:-1] / errors[1:], 4.0, rtol=0.05)
    assert errors[0, 0] <= 2.5e-5 and errors[0, 1] <= 1.6e-4  # m, m/s at 1 ms (2.20e-5, 1.39e-4)


def test_n_four_bar_chain_at_loose_tolerances_passes_its_flat_crossing():
    """The 201-body chain (100 loops, the large path: a held matrix) at tolerances 1e-2 to
    1e-4, 1 s through the flat crossing at 0.72 s, in steps of 1 and 0.5 ms, with the drift
    promise kept.  The acceleration projection opens at stability's target
    (`ACCELERATION_TOLERANCE`), however loose the tolerance: opened at the tolerance's it fell
    silent, λ's undamped (−1)ⁿ oscillation grew through 1/σ and Newton failed at the crossing
    (here 18, 14 and 3 halvings at 1 ms, 22, 12 and 11 at 0.5 ms; the 10^4-body chain at 1e-6
    in 0.5 ms steps stopped, and so does the 1001-body chain at 1e-2).  Now none at 1e-4, and
    at most 2 where Newton itself stops at 1e-3 and 1e-2 of the model size.  At 1e-4, B0
    against the exact motion within 1.4x the default tolerance's (1.33e-5 and 3.32e-6 m; 1.78e-5
    and 4.42e-6) and falling as h²."""
    times = np.arange(1, 101) * 0.01
    for tolerance, halvings in ((1e-2, 2), (1e-3, 2), (1e-4, 0)):
        errors = []
        for h, default_error in ((1e-3, 1.33e-5), (5e-4, 3.32e-6)):
            stepper, error = _chain_b0_error(100, times, h, tolerance)
            assert stepper.n_subdivisions <= halvings, (tolerance, h)
            errors.append(error)
            if tolerance == 1e-4:
                assert errors[-1] <= 1.4 * default_error
        if tolerance == 1e-4:
            assert 3.8 <= errors[0] / errors[1] <= 4.2
    # 1001 bodies at 1e-2 in 1 ms steps: main stopped at 0.7214 s after 24 halvings
    stepper, error = _chain_b0_error(500, times, 1e-3, 1e-2, drift_promise=False)
    assert stepper.n_subdivisions <= 2
    assert error <= 1e-4  # m (5.7e-5; the default tolerance 1.33e-5)


def _chain_b0_error(loops: int, times, h: float, tolerance: float, drift_promise: bool = True):
    """``(stepper, B0's largest error)``: the N-four-bar chain of `loops` stepped on the large
    path to each of `times` in steps of `h` at `tolerance`, B0 (the first crank's tip) against
    the exact motion; with `drift_promise` the velocity drift checked at every sample."""
    position, _ = n_four_bar_b0(times, n_loops=loops)
    stepper = GeneralizedAlphaStepper(n_four_bar(loops), h, tolerance=tolerance)
    stepper.start(0.0)
    assert stepper.path == "refactor"
    b0 = np.empty((times.size, 2))
    for k, t in enumerate(times):
        stepper.advance(t)
        q, v = stepper.state.coordinates, stepper.state.velocities
        b0[k] = q[0] + np.cos(q[2]), q[1] + np.sin(q[2])
        if drift_promise:
            assert stepper.recorded()[DRIFT][0][1] <= tolerance * h * max(1.0, np.abs(v[2::3]).max())
    return stepper, np.abs(b0 - position).max()


def _loose_run(times, h: float, tolerance: float, dense_max: int | None):
    """The N = 4 chain at `tolerance`; with `dense_max`, on the path its saddle size gives."""
    if dense_max is None:
        return sk.solve_dynamics(n_four_bar(4), times, max_step=h, forces=None, tolerance=tolerance)
    options = SolveOptions(tolerance, thresholds=Thresholds(saddle_dense_max_size=dense_max))
    result = run_dynamics(discretize(n_four_bar(4)), times, options, DynamicsOptions(h),
                          Request(points=["B0"], energy=True))  # fmt: skip
    assert result.linear_solver == "refactor"
    return result
