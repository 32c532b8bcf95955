"""Composite elements: a `cylinder` is exactly the six blocks one writes by hand.

The reference is the same machine written by hand with the names the cylinder gives its
parts: the two forms must give equal bodies, joints and drivers, the same equations at
the drawing, and the same motion and forces; in a repeated unit too.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sparsekin.engine.discretization import Discretization
from sparsekin import ModelError, load_model, solve_kinematics
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern

#: A boom on the ground, raised by a cylinder from the ground pin C to the boom's pin B,
#: with masses, gravity and a load: forces.
COMMON = """
name = "boom"
gravity = [0.0, -9.81]

[points]
P = [0.0, 1.8]
C = [0.7, 1.1]
B = [2.2, 2.7]
T = [5.0, 3.3]

[bodies.boom]
origin = "P"
points = ["P", "B", "T"]
mass = 400.0
inertia = 900.0
com = [2.5, 2.5]

[[joints]]
name = "foot"
type = "revolute"
bodies = ["boom", "ground"]
at = "P"

[[loads]]
type = "force"
body = "boom"
at = "T"
value = [0.0, -3000.0]
"""

COMPOSITE = COMMON + """
[[composites]]
type = "cylinder"
name = "lift"
bodies = ["ground", "boom"]
points = ["C", "B"]
law = { type = "harmonic", amplitude = 0.2, omega = 1.0 }
limits = [1.5, 2.8]
barrel_mass = 30.0
barrel_inertia = 2.0
barrel_com = 0.5
rod_mass = 12.0
rod_com = 0.4
"""

HAND = COMMON + """
[bodies.lift_barrel]
origin = "C"
points = ["C"]
mass = 30.0
inertia = 2.0
com = BARREL_COM

[bodies.lift_rod]
origin = "B"
points = ["B"]
mass = 12.0
com = ROD_COM

[[joints]]
name = "lift_barrel_pin"
type = "revolute"
bodies = ["lift_barrel", "ground"]
at = "C"

[[joints]]
name = "lift_rod_pin"
type = "revolute"
bodies = ["lift_rod", "boom"]
at = "B"

[[joints]]
name = "lift"
type = "translational"
bodies = ["lift_barrel", "lift_rod"]
axis = ["C", "B"]
limits = [1.5, 2.8]

[[drivers]]
name = "lift_driver"
type = "translational"
joint = "lift"
law = { type = "harmonic", amplitude = 0.2, omega = 1.0 }
"""


def hand_written() -> str:
    """HAND with the centres of mass on the axis: 0.5 m from C towards B, 0.4 m from B
    towards C."""
    c, b = np.array([0.7, 1.1]), np.array([2.2, 2.7])
    length = math.hypot(*(b - c))
    barrel, rod = c + 0.5 * (b - c) / length, b + 0.4 * (c - b) / length
    return HAND.replace("BARREL_COM", repr(barrel.tolist())).replace("ROD_COM", repr(rod.tolist()))


def test_a_cylinder_is_the_six_blocks_written_by_hand(tmp_path):
    (tmp_path / "composite.toml").write_text(COMPOSITE)
    (tmp_path / "hand.toml").write_text(hand_written())
    composite, hand = load_model(tmp_path / "composite.toml"), load_model(tmp_path / "hand.toml")
    assert composite.bodies == hand.bodies
    assert tuple(composite.joints) == tuple(hand.joints)
    assert tuple(composite.drivers) == tuple(hand.drivers)
    for mechanism in (composite, hand):
        assert len(mechanism.bodies) == 3 and len(mechanism.joints) == 4 and len(mechanism.drivers) == 1
    # the same equations at the drawing
    patterns = [build_pattern(m) for m in (composite, hand)]
    assert np.array_equal(patterns[0].indices, patterns[1].indices)
    filled = []
    for mechanism, pattern in zip((composite, hand), patterns):
        assembler = Assembler(Discretization(mechanism, pattern))
        assembler.set_time(0.3)
        assembler.fill_residual_jacobian(pattern.initial_coordinates.copy())
        filled.append((assembler.residual.copy(), assembler.jacobian.toarray()))
    assert np.array_equal(filled[0][0], filled[1][0]) and np.array_equal(filled[0][1], filled[1][1])
    # the same motion and forces, the stroke reported as the joint's own coordinate
    times = np.linspace(0.0, 3.0, 31)
    results = [solve_kinematics(m, times, joints=["lift"]) for m in (composite, hand)]
    assert results[0].force_labels == results[1].force_labels and "lift_driver.force" in results[0].force_labels
    for first, second in zip(*(
        (r.coordinates, r.velocities, r.accelerations, r.force_tracks, r.joint_tracks) for r in results
    )):  # fmt: skip
        np.testing.assert_array_equal(first, second)
    stroke = results[0].joint("lift").value
    np.testing.assert_allclose(stroke, math.hypot(1.5, 1.6) + 0.2 * np.sin(times), rtol=0, atol=1e-9)


def test_a_cylinder_extends_with_a_positive_stroke():
    """Whatever the order of the bodies in the file, the stroke is the distance between the
    pins: it grows as the pins move apart."""
    from sparsekin import Cylinder, Harmonic

    parts = Cylinder("jack", ("boom", "ground"), ("B", "C"), law=Harmonic(0.1, 1.0)).expand(lambda p: p)
    translational = parts.joints[2]
    assert translational.bodies == ("jack_barrel", "jack_rod") and translational.axis == ("B", "C")
    assert [joint.bodies for joint in parts.joints[:2]] == [("jack_barrel", "boom"), ("jack_rod", "ground")]



def test_a_cylinder_written_the_other_way_round_also_extends_with_its_stroke(tmp_path):
    """The boom's cylinder with its bodies and pins listed in the other order: along the
    solved motion the stroke and the distance between the pins still grow together."""
    path = tmp_path / "swapped.toml"
    path.write_text(COMPOSITE.replace('bodies = ["ground", "boom"]\npoints = ["C", "B"]',
                                      'bodies = ["boom", "ground"]\npoints = ["B", "C"]'))  # fmt: skip
    mechanism = load_model(path)
    assert mechanism.joints[mechanism.index_of("joints", "lift")].axis == ("B", "C")
    result = solve_kinematics(mechanism, np.linspace(0.0, 3.0, 31), joints=["lift"])
    stroke = result.joint("lift").value
    pins = np.linalg.norm(result.point("B").position - result.point("C").position, axis=1)
    np.testing.assert_allclose(np.diff(stroke), np.diff(pins), rtol=0, atol=1e-12)
    assert np.ptp(stroke) > 0.1


def test_a_cylinder_in_a_repeated_unit_is_expanded_in_every_copy(tmp_path):
    unit = """
