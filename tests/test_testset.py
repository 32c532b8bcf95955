"""The test-set mechanisms against their exact motions."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from examples_loader import EXAMPLES
from sparsekin.engine.discretization import Discretization
from sparsekin import load_model, save_model, solve_kinematics, testset
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern

# Two independent Newton solutions agree to the convergence tolerance (1e-12 relative)
# times the conditioning of the chain; 1e-9 of the model size leaves a wide margin.
POSITION_RTOL = 1e-9


def test_task5_is_the_example_model():
    from_file = load_model(EXAMPLES / "task5.toml")
    assert from_file == replace(testset.task5(), analysis=from_file.analysis)


def test_four_bar_chain_couplers_translate():
    n_loops, angle0, rate = 6, np.pi / 4, 1.0
    mechanism = testset.four_bar_chain(n_loops, initial_angle=angle0, rate=rate)
    assert mechanism.n_bodies == 2 * n_loops + 1
    times = np.linspace(0.0, 1.5, 151)  # crank from 45° to 131°, away from 0 and 180°
    result = solve_kinematics(mechanism, times)
    angle = angle0 + rate * times
    for i in range(n_loops + 1):
        tip = result.point("A0" if i == 0 else f"u{i - 1}.Q")  # the tip of crank i
        np.testing.assert_allclose(tip.position, np.c_[i + np.cos(angle), np.sin(angle)], atol=1e-12 * n_loops)
        np.testing.assert_allclose(tip.velocity, rate * np.c_[-np.sin(angle), np.cos(angle)], atol=1e-11)
        np.testing.assert_allclose(tip.acceleration, -(rate**2) * np.c_[np.cos(angle), np.sin(angle)], atol=1e-10)
    couplers = 3 * np.array([mechanism.body_index(f"u{k}.coupler") for k in range(n_loops)]) + 2
    np.testing.assert_allclose(result.coordinates[:, couplers], 0.0, atol=1e-12)  # no rotation


def lattice_nodes(rows, cols, times):
    """Exact node positions, velocities and accelerations: rows shear with their drivers."""
    phases = 2 * np.pi * np.arange(rows) / rows
    a, w = testset.LATTICE_AMPLITUDE, testset.LATTICE_OMEGA
    angle = np.pi / 2 + a * (np.sin(w * times[:, None] + phases) - np.sin(phases))  # (n_t, rows)
    rate = a * w * np.cos(w * times[:, None] + phases)
    acceleration = -a * w**2 * np.sin(w * times[:, None] + phases)
    direction = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    normal = np.stack([-np.sin(angle), np.cos(angle)], axis=-1)
    position = np.cumsum(direction, axis=1)  # node (r, c) = (c, 0) + sum over rows <= r
    velocity = np.cumsum(normal * rate[..., None], axis=1)
    accel = np.cumsum(normal * acceleration[..., None] - direction * rate[..., None] ** 2, axis=1)
    return position, velocity, accel


def test_lattice_rows_shear_with_their_drivers():
    rows, cols = 4, 5
    mechanism = testset.lattice(rows, cols)
    assert mechanism.n_bodies == rows * (2 * cols + 1)
    times = np.linspace(0.0, 4.0, 201)
    result = solve_kinematics(mechanism, times)
    position, velocity, acceleration = lattice_nodes(rows, cols, times)
    for r in range(1, rows + 1):
        for c in (0, cols // 2, cols):
            motion = result.point(f"c{c}_{r - 1}.T")  # node (r, c)
            np.testing.assert_allclose(motion.position, position[:, r - 1] + [c, 0.0], atol=1e-11)
            np.testing.assert_allclose(motion.velocity, velocity[:, r - 1], atol=1e-10)
            np.testing.assert_allclose(motion.acceleration, acceleration[:, r - 1], atol=1e-9)


def test_lattice_jacobian_is_square_and_well_conditioned_over_its_run():
    """How the lattice was checked: 0 degrees of freedom and no singular position."""
    mechanism = testset.lattice(3, 4)
    pattern = build_pattern(mechanism)
    assert pattern.n_equations == pattern.n_coordinates
    result = solve_kinematics(mechanism, np.linspace(0.0, np.pi, 61))  # one period of the rows
    assembler = Assembler(Discretization(mechanism, pattern))
    smallest = []
    for t, q in zip(result.times, result.coordinates):
        assembler.set_time(t)
        assembler.fill_residual_jacobian(q)
        smallest.append(np.linalg.svd(assembler.jacobian.toarray(), compute_uv=False)[-1])
    assert min(smallest) > 0.05


def task5_chain_reference(n_units: int, times: np.ndarray, amplitude: float):
    """Points of every unit from one single Task 5, shifted in time and carried by its base.

    Unit k moves relative to the c10 body of unit k-1 as a single Task 5 with phase
    phi_k moves relative to the ground; phi_k / omega is a whole number of `times` steps.
    """
    omega = testset.TASK5_OMEGA
    step = times[1] - times[0]
    shifts = np.rint(testset.task5_unit_phases(n_units) / omega / step).astype(int)
    single = solve_kinematics(testset.task5(amplitude), np.arange(times.size + shifts.max()) * step)
    names = list(testset.TASK5_POINTS)
    units = []
    for k in range(n_units):
        local = np.stack([single.point(p).position[shifts[k] : shifts[k] + times.size] for p in names], axis=1)
        local = local + [testset.TASK5_CHAIN_SPACING * k, 0.0]
        if k > 0:  # carry with the rigid motion of the base c10 of unit k-1 (frame H→G)
            h, g = units[-1][:, names.index("H")], units[-1][:, names.index("G")]
            turn = np.arctan2(*(g - h).T[::-1]) - np.arctan2(*(g[0] - h[0])[::-1])
            cosine, sine = np.cos(turn)[:, None], np.sin(turn)[:, None]
            relative = local - h[0]
            local = h[:, None, :] + np.stack(
                [cosine * relative[..., 0] - sine * relative[..., 1], sine * relative[..., 0] + cosine * relative[..., 1]],
                axis=-1,
            )
        units.append(local)
    return names, units


def test_task5_chain_units_move_as_single_task5_on_their_base():
    n_units, amplitude = 13, 0.03  # more than the 11 distinct phases
    omega = testset.TASK5_OMEGA
    step = 2 * np.pi / omega / (testset.TASK5_CHAIN_PHASES * 40)  # phase shifts fall on samples
    times = np.arange(0.0, 2.5, step)
    mechanism = testset.task5_chain(n_units, amplitude)
    assert (mechanism.n_bodies, len(mechanism.drivers)) == (10 * n_units, 2 * n_units)
    result = solve_kinematics(mechanism, times)
    names, units = task5_chain_reference(n_units, times, amplitude)
    scale = testset.TASK5_CHAIN_SPACING * n_units
    for k in range(n_units):
        for j, name in enumerate(names):
            np.testing.assert_allclose(
                result.point(f"u{k}.{name}").position, units[k][:, j], atol=POSITION_RTOL * scale, err_msg=f"u{k}.{name}"
            )


@pytest.mark.parametrize("n_units", [22, 44])
def test_task5_chain_waves_without_curling_up(n_units):
    """Base rotations cancel over each block of 11 phases; the chain's direction only waves."""
    mechanism = testset.task5_chain(n_units)
    result = solve_kinematics(mechanism, np.linspace(0.0, 4.2, 211))  # one period
    last_base = result.coordinates[:, 3 * mechanism.body_index(f"u{n_units - 1}.c10") + 2]
    first_base = result.coordinates[:, 3 * mechanism.body_index("u0.c10") + 2]
    # the last unit, at the end of a whole block, turns no more than a single unit does
    assert np.ptp(last_base) <= np.ptp(first_base) + 1e-6
    far_end = result.point(f"u{n_units - 1}.K").position
    length = testset.TASK5_CHAIN_SPACING * n_units
    assert np.ptp(far_end[:, 1]) > 0.1 * length  # the far end sweeps: a non-trivial motion
    assert np.abs(far_end[:, 1]).max() < 0.3 * length  # within ±0.3 rad of the x axis, for any n


@pytest.mark.parametrize("build", [lambda: testset.task5_chain(2), lambda: testset.four_bar_chain(3), lambda: testset.lattice(2, 2)])
def test_test_set_models_round_trip_through_files(build, tmp_path):
    mechanism = build()
    save_model(mechanism, tmp_path / "model.toml")
    assert load_model(tmp_path / "model.toml") == mechanism


@pytest.mark.parametrize(
    "build",
    [lambda: testset.task5(), lambda: testset.task5_chain(2), lambda: testset.four_bar_chain(3),
     lambda: testset.lattice(2, 3), lambda: testset.rotating_squares(4), lambda: testset.rotating_rectangles(3, 4),
     lambda: testset.parallel_bar_chain(4, bars=3), lambda: testset.parallel_bar_chain(4, bars=2)],
)  # fmt: skip
def test_test_set_models_join_every_shared_point(build):
    """No point of the test set is carried by bodies that no joint connects there (the
    two-bar chain's welded middle bar carries only its upper end)."""
    from sparsekin.model.shared_points import unjoined_points

    assert unjoined_points(build()) == []
