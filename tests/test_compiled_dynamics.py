"""The compiled dynamics loop (`sparsekin.solve._compiled_dynamics`) against the Python stepper.

Both run the same generalized-α step on the same kernels; only the dense LU differs
(LAPACK's there, `sparsekin.engine._lu_kernels` here), so the two paths differ by rounding
that Newton's stopping rule may turn into a different last iterate.  Positions and
velocities then agree to the Newton tolerance (1e-10, relative to the model's size, per
second for velocities) times a small factor; accelerations, multipliers and the forces
made of them to the tolerance times β′/γ′ (a position left δq off by Newton is an
acceleration β′ δq off, and Newton stops at δq ≈ tolerance / γ′); the energy balance to
the tolerance times the energies' scale.  Measured (benchmarks/RESULTS.md, "Forward
dynamics, compiled"): A01 1e-16 relative, Task 5 1e-15 in positions; the N-four-bar
through its singular crossings 4e-10.

With error-controlled steps (``rtol``) the compiled loop runs the controller of
`sparsekin.solve.error_control` (`sparsekin.solve._error_control_kernels`): the same steps,
rejections and outputs as the Python stepper where its Newton ends on the same iterates
(A01), and where the two LUs' rounding makes a modified Newton refactor at another step
(the N-four-bar), step sizes that differ at the rounding of the estimate — a few steps more
or fewer over thousands, the motion the same to the Newton tolerance.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from dynamics_reference import n_four_bar_b0
from helpers import actuator_round_trip, assert_same_through_a_crossing

import sparsekin as sk
from sparsekin.engine.discretization import discretize
from sparsekin.solve.dynamics import GeneralizedAlpha, run_dynamics
from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions
from sparsekin.solve.policy import Thresholds, plan_saddle_solver
from sparsekin.testset import n_four_bar, task5

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
TOLERANCE = 1e-10
#: The Python stepper only, and the compiled loop wherever the plan allows it.
PYTHON, COMPILED = Thresholds(compiled_saddle_max_size=0), Thresholds()
#: The compiled loop on its dense LU only (the N-four-bar at N = 4, 53 unknowns, takes the
#: banded LU by default, which factors afresh at every step: tests/test_compiled_banded.py).
DENSE = Thresholds(min_banded_saddle_size=10_000)


@pytest.fixture
def steppers(monkeypatch):
    """The `GeneralizedAlphaStepper` of every run, in order (their controllers' counts)."""
    from sparsekin.solve import dynamics

    made, block_stepper = [], dynamics.block_stepper

    def recorded(stepper, *args, **kwargs):
        made.append(stepper)
        return block_stepper(stepper, *args, **kwargs)

    monkeypatch.setattr(dynamics, "block_stepper", recorded)
    return made


def both_paths(mechanism, times, max_step, rtol=None, compiled=COMPILED, **request):
    """The run on the Python stepper and on the compiled loop (of `compiled` thresholds),
    every variable recorded."""
    request = Request(energy=True, **({"forces": "all", "points": "all"} | request))
    return tuple(run_dynamics(discretize(mechanism), np.asarray(times, dtype=float),
                              SolveOptions(TOLERANCE, thresholds=thresholds), DynamicsOptions(max_step, 0.9, rtol),
                              request)
                 for thresholds in (PYTHON, compiled))  # fmt: skip


def assert_same_run(python, compiled, max_step, loops, size=1.0, rounds=1.0, same_steps=True):
    """Every recorded array within the bounds of the module docstring (`size`: the model's
    length scale, `rounds`: a factor for a run through singular positions, where Newton
    stops at the rounding floor of an ill-conditioned matrix; `same_steps` False: an
    error-controlled run whose step sizes differ at rounding, `max_step` its largest)."""
    assert python.complete and compiled.complete
    (loop,) = loops  # the Python run made none; every sample after the start was compiled
    assert loop.n_compiled == compiled.n_times - 1 and not loop.fell_back
    alpha_m, alpha_f, gamma, beta = GeneralizedAlpha().coefficients
    beta_over_gamma = (1.0 - alpha_m) / (max_step * gamma * (1.0 - alpha_f))  # β′/γ′
    # positions and velocities: the tolerance relative to their scale (the projection's
    # bound is tolerance · h · max(1, |v|)); the rest is made of accelerations or multipliers
    for name in ("coordinates", "velocities", "accelerations", "energy_tracks", "force_tracks", "point_tracks"):
        if getattr(python, name) is None:  # not recorded
            assert getattr(compiled, name) is None, name
            continue
        expected, actual = np.asarray(getattr(python, name)), np.asarray(getattr(compiled, name))
        assert expected.shape == actual.shape, name
        bound = 10.0 * rounds * TOLERANCE * max(size, float(np.max(np.abs(expected))))
        if name not in ("coordinates", "velocities"):
            bound *= beta_over_gamma
        np.testing.assert_allclose(actual, expected, rtol=0.0, atol=bound, err_msg=name)
    np.testing.assert_allclose(compiled.drift_tracks, python.drift_tracks, rtol=0.0, atol=TOLERANCE * 1e-2)
    if same_steps:
        assert compiled.n_steps == python.n_steps
    assert compiled.linear_solver == python.linear_solver == "dense"


def test_a01_pendulum_is_the_python_steppers_to_rounding(compiled_loops):
    pendulum = sk.load_model(EXAMPLES / "dynamics" / "pendulum.toml")
    python, compiled = both_paths(pendulum, np.linspace(0.0, 1.0, 101), 1e-3)
    assert_same_run(python, compiled, 1e-3, compiled_loops)
    np.testing.assert_array_equal(compiled.newton_iterations, python.newton_iterations)


def test_a03_andrews_mechanism_is_the_python_steppers(compiled_loops):
    andrews = sk.load_model(EXAMPLES / "dynamics" / "andrews.toml")
    python, compiled = both_paths(andrews, np.linspace(0.0, 0.005, 11), 1e-5)
    assert_same_run(python, compiled, 1e-5, compiled_loops, size=0.1)


def test_task5_with_masses_and_drivers_is_the_python_steppers(compiled_loops):
    python, compiled = both_paths(sk.load_model(EXAMPLES / "task5_dynamics.toml"), np.linspace(0.0, 0.2, 21), 1e-3)
    assert_same_run(python, compiled, 1e-3, compiled_loops)


def test_actuator_round_trip_is_the_python_steppers(compiled_loops):
    free, _ = actuator_round_trip(0.2, 1e-3)
    python, compiled = both_paths(free, np.linspace(0.0, 0.2, 21), 1e-3)
    assert_same_run(python, compiled, 1e-3, compiled_loops)


def test_n_four_bar_through_a_singular_crossing_is_the_python_steppers(compiled_loops):
    # the first flat crossing of N = 4 comes at t = 0.72 s; the dense LU (the same rules as
    # the Python stepper's, another LU's rounding): up to the crossing the two agree to the
    # Newton tolerance; the crossing amplifies their rounding (1.1e-7 m/s apart after it
    # with the residuals summed exactly; under 6.8e-8 before them), so from there both are held to the
    # exact answer (the reduced ODE), the loop's B0 no further off it than the Python
    # stepper's, within 5 %, as on the banded LU (tests/test_compiled_banded.py)
    times = np.linspace(0.0, 1.2, 25)
    python, compiled = both_paths(n_four_bar(4), times, 1e-3, compiled=DENSE, forces=None, points="all")
    (loop,) = compiled_loops
    assert not loop.fell_back and loop.n_compiled == times.size - 1
    assert compiled.n_steps == python.n_steps
    assert_same_through_a_crossing(python, compiled, times, TOLERANCE)


def test_a_sample_it_cannot_solve_is_handed_back_to_the_python_stepper(compiled_loops):
    # Task 5 at 0.06 m of stroke amplitude loses its assembly near t = 0.755 s: the compiled
    # loop stops at that sample, the Python stepper resumes from the last one solved and
    # fails there with its detailed error; the samples before are kept.
    results = []
    for thresholds in (PYTHON, COMPILED):
        with pytest.raises(sk.ConvergenceError, match=r"the step from t = 0\.755\d* s failed after 12 halvings") as failure:
            run_dynamics(discretize(task5(amplitude=0.06)), np.linspace(0.0, 1.0, 101),
                         SolveOptions(TOLERANCE, thresholds=thresholds), DynamicsOptions(1e-3), Request(energy=True))  # fmt: skip
        results.append(failure.value.result)
    python, compiled = results
    (loop,) = compiled_loops
    assert loop.fell_back and loop.n_compiled == 75  # t = 0.01 … 0.75 s; the start is the Python stepper's
    assert python.n_times == compiled.n_times == 76  # t = 0 … 0.75 s
    np.testing.assert_allclose(compiled.coordinates, python.coordinates, rtol=0.0, atol=10.0 * TOLERANCE)
    np.testing.assert_allclose(compiled.velocities, python.velocities, rtol=0.0, atol=10.0 * TOLERANCE)


def test_the_plan_runs_the_compiled_loop_for_small_models_with_built_in_laws():
    assert plan_saddle_solver(100, "auto", compilable=True).loop == "compiled"
    assert plan_saddle_solver(100, "dense", compilable=True).loop == "compiled"
    assert plan_saddle_solver(100, "auto", compilable=False).loop == "python"  # a law object of its own
    assert plan_saddle_solver(100, "superlu", compilable=True).loop == "python"
    assert plan_saddle_solver(100, "auto", PYTHON, compilable=True).loop == "python"
    assert plan_saddle_solver(10_000, "auto", compilable=True).solver == "refactor"


# ---------------------------------------------------------------------- error-controlled steps
def test_a01_with_rtol_takes_the_python_steppers_steps(compiled_loops, steppers):
    # 10 ms largest steps leave more than 1e-8 of the pendulum's length: the controller
    # chooses every step, and rejects one on the way
    pendulum = sk.load_model(EXAMPLES / "dynamics" / "pendulum.toml")
    python, compiled = both_paths(pendulum, np.linspace(0.0, 1.0, 101), 1e-2, rtol=1e-8)
    assert_same_run(python, compiled, 1e-2, compiled_loops)
    np.testing.assert_array_equal(compiled.newton_iterations, python.newton_iterations)
    fixed = sk.solve_dynamics(pendulum, np.linspace(0.0, 1.0, 101), max_step=1e-2)
    assert python.n_steps > 5 * fixed.n_steps
    first, second = (stepper.controller for stepper in steppers[:2])
    assert first.n_rejected == second.n_rejected > 0
    assert (first.error, first.hold, first._longest) == pytest.approx((second.error, second.hold, second._longest))


@pytest.mark.parametrize(("model", "times", "max_step", "rtol", "size"), [
    ("andrews", np.linspace(0.0, 0.005, 11), 1e-4, 1e-9, 0.1),
    ("task5_dynamics", np.linspace(0.0, 0.2, 21), 1e-2, 1e-9, 1.0),
])  # fmt: skip
def test_rtol_on_small_models_is_the_python_steppers(compiled_loops, steppers, model, times, max_step, rtol, size):
    path = EXAMPLES / "dynamics" / f"{model}.toml" if model == "andrews" else EXAMPLES / f"{model}.toml"
    python, compiled = both_paths(sk.load_model(path), times, max_step, rtol=rtol)
    assert_same_run(python, compiled, max_step, compiled_loops, size=size)
    assert steppers[0].controller.n_rejected == steppers[1].controller.n_rejected > 0


def test_n_four_bar_with_rtol_through_a_crossing_is_the_python_steppers_and_the_exact_answer(compiled_loops, steppers):
    # N = 4 over 1.2 s (the flat crossing near 0.72 s): the two LUs' rounding makes modified
    # Newton refactor at other steps, the estimate differs at its rounding, and so do the
    # step sizes (measured: 4 113 against 4 115 steps, positions 2e-10 apart)
    times = np.linspace(0.0, 1.2, 25)
    python, compiled = both_paths(n_four_bar(4), times, 1e-3, rtol=1e-10, forces=None, points=None)
    assert_same_run(python, compiled, 1e-3, compiled_loops, rounds=10.0, same_steps=False)
    assert abs(compiled.n_steps - python.n_steps) <= 2e-3 * python.n_steps
    assert abs(steppers[0].controller.n_rejected - steppers[1].controller.n_rejected) <= 2
    position, velocity = n_four_bar_b0(times, n_loops=4)
    errors = []
    for result in (python, compiled):  # B0: the crank's frame at its pivot, B0 one metre along it
        x, y, angle = result.coordinates[:, 0], result.coordinates[:, 1], result.coordinates[:, 2]
        b0 = np.column_stack([x + np.cos(angle), y + np.sin(angle)])
        errors.append(np.abs(b0 - position).max())
    # measured 1.01e-6 m both (fixed 1 ms steps: ~1.7e-5 m); the two runs' errors the same to 1 %
    assert max(errors) < 3e-6 and errors[1] == pytest.approx(errors[0], rel=0.01)


def test_with_rtol_a_sample_it_cannot_solve_is_handed_back_with_the_python_steppers_error(compiled_loops):
    results = []
    for thresholds in (PYTHON, COMPILED):
        with pytest.raises(sk.ConvergenceError, match=r"the step from t = 0\.755\d* s fell below 2\.44e-07 s \(Newton"
                           ) as failure:  # fmt: skip
            run_dynamics(discretize(task5(amplitude=0.06)), np.linspace(0.0, 1.0, 101),
                         SolveOptions(TOLERANCE, thresholds=thresholds), DynamicsOptions(1e-3, 0.9, 1e-8),
                         Request(energy=True))  # fmt: skip
        results.append(failure.value.result)
    python, compiled = results
    (loop,) = compiled_loops
    assert loop.fell_back and loop.n_compiled == 75
    assert python.n_times == compiled.n_times == 76
    np.testing.assert_allclose(compiled.coordinates, python.coordinates, rtol=0.0, atol=10.0 * TOLERANCE)
    np.testing.assert_allclose(compiled.velocities, python.velocities, rtol=0.0, atol=10.0 * TOLERANCE)
