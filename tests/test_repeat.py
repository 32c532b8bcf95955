"""Units repeated into chains against the same mechanisms written out by hand.

The references here build every copy as objects, one loop iteration per copy, the way a
user would write a chain by hand (and the way the test set did before units existed);
they share nothing with `sparsekin.units` but the element classes.  A repeat must give the
same elements (`Mechanism.expanded`), the same equations (the pattern's arrays and the
residual and Jacobian at random configurations) and the same motion.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from examples_loader import EXAMPLES
from sparsekin import (
    Body,
    Harmonic,
    Linear,
    Mechanism,
    ModelError,
    Revolute,
    RotationalDriver,
    Translational,
    TranslationalDriver,
    load_model,
    save_model,
    solve_kinematics,
    testset,
)
from sparsekin.assembly import Assembler
from sparsekin.pattern import build_pattern
from sparsekin.units import Cycle, Repeat, Step, Unit

# ---------------------------------------------------------------------- the references, by hand


def four_bar_chain_by_hand(n_loops: int) -> Mechanism:
    """The chain of the contract (examples/four_bar_chain.toml) written copy by copy:
    cranks drawn upright, tips at height 1."""
    angle, tip = math.pi / 2, (0.0, 1.0)
    points = {"O0": (0.0, 0.0), "A0": tip}
    bodies = [Body("crank0", origin="O0", angle=angle, points=("O0", "A0"))]
    joints = [Revolute(("crank0", "ground"), at="O0")]
    for k in range(n_loops):
        u = f"u{k}."
        points |= {u + "T": (k + tip[0], tip[1]), u + "P": (k + 1.0, 0.0), u + "Q": (k + 1.0 + tip[0], tip[1])}
        bodies += [Body(u + "crank", origin=u + "P", angle=angle, points=(u + "P", u + "Q")),
                   Body(u + "coupler", origin=u + "T", points=(u + "T", u + "Q"))]  # fmt: skip
        previous = "crank0" if k == 0 else f"u{k - 1}.crank"
        joints += [Revolute((u + "crank", "ground"), at=u + "P"), Revolute((u + "crank", u + "coupler"), at=u + "Q"),
                   Revolute((u + "coupler", previous), at=u + "T")]  # fmt: skip
    drivers = [RotationalDriver(("crank0", "ground"), law=Linear(rate=1.0))]
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=drivers, name="four_bar_chain")


def task5_chain_by_hand(n_units: int, amplitude: float = 0.03) -> Mechanism:
    """Task 5 units in series, every unit's points drawn at its phase, written unit by unit."""
    unit = testset.task5_chain_unit(amplitude)
    phases = testset.task5_unit_phases(n_units)
    assembled = testset._task5_points_at_phases(amplitude)
    points, bodies, joints, drivers = {}, [], [], []
    for k in range(n_units):
        u = f"u{k}."
        for name, (x, y) in zip(testset.TASK5_POINTS, assembled[k % testset.TASK5_CHAIN_PHASES].tolist()):
            points[u + name] = (x + testset.TASK5_CHAIN_SPACING * k, y)
        for body in unit.bodies:
            bodies.append(replace(body, name=u + body.name, origin=u + body.origin, points=tuple(u + p for p in body.points)))
        base = "ground" if k == 0 else f"u{k - 1}.c10"
        for joint in unit.joints:
            names = tuple(base if b == "prev.c10" else u + b for b in joint.bodies)
            if isinstance(joint, Revolute):
                joints.append(Revolute(names, at=u + joint.at))
            else:
                joints.append(Translational(names, axis=(u + joint.axis[0], u + joint.axis[1]), name=u + joint.name))
        for driver in unit.drivers:
            law = replace(driver.law, phase=float(phases[k]))
            drivers.append(TranslationalDriver(u + driver.joint, law=law))
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=drivers, name=f"task5_chain_{n_units}")