name = "jacks"
[units.bay.points]
C = [0.0, 0.0]
B = [0.0, 1.0]
[units.bay.bodies.platform]
origin = "B"
points = ["B"]
[[units.bay.joints]]
type = "translational"
bodies = ["ground", "platform"]
at = "B"
direction = [0.0, 1.0]
[[units.bay.composites]]
type = "cylinder"
name = "jack"
bodies = ["ground", "platform"]
points = ["C", "B"]
law = { type = "linear", rate = 0.1 }
[[repeat]]
unit = "bay"
count = 3
prefix = "u"
offset = [2.0, 0.0]
"""
    (tmp_path / "unit.toml").write_text(unit)
    mechanism = load_model(tmp_path / "unit.toml")
    assert list(mechanism.body_names) == [f"u{k}.{name}" for k in range(3) for name in ("platform", "jack_barrel", "jack_rod")]
    result = solve_kinematics(mechanism, np.linspace(0.0, 1.0, 11), joints=["u2.jack"])
    np.testing.assert_allclose(result.joint("u2.jack").value, 1.0 + 0.1 * result.times, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (('bodies = ["ground", "boom"]', 'bodies = ["ground", "bom"]'),
         r'composites\[0\]: unknown body "bom" .*\(in its joint "lift_rod_pin"\.bodies\[1\]\)'),
        (('points = ["C", "B"]', 'points = ["C", "C"]'), r"composites\[0\]\.points: the two pins are the same point C"),
        (("rod_mass = 12.0", "rod_mass = -1.0"), r"composites\[0\]\.rod_mass: expected"),
        (('points = ["C", "B"]', 'points = ["C", "X"]'), r'composites\[0\]: unknown point "X"'),
        (('type = "cylinder"', 'type = "cylindre"'), r"composites\[0\]\.type: .*cylinder"),
        (('points = ["C", "B"]', 'points = ["C", [0.7, 1.1]]'),
         r"composites\[0\]\.barrel_com: the two pins are drawn at the same place"),
    ],
)  # fmt: skip
def test_a_wrong_cylinder_is_named_in_one_line(tmp_path, change, message):
    path = tmp_path / "wrong.toml"
    path.write_text(COMPOSITE.replace(*change))
    with pytest.raises(ModelError, match=message) as caught:
        load_model(path)
    assert "\n" not in str(caught.value)


def test_the_excavator_with_cylinder_composites_moves_as_the_one_written_by_hand():
    """examples/excavator_cylinders.toml is examples/excavator.toml with its three cylinders
    as composites (other names for the parts): the bucket tip and the strokes match."""
    from examples_loader import EXAMPLES

    hand, composite = (load_model(EXAMPLES / f"{name}.toml") for name in ("excavator", "excavator_cylinders"))
    assert composite.n_bodies == hand.n_bodies and len(composite.joints) == len(hand.joints)
    times = np.linspace(0.0, 8.0, 81)
    actuators = ["boom_actuator", "stick_actuator", "bucket_actuator"]
    results = [solve_kinematics(m, times, joints=actuators) for m in (hand, composite)]
    np.testing.assert_allclose(results[1].point("T").position, results[0].point("T").position, rtol=0, atol=1e-9)
    for name in actuators:
        np.testing.assert_allclose(results[1].joint(name).value, results[0].joint(name).value, rtol=0, atol=1e-9)
