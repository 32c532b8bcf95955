"""What ``check`` (and ``load_model``) tell a modeller: laws away from the drawing at t = 0,
the direction of each actuator's stroke, points carried by bodies that no joint connects.

References: a harmonic law's value at t = 0 (offset + amplitude · sin(phase)); the
distance between an actuator's pins along a solved motion; the topology written in the
test.
"""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
from examples_loader import EXAMPLES

from sparsekin import UnjoinedPointWarning, check_model, load_model, solve_kinematics
from sparsekin.model.shared_points import unjoined_points

EXCAVATOR = (EXAMPLES / "excavator.toml").read_text()


def write(tmp_path, text: str, name: str = "model.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", sorted(path.stem for path in EXAMPLES.glob("*.toml")))
def test_the_examples_load_without_an_unjoined_point(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnjoinedPointWarning)
        mechanism = load_model(EXAMPLES / f"{name}.toml")
    assert unjoined_points(mechanism) == []


def test_a_phase_is_reported_as_the_distance_of_the_law_from_the_drawing(tmp_path):
    amplitude, phase = 0.3, 0.7
    text = EXCAVATOR.replace(
        "amplitude = 0.3, omega = 0.7853981633974483 }",
        f"amplitude = {amplitude}, omega = 0.7853981633974483, phase = {phase} }}",
    )
    report = check_model(load_model(write(tmp_path, text)))
    (line,) = report.law_offsets
    assert line.startswith('drivers[1] "stick_stroke" (stroke of joint "stick_actuator"): law ')
    away = float(re.search(r"law ([-+][0-9.e+-]+) m from the drawing at t = 0 s", line)[1])
    assert away == pytest.approx(amplitude * math.sin(phase), rel=1e-5)  # printed to 6 digits
    assert "laws away from the drawing at t = 0 s (the pose then is not the drawing):" in str(report)
    assert check_model(load_model(EXAMPLES / "excavator.toml")).law_offsets == ()


def test_a_spline_of_absolute_values_away_from_the_drawing_is_reported(tmp_path):
    text = EXCAVATOR.replace(
        'law = { type = "harmonic", amplitude = 0.2, omega = 0.7853981633974483 }',
        'law = { type = "spline", times = [0.0, 4.0, 8.0], values = [1.0, 1.2, 1.0] }',
    )
    mechanism = load_model(write(tmp_path, text))
    drawn = math.dist((5.3, 3.0), (6.15, 1.05))  # K1 to G: the bucket stroke in the drawing
    (line,) = check_model(mechanism).law_offsets
    away = float(re.search(r"law ([-+][0-9.e+-]+) m", line)[1])
    assert line.startswith('drivers[2] "bucket_stroke"') and away == pytest.approx(1.0 - drawn, rel=1e-5)
    relative = write(tmp_path, text.replace("values = [1.0, 1.2, 1.0] }", 'values = [0.0, 0.2, 0.0], offset = "initial" }'),
                     "relative.toml")  # fmt: skip
    assert check_model(load_model(relative)).law_offsets == ()


def pin_distance(result, mechanism, first: str, second: str) -> np.ndarray:
    return np.hypot(*(result.point(second).position - result.point(first).position).T)


def test_a_swapped_axis_is_reported_as_a_retracting_stroke_and_retracts(tmp_path):
    swapped = EXCAVATOR.replace('axis = ["C1", "B1"]', 'axis = ["B1", "C1"]')
    for text, extends in ((EXCAVATOR, True), (swapped, False)):
        mechanism = load_model(write(tmp_path, text))
        line = check_model(mechanism).actuator_directions[0]
        assert line.startswith('drivers[0] "boom_stroke": a growing stroke of joint "boom_actuator"')
        assert ("pushes its pins C1 and B1 apart (extends)" in line) is extends
        assert ("pulls its pins C1 and B1 together (RETRACTS)" in line) is not extends
        # the claim, against the motion: while the stroke grows, the pins move apart or together
        times = np.linspace(0.0, 1.0, 11)
        result = solve_kinematics(mechanism, times, joints=["boom_actuator"])
        stroke = result.joint("boom_actuator").value
        distance = np.hypot(*(result.point("B1").position - np.array([0.7, 1.1])).T)  # C1 is on the ground
        assert np.all(np.sign(np.diff(distance)) == np.sign(np.diff(stroke)) * (1 if extends else -1))


def test_distance_drivers_and_cylinders_extend_with_a_growing_value():
    lines = check_model(load_model(EXAMPLES / "task5_distance.toml")).actuator_directions
    assert lines and all("apart (extends)" in line for line in lines)


def without_the_rod_pin(text: str) -> str:
    block = '[[joints]]\ntype = "revolute"\nbodies = ["boom_rod", "boom"]\nat = "B1"\n'
    assert block in text
    return text.replace(block, "")


def test_a_point_on_two_bodies_without_a_joint_there_is_warned_at_load_and_in_check(tmp_path):
    path = write(tmp_path, without_the_rod_pin(EXCAVATOR))
    with pytest.warns(UnjoinedPointWarning, match=r'model\.toml: point "B1" is carried by boom and boom_rod, which no '
                                                  r"joint connects there"):  # fmt: skip
        mechanism = load_model(path)
    report = check_model(mechanism)
    assert report.unjoined_points == ('point "B1" is carried by boom and boom_rod, which no joint connects there',)
    assert "warning: points carried by bodies no joint connects there (1):" in str(report)


def test_bodies_joined_at_a_point_through_others_or_the_ground_are_connected(tmp_path):
    # G rides on the rocker, the link and the bucket cylinder's rod: rod–rocker and
    # rocker–link revolutes at G connect all three, though the rod and the link share none.
    assert "G" in [p for body in load_model(EXAMPLES / "excavator.toml").bodies for p in body.points]
    text = """
[points]
P = [0.0, 0.0]
A = [1.0, 0.0]
[bodies.a]
origin = "P"
points = ["P", "A"]
[bodies.b]
origin = "P"
points = ["P"]
[bodies.c]
origin = "A"
points = ["A"]
[[joints]]
type = "revolute"
bodies = ["a", "ground"]
at = "P"
[[joints]]
type = "revolute"
bodies = ["ground", "b"]
at = "P"
[[joints]]
type = "rigid"
bodies = ["c", "a"]
"""
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnjoinedPointWarning)
        assert unjoined_points(load_model(write(tmp_path, text))) == []


def test_a_unit_is_checked_once_and_named(tmp_path):
    text = """
[units.bay.points]
P = [0.0, 0.0]
Q = [0.0, 1.0]
[units.bay.bodies.post]
origin = "P"
points = ["P", "Q"]
[units.bay.bodies.arm]
origin = "Q"
points = ["Q"]
[[units.bay.joints]]
type = "revolute"
bodies = ["post", "ground"]
at = "P"
[[units.bay.joints]]
type = "revolute"
bodies = ["arm", "post"]
at = "P"
[[repeat]]
unit = "bay"
count = 1000
offset = [1.0, 0.0]
"""
    with pytest.warns(UnjoinedPointWarning, match=r'point "Q" in units\.bay is carried by post and arm'):
        mechanism = load_model(write(tmp_path, text))
    assert [str(point) for point in unjoined_points(mechanism)] == [
        'point "Q" in units.bay is carried by post and arm, which no joint connects there'
    ]


def test_a_point_listed_twice_by_one_body_is_not_shared(tmp_path):
    text = '[points]\nP = [0.0, 0.0]\n[bodies.a]\norigin = "P"\npoints = ["P", "P"]\n'
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnjoinedPointWarning)
        assert unjoined_points(load_model(write(tmp_path, text))) == []
