"""The gallery: every model file of ``examples/`` is sound and runs its whole analysis, and
each mechanism moves as an independent reference says.

References, each written here from the geometry of the file, never from the solver:

* slider-crank: the closed form of the slider's position and its stroke;
* four-bar (Grashof crank-rocker): the rocker's angle from two circles at every sample,
  and its extreme positions from the law of cosines (crank and coupler in line), where
  its speed must vanish;
* Watt six-bar: the output angle from two circle intersections in turn;
* quick-return: the crank angles where the lever is tangent to the crank circle give the
  ram's extremes, its stroke 2 L r / d and the time ratio of the two strokes;
* excavator: the boom and stick angles from the law of cosines on the cylinder lengths,
  and the bucket tip against the same machine written with distance drivers.

* rotating rectangles: every rectangle's centre and angle from the closed form of the
  lattice's opening, and Poisson's ratio from it.
* Jansen's leg (link lengths on a drawing rounded to whole units): every joint from circle
  intersections (tests/jansen.py); the Strandbeest: every foot of its twelve legs from the
  same, shifted by its throw (mirrored for the mirrored legs).

(Task 5 is checked against ADAMS in test_task5.py, the planetary gear train against
Willis' formula in test_elements.py; the rotating squares and the lattice against their
closed forms and the same mechanisms written by hand in test_grids.py.)
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
from examples_loader import EXAMPLES

from sparsekin import DistanceDriver, Harmonic, RedundantConstraintWarning, check_model, load_model, solve_kinematics

GALLERY = sorted(path.stem for path in EXAMPLES.glob("*.toml"))
#: Lattices of rectangles hinged at their corners are over-constrained by design: an
#: ni × nj lattice has (ni − 2)·(nj − 2) states of self-stress (Maxwell–Calladine: 2 per
#: hinge, 2(ni−1)nj + 2ni(nj−1) of them, plus 4 for ground and driver, against 3·ni·nj
#: coordinates of full rank).  Their runs leave those equations out, with a warning.
SELF_STRESSED = {"rotating_squares": (8 - 2) * (8 - 2), "rotating_rectangles": (6 - 2) * (4 - 2)}


def circle_intersection(centre0, radius0, centre1, radius1, sign):
    """The intersection of two circles on the left (sign +1) or right (-1) of centre0 → centre1.

    Centres may be arrays of shape (n, 2).
    """
    centre0, centre1 = np.broadcast_arrays(np.asarray(centre0, float), np.asarray(centre1, float))
    between = centre1 - centre0
    distance = np.hypot(between[..., 0], between[..., 1])
    along = (radius0**2 - radius1**2 + distance**2) / (2 * distance)
    height = np.sqrt(radius0**2 - along**2)
    unit = between / distance[..., None]
    normal = np.stack([-unit[..., 1], unit[..., 0]], axis=-1)
    return centre0 + along[..., None] * unit + sign * height[..., None] * normal


def side(origin, first, second) -> float:
    """+1 if `second` is counter-clockwise from `first` seen from `origin`, else -1."""
    a, b = np.subtract(first, origin), np.subtract(second, origin)
    return float(np.sign(a[0] * b[1] - a[1] * b[0]))


def direction_angle(vectors) -> np.ndarray:
    vectors = np.asarray(vectors, float)
    return np.arctan2(vectors[..., 1], vectors[..., 0])


def law_of_cosines_angle(a: float, b: float, opposite) -> np.ndarray:
    """The angle between sides `a` and `b` of a triangle whose third side is `opposite`."""
    return np.arccos((a**2 + b**2 - np.asarray(opposite) ** 2) / (2 * a * b))


@pytest.mark.parametrize("name", GALLERY)
def test_every_example_is_sound_and_runs_its_analysis(name):
    mechanism = load_model(EXAMPLES / f"{name}.toml")
    report, redundant = check_model(mechanism), SELF_STRESSED.get(name, 0)
    assert len(report.redundant) == redundant and report.problems == ((f"{redundant} redundant equations",) if redundant
                                                                      else ())  # fmt: skip
    analysis = mechanism.analysis
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no redundant joint left out (but by design), no limit left
        if redundant:
            warnings.simplefilter("ignore", RedundantConstraintWarning)
        result = solve_kinematics(mechanism, np.linspace(0.0, analysis.t_end, analysis.steps))
    assert result.complete and result.n_times == analysis.steps


# ---------------------------------------------------------------------- slider-crank
def test_slider_crank_follows_its_closed_form():
    mechanism = load_model(EXAMPLES / "slider_crank.toml")
    points = mechanism.points
    crank = math.dist(points["O"], points["A"])
    rod = math.dist(points["A"], points["B"])
    offset = points["B"][1] - points["O"][1]
    times = np.linspace(0.0, 1.0, 361)
    theta = 2 * np.pi * times  # the file's law: one turn a second from the drawing (θ = 0)
    expected_x = crank * np.cos(theta) + np.sqrt(rod**2 - (crank * np.sin(theta) - offset) ** 2)
    position = solve_kinematics(mechanism, times).point("B").position
    np.testing.assert_allclose(position[:, 0], expected_x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(position[:, 1], offset, rtol=0, atol=1e-12)
    # the stroke, between the extended and the folded dead centres
    stroke = math.sqrt((rod + crank) ** 2 - offset**2) - math.sqrt((rod - crank) ** 2 - offset**2)
    dead_centres = np.array([math.asin(offset / (rod + crank)), math.pi + math.asin(offset / (rod - crank))])
    at_dead_centres = solve_kinematics(mechanism, np.union1d(times, dead_centres / (2 * np.pi)))
    samples = np.searchsorted(at_dead_centres.times, dead_centres / (2 * np.pi))
    slider = at_dead_centres.point("B")
    assert slider.position[samples[0], 0] - slider.position[samples[1], 0] == pytest.approx(stroke, abs=1e-12)
    np.testing.assert_allclose(slider.velocity[samples, 0], 0.0, atol=1e-10)


# ---------------------------------------------------------------------- four-bar and six-bar
def four_bar_dimensions(points):
    return {
        "ground": math.dist(points["O2"], points["O4"]),
        "crank": math.dist(points["O2"], points["A"]),
        "coupler": math.dist(points["A"], points["B"]),
        "rocker": math.dist(points["O4"], points["B"]),
    }


def test_four_bar_is_a_grashof_crank_rocker():
    links = four_bar_dimensions(load_model(EXAMPLES / "four_bar.toml").points)
    lengths = sorted(links.values())
    assert lengths[0] + lengths[3] < lengths[1] + lengths[2]  # Grashof
    assert min(links, key=links.get) == "crank"  # the shortest link turns all the way round


def test_four_bar_rocker_follows_two_circles_and_stops_where_crank_and_coupler_line_up():
    mechanism = load_model(EXAMPLES / "four_bar.toml")
    points = mechanism.points
    links = four_bar_dimensions(points)
    o2, o4 = np.array(points["O2"]), np.array(points["O4"])
    branch = side(points["A"], points["O4"], points["B"])
    # the rocker's extreme positions: B at crank + coupler or coupler - crank from O2
    extremes = []
    for reach, crank_turn in (
        (links["crank"] + links["coupler"], 0.0),
        (links["coupler"] - links["crank"], np.pi),
    ):
        opening = law_of_cosines_angle(links["ground"], links["rocker"], reach)  # angle at O4
        b = o4 + links["rocker"] * np.array([math.cos(math.pi - opening), math.sin(math.pi - opening)])
        crank_angle = (direction_angle(b - o2) + crank_turn) % (2 * np.pi)
        extremes.append((crank_angle / (2 * np.pi), math.pi - opening))  # (time, rocker direction)
    times = np.union1d(np.linspace(0.0, 1.0, 181), [time for time, _ in extremes])
    result = solve_kinematics(mechanism, times)
    crank_angle = 2 * np.pi * times
    pin_a = o2 + links["crank"] * np.stack([np.cos(crank_angle), np.sin(crank_angle)], axis=1)
    expected_b = circle_intersection(pin_a, links["coupler"], o4, links["rocker"], branch)
    np.testing.assert_allclose(result.point("B").position, expected_b, rtol=0, atol=1e-12)
    rocker = result.point("B")
    for time, rocker_direction in extremes:
        k = int(np.searchsorted(times, time))
        assert direction_angle(rocker.position[k] - o4) == pytest.approx(rocker_direction, abs=1e-12)
        np.testing.assert_allclose(rocker.velocity[k], 0.0, atol=1e-9)  # a dead point of the rocker
    swing = direction_angle(rocker.position - o4)
    assert swing.min() >= extremes[0][1] - 1e-12 and swing.max() <= extremes[1][1] + 1e-12


def test_watt_six_bar_output_follows_two_four_bars_in_turn():
    mechanism = load_model(EXAMPLES / "watt_six_bar.toml")
    p = {name: np.array(xy) for name, xy in mechanism.points.items()}
    links = four_bar_dimensions(mechanism.points)
    times = np.linspace(0.0, 1.0, 361)
    crank_angle = 2 * np.pi * times
    pin_a = p["O2"] + links["crank"] * np.stack([np.cos(crank_angle), np.sin(crank_angle)], axis=1)
    pin_b = circle_intersection(
        pin_a, links["coupler"], p["O4"], links["rocker"], side(p["A"], p["O4"], p["B"])
    )
    rocker_turn = direction_angle(pin_b - p["O4"]) - direction_angle(p["B"] - p["O4"])
    c0 = p["C"] - p["O4"]
    pin_c = p["O4"] + np.stack([np.cos(rocker_turn) * c0[0] - np.sin(rocker_turn) * c0[1],
                                np.sin(rocker_turn) * c0[0] + np.cos(rocker_turn) * c0[1]], axis=1)  # fmt: skip
    pin_d = circle_intersection(
        pin_c, math.dist(p["C"], p["D"]), p["O6"], math.dist(p["O6"], p["D"]), side(p["C"], p["O6"], p["D"])
    )
    result = solve_kinematics(mechanism, times)
    np.testing.assert_allclose(result.point("D").position, pin_d, rtol=0, atol=1e-12)
    output_angle = result.joint("output_pivot").value  # angle(output) - angle(ground)
    np.testing.assert_allclose(output_angle, direction_angle(pin_d - p["O6"]) - direction_angle(p["D"] - p["O6"]),
                               rtol=0, atol=1e-11)  # fmt: skip


# ---------------------------------------------------------------------- quick-return
def test_quick_return_stroke_and_time_ratio():
    mechanism = load_model(EXAMPLES / "quick_return.toml")
    p = {name: np.array(xy) for name, xy in mechanism.points.items()}
    crank, centres, lever = (
        math.dist(p["O2"], p["A"]),
        math.dist(p["O2"], p["O4"]),
        math.dist(p["O4"], p["T"]),
    )
    rate = -np.pi  # the file's crank law, rad/s, from θ = 0 (A level with O2)
    # the lever is at an extreme when it is tangent to the crank circle: sin θ = -r/d
    tangent = np.array([-math.asin(crank / centres), math.pi + math.asin(crank / centres)])
    period = 2 * np.pi / abs(rate)
    extreme_times = np.sort((tangent / rate) % period)
    times = np.union1d(np.linspace(0.0, period, 721), extreme_times)
    result = solve_kinematics(mechanism, times)
    ram = result.point("R")
    k = np.searchsorted(times, extreme_times)
    stroke = 2 * lever * crank / centres
    assert abs(ram.position[k[0], 0] - ram.position[k[1], 0]) == pytest.approx(stroke, abs=1e-12)
    np.testing.assert_allclose(ram.velocity[k, 0], 0.0, atol=1e-9)
    assert ram.position[:, 0].min() >= ram.position[k, 0].min() - 1e-12  # no sample goes beyond them
    assert ram.position[:, 0].max() <= ram.position[k, 0].max() + 1e-12
    quick = extreme_times[1] - extreme_times[0]
    assert quick * abs(rate) == pytest.approx(2 * math.acos(crank / centres), abs=1e-12)
    assert (period - quick) / quick == pytest.approx(1.552, abs=1e-3)  # the time ratio of a shaper
    # between the extremes the ram moves one way only
    assert np.all(np.diff(ram.position[k[0] : k[1] + 1, 0]) * np.sign(ram.velocity[k[0] + 1, 0]) > 0)


# ---------------------------------------------------------------------- excavator
def excavator_stroke(mechanism, name: str, times) -> np.ndarray:
    """The stroke a driver of the file prescribes: its drawn length + amplitude · sin(ω t)."""
    driver = next(d for d in mechanism.drivers if d.name == name)
    start, end = mechanism.joint_named(driver.joint).axis
    law = driver.law
    return math.dist(mechanism.points[start], mechanism.points[end]) + law.amplitude * np.sin(
        law.omega * times
    )


def test_excavator_boom_and_stick_follow_the_law_of_cosines():
    mechanism = load_model(EXAMPLES / "excavator.toml")
    p = {name: np.array(xy) for name, xy in mechanism.points.items()}
    times = np.linspace(0.0, 8.0, 401)
    result = solve_kinematics(mechanism, times)

    def turn(pivot, fixed_point, moving_point, length):
        a, b = math.dist(p[pivot], p[fixed_point]), math.dist(p[pivot], p[moving_point])
        gamma = law_of_cosines_angle(a, b, length)
        return side(p[pivot], p[fixed_point], p[moving_point]) * (gamma - gamma[0])

    boom = turn("P", "C1", "B1", excavator_stroke(mechanism, "boom_stroke", times))
    stick = turn("Q", "S1", "S2", excavator_stroke(mechanism, "stick_stroke", times))  # relative to the boom
    np.testing.assert_allclose(result.joint("boom_foot").value, boom, rtol=0, atol=1e-10)
    np.testing.assert_allclose(result.joint("stick_pivot").value, stick, rtol=0, atol=1e-10)

    def rotated(vector, angle):
        return np.stack([np.cos(angle) * vector[0] - np.sin(angle) * vector[1],
                         np.sin(angle) * vector[0] + np.cos(angle) * vector[1]], axis=1)  # fmt: skip

    q = p["P"] + rotated(p["Q"] - p["P"], boom)
    r = q + rotated(p["R"] - p["Q"], boom + stick)
    np.testing.assert_allclose(result.point("R").position, r, rtol=0, atol=1e-10)


def test_excavator_with_distance_drivers_moves_the_same():
    """The same machine with each cylinder and its rod replaced by a distance driver
    between their pins: the bucket tip follows the same path."""
    mechanism = load_model(EXAMPLES / "excavator.toml")
    actuators = {joint.name: joint for joint in mechanism.joints if joint.type_name == "translational"}
    cylinder_bodies = {body for joint in actuators.values() for body in joint.bodies}
    pinned = {}  # the body each cylinder or rod is pinned to, and where
    for joint in mechanism.joints:
        if joint.type_name == "revolute" and cylinder_bodies & set(joint.bodies):
            own, other = joint.bodies if joint.bodies[0] in cylinder_bodies else joint.bodies[::-1]
            pinned[own] = other
    drivers = []
    for driver in mechanism.drivers:
        joint = actuators[driver.joint]
        drivers.append(DistanceDriver(points=joint.axis, bodies=(pinned[joint.bodies[0]], pinned[joint.bodies[1]]),
                                      law=Harmonic(amplitude=driver.law.amplitude, omega=driver.law.omega)))  # fmt: skip
    distance_version = replace(
        mechanism,
        bodies=tuple(body for body in mechanism.bodies if body.name not in cylinder_bodies),
        joints=tuple(joint for joint in mechanism.joints if not cylinder_bodies & set(joint.bodies)),
        drivers=tuple(drivers),
    )
    assert distance_version.n_bodies == mechanism.n_bodies - 6
    times = np.linspace(0.0, 8.0, 401)
    with_cylinders = solve_kinematics(mechanism, times).point("T")
    with_distances = solve_kinematics(distance_version, times).point("T")
    for field in ("position", "velocity", "acceleration"):
        np.testing.assert_allclose(getattr(with_distances, field), getattr(with_cylinders, field),
                                   rtol=0, atol=1e-9)  # fmt: skip


# ---------------------------------------------------------------------- rotating rectangles
def test_rotating_rectangles_open_as_their_closed_form_with_their_poisson_ratio():
    from sparsekin.plots.metamaterials import lattice_size

    mechanism = load_model(EXAMPLES / "rotating_rectangles.toml")
    ni, nj = mechanism.repeats[0].count
    unit = mechanism.repeats[0].unit
    corner = unit.points["ur"]  # (w/2, h/2) turned by the drawn angle θ0 of rectangle (0, 0)
    theta0 = unit.bodies[0].angle
    half_width = math.cos(theta0) * corner[0] + math.sin(theta0) * corner[1]
    half_height = -math.sin(theta0) * corner[0] + math.cos(theta0) * corner[1]
    width, height = 2 * half_width, 2 * half_height
    law = mechanism.drivers[0].law
    times = np.linspace(0.0, 2 * math.pi, 61)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RedundantConstraintWarning)
        result = solve_kinematics(mechanism, times)
    theta = theta0 + law.amplitude * np.sin(law.omega * times)
    across = width * np.cos(theta) + height * np.sin(theta)
    up = width * np.sin(theta) + height * np.cos(theta)
    for i, j in [(0, 0), (1, 0), (ni - 1, 0), (0, nj - 1), (ni - 1, nj - 1), (2, 1)]:
        b = mechanism.body_index(f"r{i}_{j}.rect")
        expected = np.c_[i * across, j * up, (-1) ** (i + j) * theta]
        np.testing.assert_allclose(result.coordinates[:, 3 * b : 3 * b + 3], expected, rtol=0, atol=1e-11)
    size = lattice_size(result, ("r0_0.rect", f"r{ni - 1}_0.rect"), ("r0_0.rect", f"r0_{nj - 1}.rect"), "r0_0.rect")
    ratio = -(across / up) * (width * np.cos(theta) - height * np.sin(theta)) / (height * np.cos(theta) - width * np.sin(theta))
    inner = np.isfinite(size.poisson_ratio)
    inner[[0, -1]] = False  # one-sided differences at the ends
    # central differences of ln(size) in time: error O(dt²) relative to the ratio's own curvature
    np.testing.assert_allclose(size.poisson_ratio[inner], ratio[inner], rtol=2e-2)
    assert ratio.max() < -4.0  # strongly auxetic over the whole run, never -1


# ---------------------------------------------------------------------- Jansen's leg
def test_jansen_leg_walks_the_path_of_its_link_lengths():
    from jansen import jansen_points

    mechanism = load_model(EXAMPLES / "jansen_leg.toml")
    times = np.linspace(0.0, mechanism.analysis.t_end, mechanism.analysis.steps)
    result = solve_kinematics(mechanism, times)
    drawn = math.atan2(mechanism.points["A"][1], mechanism.points["A"][0])  # the crank's drawn direction
    reference = jansen_points(drawn + times)
    for name in ("G", "F"):
        np.testing.assert_allclose(result.point(name).position, reference[name], rtol=0, atol=1e-9)


def test_strandbeest_feet_are_the_leg_s_shifted_by_their_throws():
    from jansen import jansen_points

    mechanism = load_model(EXAMPLES / "strandbeest.toml")
    times = np.linspace(0.0, mechanism.analysis.t_end, 25)
    result = solve_kinematics(mechanism, times)
    drawn = math.atan2(4.0, 14.0)  # the leg's crank pin drawn at (14, 4)
    for k in range(6):
        foot = jansen_points(drawn + times + 2.0 * math.pi / 3.0 * (k % 3))["G"]
        np.testing.assert_allclose(result.point(f"r{k}.G").position, foot, rtol=0, atol=1e-9)
        np.testing.assert_allclose(result.point(f"l{k}.G").position, foot * [-1.0, 1.0], rtol=0, atol=1e-9)