def assert_same_equations(repeated: Mechanism, by_hand: Mechanism, rng) -> None:
    """The same pattern, targets and units, and the same residual and Jacobian anywhere."""
    a, b = build_pattern(repeated), build_pattern(by_hand)
    for field in ("indptr", "indices", "row_is_angle", "driven_row", "element_first_row"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    np.testing.assert_allclose(a.target, b.target, rtol=0, atol=1e-12 * a.length_scale)
    np.testing.assert_allclose(a.initial_coordinates, b.initial_coordinates, rtol=0, atol=1e-12 * a.length_scale)
    assemblers = Assembler(repeated, a), Assembler(by_hand, b)
    for _ in range(3):
        q = a.initial_coordinates + 0.05 * rng.standard_normal(a.n_coordinates)
        for assembler in assemblers:
            assembler.set_time(0.7)
            assembler.fill_residual_jacobian(q)
        np.testing.assert_allclose(assemblers[0].residual, assemblers[1].residual, rtol=0, atol=1e-12 * a.length_scale)
        np.testing.assert_allclose(assemblers[0].jacobian.data, assemblers[1].jacobian.data, rtol=0, atol=1e-12)
        for assembler in assemblers:
            assembler.fill_acceleration_rhs(q, 0.3 * np.ones(a.n_coordinates))
        np.testing.assert_allclose(assemblers[0].acceleration_rhs, assemblers[1].acceleration_rhs, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------- the same mechanism


def test_the_contract_four_bar_chain_is_the_chain_by_hand(rng):
    repeated = load_model(EXAMPLES / "four_bar_chain.toml")
    by_hand = four_bar_chain_by_hand(1000)
    assert repeated.n_bodies == 2001 and repeated.expanded() == replace(by_hand, analysis=repeated.analysis)
    assert_same_equations(repeated, by_hand, rng)
    times = np.linspace(0.0, 1.2, 25)
    result, reference = solve_kinematics(repeated, times), solve_kinematics(by_hand, times)
    np.testing.assert_allclose(result.coordinates, reference.coordinates, rtol=0, atol=1e-12 * 1000)
    angle = math.pi / 2 + times  # every crank turns with crank0: the tips move on unit circles
    np.testing.assert_allclose(result.point("u999.Q").position, np.c_[1000 + np.cos(angle), np.sin(angle)], atol=1e-9)


def test_a_task5_chain_with_varied_phases_is_the_chain_by_hand(rng):
    n_units = 14  # more than the 11 phases of the cycle
    repeated, by_hand = testset.task5_chain(n_units), task5_chain_by_hand(n_units)
    assert repeated.expanded() == by_hand
    assert_same_equations(repeated, by_hand, rng)
    times = np.linspace(0.0, 2.0, 41)
    result, reference = solve_kinematics(repeated, times), solve_kinematics(by_hand, times)
    scale = build_pattern(repeated).length_scale
    np.testing.assert_allclose(result.coordinates, reference.coordinates, rtol=0, atol=1e-12 * scale)


def test_the_task5_chain_file_is_the_test_set_chain():
    assert load_model(EXAMPLES / "task5_chain.toml") == replace(
        testset.task5_chain(1000), name="task5_chain", analysis=load_model(EXAMPLES / "task5_chain.toml").analysis
    )


# ---------------------------------------------------------------------- what a repeat may say
def arm_unit() -> Unit:
    """A crank on its own pivot, pinned to the crank before by a rod."""
    return Unit(
        "arm",
        points={"P": (1.0, 0.0), "Q": (1.0, 0.5), "R": (0.0, 0.5)},
        bodies=[Body("crank", origin="P", angle=math.pi / 2, points=("P", "Q")), Body("rod", origin="R", points=("R", "Q"))],
        joints=[Revolute(("crank", "ground"), at="P"), Revolute(("rod", "crank"), at="Q"),
                Revolute(("rod", "prev.crank"), at="R")],
        drivers=[],
    )  # fmt: skip


def base_model(**changes) -> Mechanism:
    fields = dict(
        points={"O": (0.0, 0.0), "A": (0.0, 0.5)},
        bodies=[Body("crank0", origin="O", angle=math.pi / 2, points=("O", "A"))],
        joints=[Revolute(("crank0", "ground"), at="O")],
        drivers=[RotationalDriver(("crank0", "ground"), law=Linear(rate=0.5))],
        repeats=[Repeat(arm_unit(), count=5, prefix="a", offset=(1.0, 0.0), first={"prev.crank": "crank0"})],
    )
    return Mechanism(**(fields | changes))


def test_names_prev_and_first():
    mechanism = base_model()
    assert mechanism.body_names[:3] == ["crank0", "a0.crank", "a0.rod"]
    assert mechanism.joints[3].bodies == ("a0.rod", "crank0")  # copy 0's prev.crank: `first`
    assert mechanism.joints[6].bodies == ("a1.rod", "a0.crank")
    assert mechanism.points["a4.Q"] == (5.0, 0.5)
    assert mechanism.body_index("a3.rod") == 8
    without_first = replace(mechanism, repeats=(replace(mechanism.repeats[0], first={}),))
    assert without_first.joints[3].bodies == ("a0.rod", "ground")  # by default: the ground


def test_the_model_may_name_copies_and_several_units():
    mechanism = base_model(
        drivers=[RotationalDriver(("a1.crank", "ground"), law=Linear(rate=0.5))],  # drive a copy's crank instead
        repeats=[
            Repeat(arm_unit(), count=2, prefix="a", offset=(1.0, 0.0), first={"prev.crank": "crank0"}),
            Repeat(replace(arm_unit(), name="more", points={"P": (3.0, 0.0), "Q": (3.0, 0.5), "R": (2.0, 0.5)}),
                   count=3, prefix="b", offset=(1.0, 0.0), first={"prev.crank": "a1.crank"}),
        ],
    )  # fmt: skip
    assert mechanism.bodies[-1].name == "b2.rod" and mechanism.points["b0.P"] == (3.0, 0.0)
    result = solve_kinematics(replace(mechanism, drivers=(RotationalDriver(("b2.crank", "ground"), law=Linear(rate=0.5)),)),
                              np.linspace(0.0, 1.0, 11))  # fmt: skip
    angle = math.pi / 2 + 0.5 * result.times  # a parallel chain: every crank turns alike
    np.testing.assert_allclose(result.point("A").position, 0.5 * np.c_[np.cos(angle), np.sin(angle)], atol=1e-12)


def test_vary_steps_and_cycles_parameters_and_points():
    driven = Unit("driven", points={"S": (0.0, 0.0)}, bodies=[Body("wheel", origin="S", points=("S",))],
                  joints=[Revolute(("wheel", "ground"), at="S")],
                  drivers=[RotationalDriver(("wheel", "ground"), law=Harmonic(amplitude=0.1, omega=2.0))])  # fmt: skip
    mechanism = Mechanism(points={}, bodies=[], repeats=[
        Repeat(driven, count=4, offset=(2.0, 0.0), vary={
            "drivers[0].law.phase": Step(0.5), "drivers[0].law.amplitude": Cycle((0.1, 0.2)),
            "points.S": Step((0.0, 0.25)),
        }),
    ])  # fmt: skip
    assert [driver.law.phase for driver in mechanism.drivers] == [0.0, 0.5, 1.0, 1.5]
    assert [driver.law.amplitude for driver in mechanism.drivers] == [0.1, 0.2, 0.1, 0.2]
    assert [mechanism.points[f"driven{k}.S"] for k in range(4)] == [(0.0, 0.0), (2.0, 0.25), (4.0, 0.5), (6.0, 0.75)]
    times = np.linspace(0.0, 1.0, 11)
    result = solve_kinematics(mechanism, times)
    for k in range(4):
        law = mechanism.drivers[k].law
        angle = result.coordinates[:, 3 * k + 2]
        np.testing.assert_allclose(angle, law.amplitude * np.sin(2.0 * times + law.phase), atol=1e-13)  # offset: 0


def test_a_repeated_model_round_trips_through_its_file(tmp_path):
    mechanism = base_model(repeats=[Repeat(arm_unit(), count=7, prefix="a", offset=(1.0, 0.0), first={"prev.crank": "crank0"},
                                           vary={"points.R": Cycle(((0.0, 0.5), (0.0, 0.5)))})])  # fmt: skip
    save_model(mechanism, tmp_path / "chain.toml")
    text = (tmp_path / "chain.toml").read_text()
    assert "[[repeat]]" in text and "a6." not in text  # the unit and the repeat, not the copies
    assert load_model(tmp_path / "chain.toml") == mechanism


# ---------------------------------------------------------------------- mistakes
FILE_HEAD = (EXAMPLES / "four_bar_chain.toml").read_text(encoding="utf-8")

MISTAKES = {
    "unknown body in a unit": (
        ('bodies = ["crank", "coupler"]', 'bodies = ["crank", "couple"]'), None,
        r'chain\.toml: repeat\[0\] copy 0: units\.loop\.joints\[1\]\.bodies\[1\]: unknown body "couple"',
    ),
    "prev of no unit body": (
        ('bodies = ["coupler", "prev.crank"]', 'bodies = ["coupler", "prev.rocker"]'), None,
        r'units\.loop\.joints\[2\]\.bodies\[1\]: "prev\.rocker" names no body of the unit \(its bodies: crank, coupler\)',
    ),
    "first names no body": (
        ('first = { "prev.crank" = "crank0" }', 'first = { "prev.crank" = "crank9" }'), None,
        r'repeat\[0\]\.first: unknown body "crank9"',
    ),
    "unknown unit": (('unit = "loop"', 'unit = "lop"'), None, r'repeat\[0\]\.unit: unknown unit "lop" \(known: loop\)'),
    "vary of no driver": (
        ('first = { "prev.crank" = "crank0" }', 'first = { "prev.crank" = "crank0" }\nvary = { "drivers[0].law.phase" = { step = 0.1 } }'),
        None, r'repeat\[0\]\.vary\."drivers\[0\]\.law\.phase": unit "loop" has 0 drivers',
    ),
    "count not whole": (("count = 1000", "count = 10.5"), None, r"repeat\[0\]\.count: expected a whole number, got 10\.5"),
    "name taken by a copy": (("A0 = [0.0, 1.0]", 'A0 = [0.0, 1.0]\n"u3.Q" = [1.0, 1.0]'), None,
                             r'repeat\[0\]\.prefix: "u3\.Q" is also the name of copy 3\'s Q'),
}


@pytest.mark.parametrize("edits", MISTAKES.values(), ids=MISTAKES.keys())
def test_a_mistake_in_a_repeat_names_unit_copy_and_element(edits, tmp_path):
    first, second, message = edits
    text = FILE_HEAD.replace(*first)
    if second is not None:
        text = text.replace(*second)
    assert text != FILE_HEAD
    path = tmp_path / "chain.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ModelError, match=message) as caught:
        load_model(path)
    assert "\n" not in str(caught.value)


def test_a_varied_value_out_of_range_names_the_copy():
    driven = Unit("d", points={"S": (0.0, 0.0)}, bodies=[Body("w", origin="S")], joints=[Revolute(("w", "ground"), at="S")],
                  drivers=[RotationalDriver(("w", "ground"), law=Harmonic(amplitude=1e14, omega=1.0))])  # fmt: skip
    with pytest.raises(ModelError, match=r'repeat\[0\] copy 16: vary."drivers\[0\].law.amplitude": the varied value is not'):
        # copy 16 is the first beyond 1e15: 1e14 + 16 · 6e13
        Mechanism(points={}, bodies=[], repeats=[Repeat(driven, count=40, vary={"drivers[0].law.amplitude": Step(6e13)})])
