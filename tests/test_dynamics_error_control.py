"""Error-controlled steps of forward dynamics (`rtol`, sparsekin.solve.error_control).

* the local error estimate C h² (ã_{n+1} − ã_n), C = β − γ/2 + 1/12, against the error one
  step actually makes (a step of h against 64 steps of h/64 from the same state): the same
  to 1 % on the pendulum (A01) with and without numerical damping, and falling as h³ there
  and on the N-four-bar;
* IFToMM A02's bounds (B0 within 1e-3 m and m/s, energy within 1e-4 of the initial kinetic
  energy, every crank at the same angle through the singular crossings) met by one `rtol`
  at every largest step, where fixed steps of 1 ms miss the energy bound, on the exact
  family at N = 4; the global error falling as rtol^(2/3) (local error ∝ h³, global ∝ h²);
* outputs still at the requested times; the options checked in one line (Python, model
  file, command line).

References: tests/dynamics_reference.py (the reduced ODE of the N-four-bar, exact at any N).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from dynamics_reference import n_four_bar_b0

import sparsekin as sk
from sparsekin.solve.dynamics import GeneralizedAlpha, GeneralizedAlphaStepper
from sparsekin.solve.error_control import local_error_constant
from sparsekin.testset import n_four_bar

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def one_step_errors(mechanism, rho_inf: float, t0: float, steps) -> tuple[np.ndarray, np.ndarray]:
    """For each h of `steps`: the estimate of the step from the fixed-step state at `t0`,
    and the step's actual local error (the step of h minus 64 steps of h/64 from the same
    state, whose own error is 64² times smaller), both weighted like the tolerance (lengths
    over the model size, angles in rad), largest over the coordinates."""
    estimates, actual = [], []
    for h in steps:
        stepper = GeneralizedAlphaStepper(mechanism, h, integrator=GeneralizedAlpha(rho_inf))
        stepper.start(0.0)
        stepper.advance(t0)
        before = stepper.state
        _, _, gamma, beta = stepper.integrator.coefficients
        after = stepper._step(before, h, t0 + h)
        change = after.pseudo_accelerations - before.pseudo_accelerations
        estimate = local_error_constant(gamma, beta) * h * h * change
        fine, k = before, 64
        stepper._factored = False
        for i in range(k):
            fine = stepper._step(fine, h / k, t0 + (i + 1) * h / k)
        weights = stepper.pattern.coordinate_weights
        estimates.append(np.max(np.abs(estimate) * weights))
        actual.append(np.max(np.abs(after.coordinates - fine.coordinates) * weights))
    return np.array(estimates), np.array(actual)


@pytest.mark.parametrize("rho_inf", [1.0, 0.9])
def test_the_local_error_estimate_is_the_error_of_the_step(rho_inf):
    pendulum = sk.load_model(EXAMPLES / "dynamics" / "pendulum.toml")
    estimates, actual = one_step_errors(pendulum, rho_inf, 0.3, [2e-3, 1e-3, 5e-4])
    np.testing.assert_allclose(estimates / actual, 1.0, atol=0.012)  # measured 0.990–0.998
    np.testing.assert_allclose(estimates[:-1] / estimates[1:], 8.0, rtol=0.02)  # h³


def test_the_local_error_estimate_falls_as_h_cubed_on_a_linkage():
    estimates, actual = one_step_errors(n_four_bar(4), 0.9, 0.3, [2e-3, 1e-3, 5e-4])
    np.testing.assert_allclose(estimates[:-1] / estimates[1:], 8.0, rtol=0.02)
    np.testing.assert_allclose(actual[:-1] / actual[1:], 8.0, rtol=0.02)
    # the estimate's largest entry and the actual error's are not the same coordinate's:
    # within 20 % (measured: estimate / actual = 1.19 at every step)
    assert np.all((estimates / actual > 1.0) & (estimates / actual < 1.25))


@pytest.fixture(scope="module")
def a02_runs():
    """The N-four-bar, N = 4 (the exact family; a flat crossing at 0.72 s), over 1 s at
    fixed steps of 1 ms and with rtol = 1e-10 at largest steps of 1, 0.5 and 0.25 ms (and
    rtol = 1e-9 at 1 ms)."""
    times = np.linspace(0.0, 1.0, 21)
    position, velocity = n_four_bar_b0(times, n_loops=4)
    runs = {("fixed", 1e-3): sk.solve_dynamics(n_four_bar(4), times, max_step=1e-3, forces=None)}
    for rtol, steps in ((1e-10, (1e-3, 5e-4, 2.5e-4)), (1e-9, (1e-3,))):
        for h in steps:
            runs[(rtol, h)] = sk.solve_dynamics(n_four_bar(4), times, max_step=h, rtol=rtol, forces=None)
    errors = {}
    for key, result in runs.items():
        b0 = result.point("B0")
        cranks = result.coordinates[:, [2, *range(5, result.coordinates.shape[1], 6)]]
        errors[key] = (np.abs(b0.position - position).max(), np.abs(b0.velocity - velocity).max(),
                       np.abs(result.energy.balance).max() / result.energy.kinetic[0], np.ptp(cranks, axis=1).max(),
                       result)  # fmt: skip
    return times, errors


def test_one_rtol_meets_the_benchmark_at_every_largest_step(a02_runs):
    times, errors = a02_runs
    assert errors[("fixed", 1e-3)][2] > 1e-4  # fixed 1 ms steps miss the energy bound (4.0e-4)
    for h in (1e-3, 5e-4, 2.5e-4):
        position, velocity, energy, spread, result = errors[(1e-10, h)]
        np.testing.assert_array_equal(result.times, times)  # every output at its time, through the crossing
        assert position < 1e-3 and velocity < 1e-3 and energy < 1e-4
        assert spread < 1e-8  # every crank at the same angle
    # the largest step only caps the steps: the same accuracy whatever it is
    velocities = [errors[(1e-10, h)][1] for h in (1e-3, 5e-4, 2.5e-4)]
    assert max(velocities) < 1.3 * min(velocities)


def test_the_error_falls_as_rtol_to_the_two_thirds(a02_runs):
    _, errors = a02_runs
    # local error ∝ h³ held at rtol, global ∝ h²: rtol^(2/3), 10^(2/3) = 4.64 per decade
    for k in range(3):
        assert 3.8 < errors[(1e-9, 1e-3)][k] / errors[(1e-10, 1e-3)][k] < 5.6
    steps = errors[(1e-10, 1e-3)][4].n_steps / errors[(1e-9, 1e-3)][4].n_steps
    assert 1.9 < steps < 2.5  # 10^(1/3) = 2.15 more steps


@pytest.mark.parametrize(("keywords", "message"), [
    ({"rtol": 0.5}, r"`rtol` must be a number in \[1e-12, 0.1\], got 0.5"),
    ({"rtol": "tight"}, "`rtol` must be None or a positive number, got 'tight'"),
])
def test_rtol_is_checked(keywords, message):
    pendulum = sk.load_model(EXAMPLES / "dynamics" / "pendulum.toml")
    with pytest.raises(ValueError, match=message):
        sk.solve_dynamics(pendulum, [0.0, 0.1], **keywords)


def test_rtol_in_the_model_file_and_on_the_command_line(tmp_path, capsys):
    from sparsekin.cli import main

    source = (EXAMPLES / "dynamics" / "pendulum.toml").read_text(encoding="utf-8")
    assert "[analysis]" in source
    path = tmp_path / "model.toml"
    path.write_text(source.replace("[analysis]", "[analysis]\nrtol = 1e-8"), encoding="utf-8")
    model = sk.load_model(path)
    assert model.analysis.rtol == 1e-8
    times = np.linspace(0.0, 0.5, 11)
    from_file = sk.solve_dynamics(model, times, max_step=0.01)
    given = sk.solve_dynamics(model, times, max_step=0.01, rtol=1e-8)
    fixed = sk.solve_dynamics(sk.load_model(EXAMPLES / "dynamics" / "pendulum.toml"), times, max_step=0.01)
    np.testing.assert_array_equal(from_file.coordinates, given.coordinates)
    assert from_file.n_steps > fixed.n_steps  # 0.01 s steps leave more than 1e-8 of the pendulum's length

    path.write_text(source.replace("[analysis]", "[analysis]\nrtol = 0.0"), encoding="utf-8")
    with pytest.raises(sk.ModelError, match=r"analysis\.rtol: expected rtol in \[1e-12, 0\.1\], got 0\.0"):
        sk.load_model(path)
    assert main(["run", str(EXAMPLES / "task5_dynamics.toml"), "--rtol", "1e-6", "--out", str(tmp_path / "a")]) != 0
    assert "--rtol is for forward dynamics" in capsys.readouterr().err
    status = main(["run", str(EXAMPLES / "dynamics" / "pendulum.toml"), "--dynamics", "--rtol", "2", "--out",
                   str(tmp_path / "b")])  # fmt: skip
    assert status != 0
    assert "--rtol must be a number in [1e-12, 0.1], got 2.0" in capsys.readouterr().err
    status = main(["run", str(EXAMPLES / "dynamics" / "pendulum.toml"), "--t-end", "0.5", "--steps", "11", "--rtol",
                   "1e-8", "--max-step", "0.01", "--out", str(tmp_path / "c"), "--quiet"])  # fmt: skip
    assert status == 0
    points = np.loadtxt(tmp_path / "c" / "points.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(points[:, 1:3], from_file.point("P").position, rtol=0.0, atol=1e-12)


def test_the_tightest_tolerance_passes_a_flat_crossing():
    """The N-four-bar (N = 4) through its flat crossing at 0.718 s with the tightest rtol,
    1e-12.  While the residuals rounded at the coordinates' ulp, the estimate there was
    Newton's noise along the vanishing singular values of Φq, which no step brings down:
    the steps fell to 2.4e-7 s and the run stopped, until steps at `shortest` were
    accepted (one was, on this run).  Summed exactly, the crossing needs none: 9850 steps,
    B0 3.7e-9 m off the exact answer at 0.75 s."""
    from sparsekin.solve.options import DynamicsOptions

    times = np.arange(0.05, 0.8, 0.05)
    stepper = GeneralizedAlphaStepper(n_four_bar(4), dynamics=DynamicsOptions(1e-3, 0.9, 1e-12))
    stepper.start(0.0)
    for t in times:
        stepper.advance(t)
    position, _ = n_four_bar_b0(np.array([times[-1]]), n_loops=4)
    x, y, angle = stepper.state.coordinates[:3]  # crank0: frame at its pivot O0, B0 one metre along it
    b0 = np.array([x + np.cos(angle), y + np.sin(angle)])
    assert stepper.n_steps < 20_000
    assert np.abs(b0 - position[0]).max() < 1e-8


def test_a_step_at_the_shortest_is_accepted_above_the_tolerance():
    """An estimate that no step brings down (noise, where Φq loses rank for an instant)
    shortens the step to `shortest`, 1/16 of the longest accepted lately, and no further:
    that step is accepted and counted (`n_uncontrolled`); a longer one is rejected."""
    from sparsekin.solve.error_control import SHORTEST_FRACTION, ErrorTooLarge, StepSizeController

    weights = np.ones(3)
    controller = StepSizeController(1e-8, 0.5, 0.25, weights, 1e-3)
    controller.check(np.zeros(3), np.zeros(3), 1e-3)  # accepted: the longest lately
    assert controller.shortest == pytest.approx(SHORTEST_FRACTION * 1e-3)
    noisy = np.array([0.0, 1e3, 0.0])  # far above rtol at any step
    with pytest.raises(ErrorTooLarge):
        controller.check(noisy, np.zeros(3), 2.0 * controller.shortest)
    controller.check(noisy, np.zeros(3), controller.shortest)
    assert controller.n_uncontrolled == 1 and controller.n_rejected == 1 and controller.error > 1.0


def test_a_non_finite_estimate_is_too_large_in_both_controllers():
    """A NaN or infinite local error estimate rejects the step (Python controller and the
    compiled loop's kernels alike), and the next step is the shortest shrink allowed."""
    from sparsekin.solve import _error_control_kernels as kernels
    from sparsekin.solve.error_control import SHRINK_LIMIT, ErrorTooLarge, StepSizeController

    weights = np.ones(3)
    old, change = np.zeros(3), np.zeros(3)
    for bad in (np.nan, np.inf):
        new = np.array([0.0, bad, 0.0])
        controller = StepSizeController(1e-8, 0.5, 0.25, weights, 1e-2)
        values, rules = kernels.control_state(controller), kernels.control_rules(controller)
        with pytest.raises(ErrorTooLarge):
            controller.check(new, old, 1e-3)
        assert controller.n_rejected == 1 and controller.factor() == SHRINK_LIMIT
        assert not kernels.accept_step(values, rules, new, old, weights, 1e-3, 0.0, change)
        assert values[kernels.CONTROL_FIELDS.index("n_rejected")] == 1.0
        assert kernels._factor(values, rules) == SHRINK_LIMIT
