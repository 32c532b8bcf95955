"""The joints and drivers beyond the first three, and the elements' own coordinates,
against closed forms and against the same motion written with other elements.

* pin-in-slot: a Scotch yoke, whose yoke moves by r·cos θ;
* gear: a planetary train used as a differential, against Willis' formula;
* rack and pinion: a pinion rolling on a fixed rack, and a fixed pinion driving a rack:
  travel = radius × angle;
* distance driver: Task 5 with its actuators as distance drivers (no cylinder and rod
  bodies) moves as examples/task5.toml;
* path driver: Task 5 with its tool point K prescribed on the path the strokes give it
  returns those strokes (inverse kinematics);
* own coordinates: Task 5's strokes equal their laws, revolute rates equal five-point
  differences of the angles;
* limits: warned once per element and run, reported by `check_model`.

Closed forms are evaluated with NumPy alone; tolerances as in tests/test_closed_forms.py
(1e-10 relative to the scale of each quantity).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
from examples_loader import EXAMPLES
from helpers import assert_close, assert_same_motion

from sparsekin import (
    Body,
    Harmonic,
    LimitWarning,
    Linear,
    Mechanism,
    ModelError,
    PathDriver,
    PinInSlot,
    RackPinion,
    Revolute,
    RotationalDriver,
    Spline,
    Translational,
    check_model,
    load_model,
    solve_kinematics,
)
from sparsekin.testset import task5


# ---------------------------------------------------------------------- pin in slot
def scotch_yoke(radius=0.1, start=0.3, rate=2 * math.pi) -> Mechanism:
    """A crank whose pin A drives a yoke through a vertical slot; the yoke slides along x."""
    a = (radius * math.cos(start), radius * math.sin(start))
    return Mechanism(
        points={"O": (0.0, 0.0), "A": a, "Y": (a[0], 0.0)},
        bodies=[Body("crank", origin="O", angle=start, points=("O", "A")), Body("yoke", origin="Y", points=("Y",))],
        joints=[
            Revolute(("crank", "ground"), at="O"),
            Translational(("ground", "yoke"), at="Y", direction=(1.0, 0.0), name="guide"),
            PinInSlot(("yoke", "crank"), at="A", direction=(0.0, 1.0), name="slot"),
        ],
        drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=rate))],
        name="scotch_yoke",
    )


@pytest.mark.parametrize("linear_solver", ["auto", "superlu"])
def test_scotch_yoke_moves_its_yoke_by_r_cos_theta(linear_solver):
    radius, start, rate = 0.1, 0.3, 2 * math.pi
    times = np.linspace(0.0, 1.5, 301)
    result = solve_kinematics(scotch_yoke(radius, start, rate), times, linear_solver=linear_solver)
    theta = start + rate * times
    x = radius * np.array([np.cos(theta), -rate * np.sin(theta), -rate**2 * np.cos(theta)])
    y = radius * np.array([np.sin(theta), rate * np.cos(theta), -rate**2 * np.sin(theta)])
    yoke = result.point("Y")
    for order, (label, motion) in enumerate(zip(("position", "velocity", "acceleration"), yoke)):
        assert_close(motion[:, 0], x[order], err_msg=label)
        assert_close(motion[:, 1], 0.0 * x[order], err_msg=label, scale=np.max(np.abs(x[order])))
    # The yoke's own coordinate (the guide's stroke) and the pin's slide along the slot.
    stroke, slide = result.joint("guide"), result.joint("slot")
    for order in range(3):
        assert_close(stroke[order], x[order] - (order == 0) * x[0, 0])
        assert_close(slide[order], y[order] - (order == 0) * y[0, 0])


# ---------------------------------------------------------------------- gears
def test_planetary_train_follows_willis():
    """Sun and ring driven: (w_sun - w_carrier) / (w_ring - w_carrier) = -R_ring / R_sun."""
    sun, planet, ring = 0.10, 0.05, 0.20
    mechanism = load_model(EXAMPLES / "planetary_gear.toml")
    times = np.linspace(0.0, 2.0, 401)
    result = solve_kinematics(mechanism, times)
    theta_sun = np.array([2 * np.pi * times, np.full_like(times, 2 * np.pi), 0.0 * times])
    theta_ring = 0.5 * np.array([np.sin(3 * times), 3 * np.cos(3 * times), -9 * np.sin(3 * times)])
    theta_carrier = (sun * theta_sun + ring * theta_ring) / (sun + ring)  # Willis, angles from 0
    theta_planet = theta_carrier - sun / planet * (theta_sun - theta_carrier)
    np.testing.assert_allclose(
        (theta_sun[1] - theta_carrier[1]) / (theta_ring[1] - theta_carrier[1]), -ring / sun, rtol=1e-12
    )
    for name, expected in (("carrier", theta_carrier), ("planet", theta_planet)):
        column = 3 * mechanism.body_index(name) + 2
        for order, solved in enumerate((result.coordinates, result.velocities, result.accelerations)):
            assert_close(solved[:, column], expected[order], err_msg=f"{name} order {order}")
    # the planet's centre runs on a circle of radius sun + planet with the carrier
    arm = sun + planet
    c, s = np.cos(theta_carrier[0]), np.sin(theta_carrier[0])
    assert_close(result.point("P").position, arm * np.stack([c, s], axis=1))
    w, a = theta_carrier[1], theta_carrier[2]
    assert_close(result.point("P").acceleration, arm * np.stack([-a * s - w * w * c, a * c - w * w * s], axis=1))


def test_a_gear_against_the_ground_is_a_fixed_ring():
    """The ring welded to the ground: the carrier turns at R_sun / (R_sun + R_ring) of the sun."""
    mechanism = load_model(EXAMPLES / "planetary_gear.toml")
    fixed = replace(
        mechanism,
        bodies=tuple(body for body in mechanism.bodies if body.name != "ring"),
        joints=tuple(
            replace(joint, bodies=("planet", "ground")) if joint.name == "planet_ring" else joint
            for joint in mechanism.joints
            if "ring" not in joint.bodies or joint.name == "planet_ring"
        ),
        drivers=mechanism.drivers[:1],
    )
    result = solve_kinematics(fixed, np.linspace(0.0, 1.0, 101))
    carrier = 3 * fixed.body_index("carrier") + 2
    assert_close(result.velocities[:, carrier], np.full(101, 2 * np.pi * 0.1 / 0.3))


# ---------------------------------------------------------------------- rack and pinion
ROLL = Harmonic(amplitude=2.0, omega=1.5, offset=0.0)  # the pinion's angle, rad


def test_a_pinion_rolls_along_a_fixed_rack():
    radius = 0.05
    mechanism = Mechanism(
        points={"P": (0.0, radius)},
        bodies=[Body("pinion", origin="P", points=("P",))],
        joints=[
            PinInSlot(("ground", "pinion"), at="P", direction=(1.0, 0.0)),
            RackPinion(("ground", "pinion"), at="P", direction=(1.0, 0.0), radius=radius, name="mesh"),
        ],
        drivers=[RotationalDriver(("pinion", "ground"), law=ROLL)],
    )
    times = np.linspace(0.0, 4.0, 401)
    result = solve_kinematics(mechanism, times)
    theta = ROLL.evaluate(times, 0.0)
    for order, motion in enumerate(result.point("P")):
        assert_close(motion[:, 0], -radius * theta[order])  # travel = -radius × rotation
        assert_close(motion[:, 1], radius * (order == 0) + 0.0 * times, scale=radius * np.max(np.abs(theta[order])))


def test_a_fixed_pinion_drives_a_rack():
    radius = 0.08
    mechanism = Mechanism(
        points={"P": (0.0, 0.0), "R": (0.0, -radius)},
        bodies=[Body("pinion", origin="P", points=("P",)), Body("rack", origin="R", points=("R",))],
        joints=[
            Revolute(("pinion", "ground"), at="P"),
            Translational(("ground", "rack"), at="R", direction=(1.0, 0.0), name="rail"),
            RackPinion(("rack", "pinion"), at="P", direction=(1.0, 0.0), radius=radius),
        ],
        drivers=[RotationalDriver(("pinion", "ground"), law=ROLL)],
    )
    times = np.linspace(0.0, 4.0, 401)
    result = solve_kinematics(mechanism, times, linear_solver="superlu")
    theta = ROLL.evaluate(times, 0.0)
    for order, value in enumerate(result.joint("rail")):  # the rack's travel along its rail
        assert_close(value, radius * theta[order])


# ---------------------------------------------------------------------- distance and path drivers
#: The ends of Task 5's two actuators.
STROKE_ENDS = (("N", "M"), ("H", "G"))

@pytest.fixture(scope="module")
def task5_reference():
    times = np.linspace(0.0, 10.0, 1001)
    return times, solve_kinematics(load_model(EXAMPLES / "task5.toml"), times)


def test_task5_with_distance_drivers_moves_as_with_cylinders(task5_reference):
    times, reference = task5_reference
    mechanism = load_model(EXAMPLES / "task5_distance.toml")
    assert mechanism.n_bodies == 6 and check_model(mechanism).sound
    for linear_solver in ("auto", "refactor"):
        result = solve_kinematics(mechanism, times, linear_solver=linear_solver)
        for name in "ABDEFGIJKLM":
            np.testing.assert_allclose(result.point(name).position, reference.point(name).position, rtol=0, atol=1e-10)
        for name in "AJK":
            assert_same_motion(result.point(name), reference.point(name), labels=[f"{name} {label}" for label in
                               ("position", "velocity", "acceleration")])  # fmt: skip
        # the driven distances are what the strokes were
        for name in ("actuator1", "actuator2"):
            for solved, stroke in zip(result.driver(name), reference.joint(name)):
                assert_close(solved, stroke)


def test_a_prescribed_tool_path_gives_back_the_strokes():
    """Inverse kinematics: K follows the path the two strokes gave it; the strokes come back."""
    forward = task5()
    fine = np.linspace(0.0, 4.0, 4001)
    path = solve_kinematics(forward, fine).point("K").position
    inverse = replace(
        forward,
        drivers=(PathDriver("c1", "K", law_x=Spline(fine, path[:, 0]), law_y=Spline(fine, path[:, 1]), name="tool"),),
    )
    times = np.linspace(0.0, 4.0, 401)
    for linear_solver in ("auto", "superlu"):
        result = solve_kinematics(inverse, times, linear_solver=linear_solver)
        for driver, (start, end) in zip(forward.drivers, STROKE_ENDS):
            stroke = driver.law.evaluate(times, math.dist(forward.points[start], forward.points[end]))
            name = driver.joint
            np.testing.assert_allclose(result.joint(name).value, stroke[0], rtol=0, atol=1e-9)
            np.testing.assert_allclose(result.joint(name).rate, stroke[1], rtol=0, atol=1e-6)


# ---------------------------------------------------------------------- own coordinates
def test_task5_strokes_equal_their_laws(task5_reference):
    times, result = task5_reference
    mechanism = result.mechanism
    for driver, (start, end) in zip(mechanism.drivers, STROKE_ENDS):
        law = driver.law.evaluate(times, math.dist(mechanism.points[start], mechanism.points[end]))
        for order, value in enumerate(result.joint(driver.joint)):
            assert_close(value, law[order], err_msg=f"{driver.joint} order {order}")


def test_revolute_rates_are_differences_of_their_angles():
    step = 1e-3
    times = np.arange(0.0, 1.0 + step / 2, step)
    result = solve_kinematics(task5(), times)
    for index in range(12):  # the revolutes
        angle, rate, acceleration = result.joint(index)
        # five-point differences: truncation ~ h⁴ |angle⁽⁵⁾| / 30, rounding ~ 1e-16 / h
        first = (angle[:-4] - 8 * angle[1:-3] + 8 * angle[3:-1] - angle[4:]) / (12 * step)
        second = (-angle[:-4] + 16 * angle[1:-3] - 30 * angle[2:-2] + 16 * angle[3:-1] - angle[4:]) / (12 * step**2)
        assert_close(rate[2:-2], first, rtol=1e-8)
        assert_close(acceleration[2:-2], second, rtol=1e-5)
        body_i, body_j = (task5().body_index(name) for name in task5().joints[index].bodies)
        angle_i = result.coordinates[:, 3 * body_i + 2] if body_i >= 0 else 0.0
        angle_j = result.coordinates[:, 3 * body_j + 2] if body_j >= 0 else 0.0
        np.testing.assert_array_equal(angle, angle_i - angle_j)


def test_an_element_without_an_own_coordinate_is_named():
    mechanism = load_model(EXAMPLES / "planetary_gear.toml")
    result = solve_kinematics(mechanism, [0.0, 0.1])
    with pytest.raises(KeyError, match=r"joints\[4\] is gear, which has no coordinate of its own"):
        result.joint("sun_planet")
    with pytest.raises(KeyError, match=r'unknown joint "axle": expected a name'):
        result.joint("axle")
    assert result.joint_names == ("joints[0]", "joints[1]", "carrier_axis", "planet_axis")


def test_an_element_asked_twice_has_one_output_row_with_its_own_rates():
    from sparsekin.engine.outputs import own_coordinates
    from sparsekin.engine.pattern import build_output_pattern

    mechanism = scotch_yoke()
    times = np.linspace(0.0, 0.5, 11)
    result = solve_kinematics(mechanism, times)
    states = result.coordinates, result.velocities, result.accelerations
    once = build_output_pattern(mechanism, joints=[1])
    twice = build_output_pattern(mechanism, joints=[1, 1, -2], drivers=[0, 0])  # -2 is joints[1] again
    assert (once.n_rows, twice.n_rows) == (1, 2)
    for row in range(twice.n_rows):  # no entry of a row given twice
        columns = twice.indices[twice.indptr[row] : twice.indptr[row + 1]]
        assert columns.size == np.unique(columns).size
    for got, want in zip(own_coordinates(twice, *states), result.joint("guide")):
        np.testing.assert_allclose(got[:, 0], want, rtol=0, atol=1e-12)  # the stroke's rate, not twice it
    for got, want in zip(own_coordinates(twice, *states), result.driver(0)):
        np.testing.assert_allclose(got[:, 1], want, rtol=0, atol=1e-12)
    for got, want in zip(own_coordinates(once, *states), own_coordinates(twice, *states)):
        np.testing.assert_array_equal(got[:, 0], want[:, 0])


def test_a_driver_may_not_take_a_joints_name():
    mechanism = scotch_yoke()
    with pytest.raises(ModelError, match=r'^drivers\[0\]\.name: driver name "guide" is also the name of joints\[1\]: '
                                         r"joints and drivers need distinct names$"):  # fmt: skip
        replace(mechanism, drivers=[PathDriver("crank", "A", law_x=Linear(rate=0.0), law_y=Linear(rate=0.1), name="guide")])
    renamed = replace(mechanism, drivers=[replace(mechanism.drivers[0], name="motor")])
    assert renamed.drivers[0].name == "motor"


# ---------------------------------------------------------------------- limits
def task5_with_limits(low: float, high: float) -> Mechanism:
    mechanism = task5()
    joints = tuple(replace(joint, limits=(low, high)) if joint.name == "actuator1" else joint for joint in mechanism.joints)
    return replace(mechanism, joints=joints)


def test_leaving_the_limits_warns_once_with_the_first_time_outside():
    times = np.linspace(0.0, 10.0, 1001)
    stroke0 = math.dist((0.4, -0.2), (0.2, 0.6))
    with pytest.warns(LimitWarning) as caught:
        result = solve_kinematics(task5_with_limits(0.70, stroke0 + 0.04), times)
    assert len(caught) == 1
    outside = np.flatnonzero(result.joint("actuator1").value > stroke0 + 0.04)[0]
    # stroke0 + 0.05 sin(1.5 t) > stroke0 + 0.04 from t = asin(0.8) / 1.5 = 0.618 s
    assert times[outside] == pytest.approx(math.asin(0.8) / 1.5, abs=0.01)
    message = str(caught[0].message)
    assert message.startswith('joints[12] "actuator1" (translational c8–c7 along N→M) left its limits: stroke ')
    assert f"at t = {times[outside]:.6g} s, outside [0.7, {stroke0 + 0.04:g}]" in message


def test_staying_within_the_limits_is_silent_and_check_reports_them():
    with warnings.catch_warnings():
        warnings.simplefilter("error", LimitWarning)
        solve_kinematics(task5_with_limits(0.7, 0.9), np.linspace(0.0, 10.0, 101))
    report = check_model(task5_with_limits(0.7, 0.9))
    assert [str(state) for state in report.limits] == [
        'joints[12] "actuator1" (translational c8–c7 along N→M): stroke 0.824621 m at t = 0 s, within its limits '
        "[0.7, 0.9]"
    ]
    assert "limits: 1 element" in str(report)
    outside = check_model(task5_with_limits(0.9, 1.0))
    assert not outside.sound and "outside its limits" in str(outside)
