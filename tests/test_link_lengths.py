"""Exact link lengths on an approximate drawing (`Body.lengths`), and the assembly from it.

Theo Jansen's leg from its thirteen "holy numbers" drawn on a plan rounded to whole
units: its foot path must be the exact one, which the test computes on its own by
intersecting circles (the positions of every joint from the crank angle, one loop
closure at a time).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sparsekin import Body, Linear, Mechanism, ModelError, Revolute, RotationalDriver, check_model, solve_kinematics
from sparsekin.analysis.assemble import assemble
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern
from sparsekin.model.lengths import nearest_points
from sparsekin.model.modelfile import load_model, save_model

#: The holy numbers (the crank axle at the origin, the rocker pivot at (-a, -l)).
HOLY = dict(a=38.0, b=41.5, c=39.3, d=40.1, e=55.8, f=39.4, g=36.7, h=65.7, i=49.0, j=50.0, k=61.9, l=7.8, m=15.0)
#: The links: body name -> (points, the holy letters of its lengths between them).
LINKS = {
    "crank": (("O", "A"), (("O", "A", "m"),)),
    "upper_bar": (("A", "C"), (("A", "C", "j"),)),
    "lower_bar": (("A", "D"), (("A", "D", "k"),)),
    "rocker": (("P", "D"), (("P", "D", "c"),)),
    "upper_triangle": (("P", "C", "E"), (("P", "C", "b"), ("C", "E", "e"), ("P", "E", "d"))),
    "outer_bar": (("E", "F"), (("E", "F", "f"),)),
    "leg": (("D", "F", "G"), (("D", "F", "g"), ("F", "G", "h"), ("D", "G", "i"))),
}
PINS = (("crank", "ground", "O"), ("crank", "upper_bar", "A"), ("crank", "lower_bar", "A"),
        ("upper_bar", "upper_triangle", "C"), ("upper_triangle", "ground", "P"), ("rocker", "ground", "P"),
        ("lower_bar", "rocker", "D"), ("rocker", "leg", "D"), ("upper_triangle", "outer_bar", "E"),
        ("outer_bar", "leg", "F"))  # fmt: skip


def _circles(centre_1, radius_1, centre_2, radius_2, side):
    """The intersection of two circles left of the line from centre 1 to centre 2 (side
    +1) or right of it (side -1): the law of cosines, written out."""
    dx, dy = centre_2[..., 0] - centre_1[..., 0], centre_2[..., 1] - centre_1[..., 1]
    distance = np.hypot(dx, dy)
    along = (radius_1**2 - radius_2**2 + distance**2) / (2 * distance)
    across = np.sqrt(radius_1**2 - along**2)
    ux, uy = dx / distance, dy / distance
    return np.stack([centre_1[..., 0] + along * ux - side * across * uy,
                     centre_1[..., 1] + along * uy + side * across * ux], axis=-1)  # fmt: skip


def jansen_points(crank_angle):
    """Every joint of the leg at crank angles `crank_angle` (rad), each (n, 2)."""
    n = HOLY
    theta = np.atleast_1d(np.asarray(crank_angle, dtype=float))
    o = np.zeros((theta.size, 2))
    p = np.tile([-n["a"], -n["l"]], (theta.size, 1))
    a = np.stack([n["m"] * np.cos(theta), n["m"] * np.sin(theta)], axis=-1)
    c = _circles(a, n["j"], p, n["b"], -1)  # above the line crank–pivot
    d = _circles(a, n["k"], p, n["c"], +1)  # below it
    e = _circles(p, n["d"], c, n["e"], +1)  # outside, to the left
    f = _circles(e, n["f"], d, n["g"], -1)
    g = _circles(f, n["h"], d, n["i"], -1)
    return dict(O=o, P=p, A=a, C=c, D=d, E=e, F=f, G=g)


def jansen_leg(drawn_at: float = 0.3, rounding: float = 1.0, phase: float = 0.0, rate: float = 1.0) -> Mechanism:
    """The leg with its exact lengths, drawn at crank angle `drawn_at`, the moving points
    rounded to multiples of `rounding`; the crank turns at `rate` from `phase` past its
    drawn direction."""
    exact = {name: xy[0] for name, xy in jansen_points(drawn_at).items()}
    points = {name: (tuple(float(v) for v in xy) if name in ("O", "P")
                     else tuple(float(rounding * round(v / rounding)) for v in xy)) for name, xy in exact.items()}  # fmt: skip
    bodies = [Body(name, origin=carried[0], points=carried,
                   lengths=tuple((p, q, HOLY[letter]) for p, q, letter in lengths))
              for name, (carried, lengths) in LINKS.items()]  # fmt: skip
    joints = [Revolute((i, j), at=at) for i, j, at in PINS]
    law = Linear(rate=rate, start=phase)
    return Mechanism(points=points, bodies=bodies, joints=joints,
                     drivers=[RotationalDriver(("crank", "ground"), law=law)], name="jansen-leg")  # fmt: skip


def test_nearest_points_of_a_rough_triangle_meet_its_lengths_and_stay_near_the_drawing():
    drawn = np.array([[[0.0, 0.0], [40.0, 1.0], [20.0, 30.0]]])
    first, second, lengths = np.array([0, 1, 0]), np.array([1, 2, 2]), np.array([41.5, 40.1, 55.8])
    points, error = nearest_points(drawn, first, second, lengths)
    sides = np.hypot(*(points[0, first] - points[0, second]).T)
    np.testing.assert_allclose(sides, lengths, rtol=1e-14)
    assert error[0] < 1e-13
    # nearest: the change is a combination of the constraints' gradients (Lagrange)
    across = points[0, first] - points[0, second]
    gradient = np.zeros((3, 3, 2))
    gradient[np.arange(3), first] = across
    gradient[np.arange(3), second] -= across
    change = (points - drawn).ravel()
    coefficients, *_ = np.linalg.lstsq(gradient.reshape(3, 6).T, change, rcond=None)
    np.testing.assert_allclose(gradient.reshape(3, 6).T @ coefficients, change, atol=1e-12)


def test_jansen_leg_from_its_holy_numbers_on_a_rounded_drawing_walks_the_exact_foot_path():
    leg = jansen_leg()
    times = np.linspace(0.0, 2.0 * math.pi, 73)
    result = solve_kinematics(leg, times)
    drawn_crank = math.atan2(leg.points["A"][1], leg.points["A"][0])  # the crank's drawn direction
    reference = jansen_points(drawn_crank + times)
    for name in ("A", "C", "D", "E", "F", "G"):
        np.testing.assert_allclose(result.point(name).position, reference[name], rtol=0.0, atol=1e-9, err_msg=name)
    # the rounding alone moved the foot by up to about a unit: the lengths matter
    rough = {name: xy for name, xy in leg.points.items()}
    assert max(abs(rough["G"][0] - reference["G"][0, 0]), abs(rough["G"][1] - reference["G"][0, 1])) > 0.05


def test_a_crank_started_two_thirds_of_a_turn_from_its_drawing_assembles_on_the_drawn_branch():
    phase = 4.0 * math.pi / 3.0
    leg = jansen_leg(phase=phase)
    times = np.linspace(0.0, 1.0, 11)
    result = solve_kinematics(leg, times)
    drawn_crank = math.atan2(leg.points["A"][1], leg.points["A"][0])
    reference = jansen_points(drawn_crank + phase + times)
    np.testing.assert_allclose(result.point("G").position, reference["G"], rtol=0.0, atol=1e-9)


def test_check_reports_the_moves_largest_first_and_the_lengths_used(capsys):
    leg = jansen_leg()
    report = check_model(leg)
    assert report.sound and report.assembled
    distances = [distance for _, distance in report.moves]
    assert distances == sorted(distances, reverse=True) and distances[0] > 0.1
    reference = jansen_points(math.atan2(leg.points["A"][1], leg.points["A"][0]))
    name, largest = report.moves[0]
    assert largest == pytest.approx(np.hypot(*(np.array(leg.points[name]) - reference[name][0])), abs=1e-9)
    assert len(report.lengths) == len(LINKS)
    text = str(report)
    assert "points moved from the drawing" in text and "upper_triangle: P–C 41.5 (drawn" in text


def test_the_assembly_follows_the_drawing_and_reports_its_steps():
    leg = jansen_leg(phase=4.0 * math.pi / 3.0)
    pattern = build_pattern(leg)
    assembler = Assembler(leg, pattern)
    assembler.set_time(0.0)
    assembly = assemble(assembler, pattern.initial_coordinates, pattern.coordinate_weights)
    assert assembly.steps > 1 and assembly.residual <= 1e-12


def test_lengths_round_trip_through_the_file_and_contradictions_name_the_body(tmp_path):
    leg = jansen_leg()
    path = tmp_path / "leg.toml"
    save_model(leg, path)
    assert "lengths = [" in path.read_text()
    again = load_model(path)
    assert again.bodies == leg.bodies
    text = path.read_text().replace('["D", "G", 49.0]', '["D", "G", 110.0]')
    path.write_text(text)
    with pytest.raises(ModelError, match=r"bodies\.leg: the lengths D–F 36\.7, F–G 65\.7 and D–G 110 cannot close"):
        load_model(path)


@pytest.mark.parametrize("entry, message", [
    (("O", "Z", 1.0), 'lengths\\[0\\]\\[1\\]: "Z" is not one of the body\'s points'),
    (("O", "O", 1.0), "expected two different points"),
    (("O", "A", -1.0), "expected a length > 0"),
])  # fmt: skip
def test_bad_lengths_are_refused(entry, message):
    with pytest.raises(ModelError, match=message):
        Body("crank", origin="O", points=("O", "A"), lengths=(entry,))
