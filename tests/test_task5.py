"""The Task 5 ten-body linkage against the report, the ADAMS export and its own physics."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sparsekin.engine.discretization import Discretization
from sparsekin import ConvergenceError, solve_kinematics
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern

#: The MSC ADAMS export of point A (its header names the source; docs/task5.md).
ADAMS_POINT_A = Path(__file__).resolve().parent / "data" / "adams_point_A.csv"
PERIOD = 4 * math.pi / 3  # both strokes are L0 + 0.05 sin(1.5 t)


@pytest.fixture(scope="module")
def task5():
    from examples_loader import load_example

    return load_example("task5").build_task5()


def test_jacobian_determinant_at_start_matches_report(task5):
    """The report's det of the 30×30 Jacobian at t = 0 (given to 7 significant digits)."""
    pattern = build_pattern(task5)
    assembler = Assembler(Discretization(task5, pattern))
    assembler.set_time(0.0)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    jacobian = assembler.jacobian.toarray()
    assert jacobian.shape == (30, 30)
    assert np.linalg.det(jacobian) == pytest.approx(-0.01343628, rel=5e-8)
    assert np.linalg.cond(jacobian) == pytest.approx(94, rel=0.01)  # task5.md: "about 94"


def test_point_a_matches_adams(task5):
    """ADAMS rounds to 1e-4 mm, so a correct solver is within 5e-5 mm (+ ADAMS' own error)."""
    adams = np.loadtxt(ADAMS_POINT_A, delimiter=",", comments="#", skiprows=4)
    assert adams.shape == (501, 3) and adams[-1, 0] == 5.0
    result = solve_kinematics(task5, adams[:, 0])
    deviation_mm = np.abs(result.point("A").position * 1000.0 - adams[:, 1:])
    assert deviation_mm.max() <= 1e-4


def run_at_step(mechanism, step: float, t_end: float = 2.2):
    """0–2.2 s: through full extension of the actuators (t = π/3, the near dead centre)."""
    return solve_kinematics(mechanism, np.arange(0.0, t_end + step / 2, step))


@pytest.fixture(scope="module")
def fine_run(task5):
    return 0.0025, run_at_step(task5, 0.0025)


def five_point_derivatives(samples: np.ndarray, step: float):
    """First and second derivatives at the interior samples [2:-2] by 5-point stencils."""
    m2, m1, c, p1, p2 = (samples[k : samples.shape[0] - 4 + k] for k in range(5))
    first = (m2 - 8 * m1 + 8 * p1 - p2) / (12 * step)
    second = (-m2 + 16 * m1 - 30 * c + 16 * p1 - p2) / (12 * step**2)
    return first, second


def test_velocities_and_accelerations_match_differences_of_positions(fine_run):
    step, result = fine_run
    # At step 2.5 ms the stencils' truncation near the dead centre is 1.3e-9 (velocities)
    # and 1.1e-8 (accelerations), as measured by the fourth-order test below; the rounding
    # of positions adds ~1e-15 / step² ~ 2e-10.
    first, second = five_point_derivatives(result.coordinates, step)
    np.testing.assert_allclose(result.velocities[2:-2], first, atol=5e-9)
    np.testing.assert_allclose(result.accelerations[2:-2], second, atol=5e-8)
    for name in ("A", "J", "K"):
        motion = result.point(name)
        first, second = five_point_derivatives(motion.position, step)
        np.testing.assert_allclose(motion.velocity[2:-2], first, atol=5e-9)
        np.testing.assert_allclose(motion.acceleration[2:-2], second, atol=5e-8)


def test_difference_errors_fall_with_the_fourth_power_of_the_step(task5):
    """The gap between solved and differenced derivatives is the stencils' truncation alone."""
    gaps = []
    for step in (0.01, 0.005):
        result = run_at_step(task5, step)
        first, second = five_point_derivatives(result.coordinates, step)
        gaps.append((np.abs(result.velocities[2:-2] - first).max(), np.abs(result.accelerations[2:-2] - second).max()))
    velocity_ratio, acceleration_ratio = np.array(gaps[0]) / np.array(gaps[1])
    assert 12 < velocity_ratio < 20 and 12 < acceleration_ratio < 20  # 2⁴ = 16


def test_motion_is_periodic(task5):
    """After one period of the strokes, every body is back where it was (same branch)."""
    times = np.linspace(0.0, PERIOD + 0.5, 1001)
    result = solve_kinematics(task5, times)
    later = np.searchsorted(times, times[times <= 0.5] + PERIOD - 1e-12)
    np.testing.assert_allclose(
        result.coordinates[later], solve_kinematics(task5, times[later] - PERIOD).coordinates, atol=1e-9
    )


def test_actuator_strokes_follow_their_law(fine_run):
    """The distance N→M along the axis is L0 + 0.05 sin(1.5 t): the driver, from points."""
    _, result = fine_run
    stroke = np.linalg.norm(result.point("M").position - result.point("N").position, axis=1)
    np.testing.assert_allclose(stroke, 0.8246211251235321 + 0.05 * np.sin(1.5 * result.times), atol=1e-12)


def test_newton_converges_in_one_or_two_corrections_at_1_ms(task5):
    result = solve_kinematics(task5, np.arange(0.0, 2.0, 0.001), linear_solver="superlu")
    assert result.newton_iterations[1:].max() <= 2
    # one factorization per correction plus one at the converged position of each sample
    assert result.n_factorizations == result.newton_iterations.sum() + result.n_times
    assert result.n_solves == result.newton_iterations.sum() + 2 * result.n_times


@pytest.mark.parametrize("linear_solver", ["dense", "refactor"])
def test_chord_newton_factors_once_per_sample_at_1_ms(task5, linear_solver):
    """Chord corrections reuse the previous factorization; the Jacobian is factored only
    at each converged position, then (unless the residual is already at rounding level)
    one Newton correction with it polishes q."""
    result = solve_kinematics(task5, np.arange(0.0, 2.0, 0.001), linear_solver=linear_solver)
    assert result.linear_solver == ("compiled" if linear_solver == "dense" else "refactor")
    # one chord correction, and the polishing Newton correction unless already at rounding
    assert set(result.newton_iterations[1:]) <= {0, 1, 2}
    # the first sample: plain Newton from the drawing (0 corrections: it is assembled)
    assert result.n_factorizations + result.n_refactorizations == result.n_times
    assert result.n_solves == result.newton_iterations.sum() + 2 * result.n_times


def test_lock_up_keeps_the_samples_solved_before_it():
    """Strokes of 0.06 m reach the dead centre of c3 near t = 0.76 s (task5.md)."""
    from examples_loader import load_example

    times = np.arange(0.0, 2.0, 0.001)
    with pytest.raises(ConvergenceError, match=r"t = 0\.7\d+ s.*actuator1.*actuator2") as caught:
        solve_kinematics(load_example("task5").build_task5(amplitude=0.06), times)
    error = caught.value
    assert 0.74 < error.time < 0.78
    assert set(error.driver_values) == {
        'drivers[0] (stroke of joint "actuator1")',
        'drivers[1] (stroke of joint "actuator2")',
    }
    solved = error.result
    assert not solved.complete and solved.n_times == np.searchsorted(times, error.time)
    np.testing.assert_array_equal(solved.times, times[: solved.n_times])
    assert np.all(np.isfinite(solved.coordinates))
