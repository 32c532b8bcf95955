"""The pipeline every analysis runs on: the run driver's contract, step control, the plan
of ``"auto"`` and the options checked once (`sparsekin.solve.run`, `.step_control`,
`.policy`, `.options`).

The driver and step control are driven here by small steppers written for the test, as a
new analysis would drive them; the kinematic runs through them are checked against closed
forms and each other in the other test files.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from sparsekin import AnalysisInterrupted, ConvergenceError, testset
from sparsekin.engine.discretization import discretize
from sparsekin.solve.options import Request, SolveOptions
from sparsekin.solve.policy import COMPILED_MAX_COORDINATES, Thresholds, plan_linear_solver
from sparsekin.solve.run import run
from sparsekin.solve.step_control import StepAbandoned, StepControl, StepRejected, march
from sparsekin.solve.steppers import SampleBlock, StepperStats


class _Clock:
    """A block stepper of one coordinate, q = t, that raises `failure` at `fail_at` (s)."""

    def __init__(self, fail_at=np.inf, failure=None) -> None:
        self.fail_at, self.failure = fail_at, failure

    def advance_block(self, times):
        times = np.asarray(times)
        solved = times[times < self.fail_at][:2]  # at most two samples per block
        if solved.size == 0:
            raise self.failure
        q = solved[:, None]
        return SampleBlock(solved, q, np.ones_like(q), np.zeros_like(q), np.arange(solved.size), {})

    def stats(self) -> StepperStats:
        return StepperStats(path="clock")


class _Kept(NamedTuple):
    """What `finish` returns: the times recorded and the corrections (a result has `n_times`)."""

    times: np.ndarray
    iterations: np.ndarray

    @property
    def n_times(self) -> int:
        return self.times.size


def _drive(stepper, times, **options):
    kept = []

    def finish(state):
        return _Kept(np.concatenate(kept) if kept else np.zeros(0), state.iterations[: state.done].copy())

    return run(stepper, times, lambda block: kept.append(block.times.copy()), finish, **options)


def test_the_driver_solves_every_sample_in_blocks_and_reports_progress():
    times, progress = np.linspace(0.0, 1.0, 7), []
    recorded, iterations = _drive(_Clock(), times, chunk=5, progress=lambda done, n: progress.append((done, n)))
    np.testing.assert_array_equal(recorded, times)
    assert iterations.tolist() == [0, 1, 0, 1, 0, 1, 0]  # each block's own corrections, in place
    assert progress == [(2, 7), (4, 7), (6, 7), (7, 7)]


def test_an_error_carries_the_samples_recorded_before_it():
    times = np.linspace(0.0, 1.0, 11)
    failure = ConvergenceError("no convergence", time=0.55, driver_values={})
    with pytest.raises(ConvergenceError) as caught:
        _drive(_Clock(fail_at=0.55, failure=failure), times, chunk=3)
    np.testing.assert_array_equal(caught.value.result.times, times[:6])


def test_ctrl_c_becomes_an_interruption_with_the_samples_solved():
    times = np.linspace(0.0, 1.0, 11)
    with pytest.raises(AnalysisInterrupted) as caught:
        _drive(_Clock(fail_at=0.35, failure=KeyboardInterrupt()), times, chunk=4)
    np.testing.assert_array_equal(caught.value.result.times, times[:4])
    assert str(caught.value).startswith("interrupted after 4 samples")


def test_march_halves_a_rejected_step_and_grows_back_to_the_interval():
    steps = []

    def attempt(t0, t1, guarded):
        if t1 - t0 > 0.3:
            raise StepRejected("too long")
        steps.append((round(t0, 12), round(t1, 12), guarded))
        return 2

    outcome = march(0.0, 1.0, attempt)
    assert [step[:2] for step in steps] == [(0.0, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.0)]
    assert outcome.corrections == 8 and outcome.halvings == 4
    assert all(guarded for *_, guarded in steps)  # 0.25 is far above 2**-8 of the interval


def test_march_gives_up_on_the_shortest_step_and_stops_guarding_short_ones():
    seen = []

    def attempt(t0, t1, guarded):
        seen.append(guarded)
        raise StepRejected("never")

    with pytest.raises(StepAbandoned) as caught:
        march(0.0, 1.0, attempt, StepControl(guarded_halvings=3, failure_halvings=6))
    assert caught.value.reason == "never" and caught.value.t_from == 0.0
    assert caught.value.t_to == pytest.approx(2.0**-6) and caught.value.halvings == 6
    assert seen == [True, True, False, False, False, False]  # steps 1/2 .. 1/64: unguarded from 1/8 on


@pytest.mark.parametrize(
    ("build", "thresholds", "expected"),
    [
        (testset.task5, Thresholds(), ("compiled", "dense")),
        (testset.task5, Thresholds(compiled_max_coordinates=0), ("python", "refactor")),
        (lambda: testset.lattice(6, 8), Thresholds(), ("python", "refactor")),
        (lambda: testset.lattice(6, 8), Thresholds(compiled_max_coordinates=10**6), ("compiled", "dense")),
        (lambda: testset.rotating_squares(4), Thresholds(), ("python", "dense")),  # redundant: not square
    ],
)
def test_auto_plans_by_size_and_squareness(build, thresholds, expected):
    plan = plan_linear_solver(discretize(build()), "auto", thresholds)
    assert (plan.loop, plan.solver) == expected and plan.chord
    assert plan.reuse_fill == thresholds.max_refactor_fill


def test_a_named_solver_is_planned_as_asked():
    model = discretize(testset.task5())
    assert model.n_coordinates <= COMPILED_MAX_COORDINATES
    superlu = plan_linear_solver(model, "superlu")
    assert (superlu.loop, superlu.solver, superlu.chord, superlu.reuse_fill) == ("python", "superlu", False, None)
    assert plan_linear_solver(model, "refactor").loop == "python"


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (dict(tolerance=0.5), r"`tolerance` must be a number in \["),
        (dict(tolerance=True), "`tolerance` must be a positive number"),
        (dict(max_iterations=0), "`max_iterations` must be a whole number >= 1"),
        (dict(linear_solver="fast"), "`linear_solver` must be one of 'auto', 'superlu', 'refactor', 'dense'"),
    ],
)
def test_options_are_refused_when_made(options, message):
    with pytest.raises(ValueError, match=message):
        SolveOptions(**options)


def test_a_request_is_refused_when_made_and_resolved_against_a_model():
    with pytest.raises(ValueError, match="`quasi_static` must be True or False"):
        Request(quasi_static="yes")
    with pytest.raises(ValueError, match="`chunk_samples` must be a whole number >= 1"):
        Request(chunk_samples=0)
    selection = Request(points=["K"], joints="all").selection(discretize(testset.task5()))
    assert selection.point_names == ("K",) and selection.joint_indices and selection.forces is None
