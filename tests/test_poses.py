"""A solved pose as the drawing of a new model (`pose_model`, ``run --save-pose``), and copies
drawn once but started at other phases of their crank (assembled along a path from the
drawing): a twelve-leg walking machine from one drawn leg."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers import assert_close, assert_same_motion
from jansen import jansen_leg, jansen_points

from sparsekin import (
    Body,
    Cycle,
    Harmonic,
    Mechanism,
    ModelError,
    Repeat,
    Revolute,
    RotationalDriver,
    Translational,
    TranslationalDriver,
    Unit,
    solve_kinematics,
)
from sparsekin.cli import main
from sparsekin.model.laws import Linear, Polynomial, Spline
from sparsekin.model.modelfile import load_model, save_model
from sparsekin.model.poses import shifted_law
from sparsekin.solve.poses import pose_model

TIMES = np.linspace(0.0, 2.0 * math.pi, 49)


@pytest.mark.parametrize("law", [
    Linear(rate=0.7), Harmonic(amplitude=0.3, omega=2.0, phase=0.1),
    Polynomial((None, 0.5, -0.25, 0.125)), Spline(times=(0.0, 1.0, 2.0, 3.0), values=(0.0, 1.0, 0.5, 2.0), offset=None),
])  # fmt: skip
def test_a_shifted_law_is_the_law_later(law):
    initial, shift = 0.4, 0.75
    later = shifted_law(law, shift, initial)
    t = np.linspace(0.0, 1.5, 7)
    for mine, theirs in zip(later.evaluate(t, 99.0), law.evaluate(t + shift, initial)):
        assert_close(mine, theirs, 1e-13)


def test_a_pose_saved_at_t_runs_on_as_the_original_run_from_t(tmp_path):
    leg = jansen_leg()
    run = solve_kinematics(leg, TIMES)
    k = 17
    path = tmp_path / "pose.toml"
    save_model(pose_model(run, TIMES[k]), path)
    later = solve_kinematics(load_model(path), TIMES[k:] - TIMES[k])
    assert_same_motion([later.coordinates, later.velocities, later.accelerations],
                       [run.coordinates[k:], run.velocities[k:], run.accelerations[k:]], 1e-10)  # fmt: skip
    assert later.newton_iterations[0] == 0  # the drawing is the pose: nothing to assemble


def test_a_pose_between_samples_is_solved_there():
    leg = jansen_leg()
    run = solve_kinematics(leg, TIMES[:5])
    middle = 0.5 * (TIMES[1] + TIMES[2])
    posed = pose_model(run, middle)
    reference = jansen_points(math.atan2(leg.points["A"][1], leg.points["A"][0]) + middle)
    assert_close(np.array(posed.points["G"]), reference["G"][0], 1e-10)
    with pytest.raises(ValueError, match="within the run"):
        pose_model(run, 10.0)


def test_the_exact_drawing_of_a_rough_one_has_the_lengths_between_its_points():
    posed = pose_model(solve_kinematics(jansen_leg(), TIMES[:2]), 0.0)
    for body in posed.bodies:
        for a, b, length in body.lengths:
            assert math.dist(posed.points[a], posed.points[b]) == pytest.approx(length, abs=1e-10)


def test_a_point_two_bodies_separate_cannot_be_drawn():
    """A telescope: the inner tube slides out of the outer one along their shared point P."""
    telescope = Mechanism(
        points={"O": (0.0, 0.0), "P": (1.0, 0.0)},
        bodies=[Body("outer", origin="O", points=("O", "P")), Body("inner", origin="P", points=("P",))],
        joints=[Revolute(("outer", "ground"), at="O"),
                Translational(("outer", "inner"), at="P", direction=(1.0, 0.0), name="slide")],
        drivers=[RotationalDriver(("outer", "ground"), law=Linear(rate=1.0)),
                 TranslationalDriver("slide", law=Linear(rate=0.5))],
    )  # fmt: skip
    run = solve_kinematics(telescope, [0.0, 1.0])
    assert pose_model(run, 0.0).points["P"] == (1.0, 0.0)
    with pytest.raises(ModelError, match=r"points\.P: carried by outer and inner, which are 0\.5 m apart"):
        pose_model(run, 1.0)


def test_run_saves_the_pose_from_the_command_line(tmp_path, capsys):
    path = tmp_path / "leg.toml"
    save_model(jansen_leg(), path)
    pose = tmp_path / "pose.toml"
    assert main(["run", str(path), "--t-end", "1", "--steps", "5", "--points", "G", "--out", str(tmp_path / "out"),
                 "--quiet", "--save-pose", "0.5", str(pose)]) == 0  # fmt: skip
    assert str(pose) in capsys.readouterr().out
    exact = load_model(pose)
    reference = jansen_points(math.atan2(*np.array(load_model(path).points["A"])[::-1]) + 0.5)
    assert_close(np.array(exact.points["G"]), reference["G"][0], 1e-10)
    assert main(["run", str(path), "--save-pose", "x", str(pose)]) == 2


def _machine(legs: int = 12) -> Mechanism:
    """Twelve legs from one drawn leg: a unit drawn once, and its mirror image (the same
    drawing with x negated); each repeated over three throws 120° apart (`vary` of the
    crank law's start), twice (front and back), every copy assembled at its phase."""
    leg = jansen_leg()
    units = []
    for mirrored in (False, True):
        sign = -1.0 if mirrored else 1.0
        points = {name: (sign * x, y) for name, (x, y) in leg.points.items()}
        rate = -1.0 if mirrored else 1.0  # the mirror image of a crank turning counter-clockwise
        drivers = (dataclasses.replace(leg.drivers[0], law=Linear(rate=rate, start=0.0)),)
        units.append(Unit("mirrored" if mirrored else "leg", points=points, bodies=leg.bodies, joints=leg.joints,
                          drivers=drivers))  # fmt: skip
    throws = [0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0]
    repeats = [Repeat(units[0], count=legs // 2, prefix="r", vary={"drivers[0].law.start": Cycle(throws)}),
               Repeat(units[1], count=legs // 2, prefix="l", vary={"drivers[0].law.start": Cycle([-t for t in throws])})]
    return Mechanism(points={}, bodies=(), repeats=tuple(repeats), name="walker")


def test_twelve_legs_from_one_drawn_leg_each_foot_at_its_phase():
    machine = _machine()
    times = np.linspace(0.0, 2.0 * math.pi, 25)
    run = solve_kinematics(machine, times)
    leg = jansen_leg()
    drawn = math.atan2(leg.points["A"][1], leg.points["A"][0])
    single = solve_kinematics(leg, np.linspace(0.0, 4.0 * math.pi, 49))  # the single leg, two turns
    for k in range(6):
        shift = [0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0][k % 3]
        at = np.searchsorted(single.times, shift - 1e-12)
        foot = single.point("G").position[at : at + times.size]
        assert_close(run.point(f"r{k}.G").position, foot, 1e-9 / 100, err_msg=f"r{k}")
        mirrored = foot * np.array([-1.0, 1.0])
        assert_close(run.point(f"l{k}.G").position, mirrored, 1e-9 / 100, err_msg=f"l{k}")
    exact = jansen_points(drawn + times + 2.0 * math.pi / 3.0)["G"]
    np.testing.assert_allclose(run.point("r1.G").position, exact, rtol=0.0, atol=1e-9)


def test_the_pose_of_a_grid_runs_on_as_the_grid():
    """A repeat's copies are written one by one; their equations, laid out kind by kind in
    the grid and copy by copy in the posed model, are compared row by row."""
    from examples_loader import EXAMPLES

    grid = load_model(EXAMPLES / "lattice.toml")
    times = np.linspace(0.0, 0.5, 6)
    run = solve_kinematics(grid, times)
    later = solve_kinematics(pose_model(run, times[3]), times[3:] - times[3])
    assert_same_motion([later.coordinates, later.velocities, later.accelerations],
                       [run.coordinates[3:], run.velocities[3:], run.accelerations[3:]], 1e-10)  # fmt: skip
