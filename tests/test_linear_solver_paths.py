"""Every linear-solver path of `solve_kinematics` gives the same motion.

The paths differ in how the linear systems are solved (a compiled loop on a dense LU, a
refactorization on a fixed pattern, SuperLU every iteration) and in the Newton iteration
(chord or plain), never in the equations: on every family of the test set, and through a
hand-over from the compiled loop to the Python loop, they agree to rounding.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from helpers import MOTION, assert_same_motion, solve_with

from sparsekin import SingularConfigurationError, solve_kinematics, testset
from sparsekin.solve.policy import COMPILED_MAX_COORDINATES, Thresholds

FAMILIES = {
    "task5": (testset.task5, np.linspace(0.0, 4.0, 401)),
    "task5_chain": (lambda: testset.task5_chain(3), np.linspace(0.0, 4.0, 201)),
    "four_bar_chain": (lambda: testset.four_bar_chain(8), np.linspace(0.0, 2.0, 201)),
    "lattice": (lambda: testset.lattice(3, 4), np.linspace(0.0, 3.0, 151)),
}


def assert_same_run(result, reference, scale):
    """Positions to 1e-11 of the model size (angles in rad), derivatives to 1e-9 relative."""
    assert result.complete and reference.complete
    weights = np.full(reference.coordinates.shape[1], 1.0 / scale)
    weights[2::3] = 1.0
    np.testing.assert_allclose(
        result.coordinates * weights, reference.coordinates * weights, rtol=0, atol=1e-11
    )
    derivatives = [(run.velocities, run.accelerations) for run in (result, reference)]
    assert_same_motion(*derivatives, 1e-9, labels=MOTION[1:])


@pytest.fixture(scope="module", params=list(FAMILIES))
def family_run(request):
    build, times = FAMILIES[request.param]
    mechanism = build()
    reference = solve_kinematics(mechanism, times, linear_solver="superlu")
    scale = max(np.abs(mechanism.positions(list(mechanism.points))).max(), 1e-3)
    return mechanism, times, reference, scale


@pytest.mark.parametrize("linear_solver", ["refactor", "dense", "auto"])
def test_paths_agree_with_superlu(family_run, linear_solver):
    mechanism, times, reference, scale = family_run
    result = solve_kinematics(mechanism, times, linear_solver=linear_solver)
    assert_same_run(result, reference, scale)
    np.testing.assert_array_equal(result.times, reference.times)
    if linear_solver == "dense":
        assert result.linear_solver == "compiled"
    elif linear_solver == "refactor":
        assert result.linear_solver == "refactor"
        assert result.n_factorizations == 1  # the guard never had to refactor afresh
        assert result.n_refactorizations == result.n_times - 1
    else:
        small = 3 * mechanism.n_bodies <= COMPILED_MAX_COORDINATES
        assert result.linear_solver == ("compiled" if small else "refactor")


def test_chord_needs_fewer_factorizations_than_plain_newton(family_run):
    mechanism, times, reference, _ = family_run
    result = solve_kinematics(mechanism, times, linear_solver="refactor")
    assert result.n_factorizations + result.n_refactorizations == result.n_times
    assert reference.n_factorizations == result.n_times + reference.newton_iterations.sum()


@pytest.mark.parametrize("linear_solver", ["dense", "refactor", "superlu"])
def test_every_path_stops_at_the_same_lock_up(linear_solver):
    """Task 5 with 0.06 m strokes: the compiled loop hands the failing step to the Python
    loop, which subdivides it and diagnoses the dead centre, as the other paths do."""
    times = np.linspace(0.0, 1.0, 101)
    with pytest.raises(
        SingularConfigurationError, match=r"singular configuration at t = 0\.755\d* s"
    ) as caught:
        solve_kinematics(testset.task5(amplitude=0.06), times, linear_solver=linear_solver)
    assert caught.value.result.n_times == 76
    reference = solve_kinematics(testset.task5(amplitude=0.06), times[:76], linear_solver="superlu")
    # Approaching the dead centre the condition number climbs from 94 to about 7000, so the
    # paths' rounding differences grow there; still within 1e-11 of the model size.
    np.testing.assert_allclose(caught.value.result.coordinates, reference.coordinates, rtol=0, atol=1.2e-11)


def test_hand_over_from_the_compiled_loop_keeps_solving():
    """A step too long for Newton from the predictor: the compiled loop stops there, the
    Python loop subdivides it and goes on to the end."""
    times = np.concatenate([np.linspace(0.0, 0.5, 51), [3.0], np.linspace(3.01, 3.5, 50)])
    result = solve_kinematics(testset.task5(), times, linear_solver="dense")
    reference = solve_kinematics(testset.task5(), times, linear_solver="superlu")
    assert result.linear_solver == "compiled+dense"
    assert result.n_subdivisions > 0 and reference.n_subdivisions > 0
    assert_same_run(result, reference, 1.2)


def test_unknown_linear_solver_is_refused():
    with pytest.raises(
        ValueError, match="`linear_solver` must be one of 'auto', 'superlu', 'refactor', 'dense'"
    ):
        solve_kinematics(testset.task5(), [0.0], linear_solver="umfpack")


def test_models_the_compiled_loop_cannot_run_use_the_python_loop():
    """A law of another kind: ``"dense"`` solves with `DenseSolver` in the Python loop."""

    class Ramp:
        def evaluate(self, t, initial):
            return initial + 0.01 * t, 0.01, 0.0

    mechanism = testset.task5()
    mechanism = replace(mechanism, drivers=(replace(mechanism.drivers[0], law=Ramp()), mechanism.drivers[1]))
    times = np.linspace(0.0, 1.0, 11)
    result = solve_kinematics(mechanism, times, linear_solver="dense")
    assert result.linear_solver == "dense"
    assert_same_run(result, solve_kinematics(mechanism, times, linear_solver="superlu"), 1.2)


def test_auto_refactors_a_model_above_the_compiled_size():
    mechanism, times = testset.lattice(6, 8), np.linspace(0.0, 1.0, 51)  # 306 coordinates
    result = solve_kinematics(mechanism, times)
    assert result.linear_solver == "refactor"
    assert_same_run(result, solve_kinematics(mechanism, times, linear_solver="superlu"), 8.0)


def test_auto_reuses_a_factorization_with_heavy_fill():
    """Above `MAX_REFACTOR_FILL` entries of L + U per Jacobian entry, ``auto`` goes on
    reusing the refactorization across samples (GMRES preconditioned by it) from the first
    sample on; the motion is the same, with far fewer factorizations than samples."""
    mechanism, times = testset.lattice(6, 8), np.linspace(0.0, 1.0, 51)
    result = solve_with(mechanism, times, thresholds=Thresholds(max_refactor_fill=1.0))  # every model's fill is heavier
    assert result.linear_solver == "reuse"
    assert result.n_factorizations + result.n_refactorizations < result.n_times // 5
    assert_same_run(result, solve_kinematics(mechanism, times, linear_solver="superlu"), 8.0)


#: Overconstrained families: solved without their redundant equations (a reduced system).
REDUNDANT_FAMILIES = {
    "parallel_bar_chain": (lambda: testset.parallel_bar_chain(40), np.linspace(0.0, 2.0, 41)),
    "rotating_squares": (lambda: testset.rotating_squares(8), np.linspace(0.0, 2.0, 41)),
}


@pytest.mark.filterwarnings("ignore::sparsekin.RedundantConstraintWarning")
@pytest.mark.parametrize("name", ["task5_chain", "four_bar_chain", "lattice", *REDUNDANT_FAMILIES])
def test_reuse_agrees_with_superlu_on_every_family(name):
    """The reusing path on the families whose paths are compared above (velocities and
    accelerations included), over their whole motions; on the overconstrained ones too,
    whose reduced system first filled in the refactorization's order."""
    build, times = {**FAMILIES, **REDUNDANT_FAMILIES}[name]
    mechanism = build()
    # every model reuses, none runs the compiled loop
    result = solve_with(mechanism, times, thresholds=Thresholds(max_refactor_fill=0.0, compiled_max_coordinates=0))
    assert result.linear_solver == "reuse"
    scale = max(np.abs(mechanism.positions(list(mechanism.points))).max(), 1e-3)
    assert_same_run(result, solve_kinematics(mechanism, times, linear_solver="superlu"), scale)


def test_auto_with_heavy_fill_gives_the_forces_of_superlu_from_the_first_sample():
    """Reusing the factorization from the first sample on, the forces (transposed systems,
    solved by GMRES with the held factorization) are those of ``linear_solver="superlu"``
    at every sample, the first included."""
    grid = testset.lattice(6, 8).expanded()  # every bar with its own mass below
    bodies = tuple(replace(body, mass=2.0, inertia=0.2) for body in grid.bodies)
    mechanism, times = replace(grid, bodies=bodies, gravity=(0.0, -9.81)), np.linspace(0.0, 1.0, 11)
    heavy = Thresholds(max_refactor_fill=1.0)  # every model's fill is heavier
    result = solve_with(mechanism, times, forces="all", thresholds=heavy)
    reference = solve_kinematics(mechanism, times, forces="all", linear_solver="superlu")
    assert result.linear_solver == "reuse" and result.complete
    assert result.force_labels == reference.force_labels and len(result.force_labels) > 100
    assert result.n_factorizations + result.n_refactorizations < result.n_times
    scale = np.abs(reference.force_tracks).max()
    np.testing.assert_allclose(result.force_tracks, reference.force_tracks, rtol=0, atol=1e-9 * scale)
