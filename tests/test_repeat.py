"""Units repeated into chains against the same mechanisms written out by hand.

The references here build every copy as objects, one loop iteration per copy, the way a
user would write a chain by hand (and the way the test set did before units existed);
they share nothing with `sparsekin.model.units` but the element classes.  A repeat must give the
same elements (`Mechanism.expanded`), the same equations (the pattern's arrays and the
residual and Jacobian at random configurations) and the same motion.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from examples_loader import EXAMPLES
from sparsekin.engine.discretization import Discretization, discretize
from sparsekin import (
    Body,
    Harmonic,
    Linear,
    Mechanism,
    ModelError,
    Polynomial,
    Revolute,
    RotationalDriver,
    Spline,
    Translational,
    TranslationalDriver,
    load_model,
    save_model,
    solve_kinematics,
    testset,
)
from sparsekin.engine.assembly import Assembler
from sparsekin.model.mechanism import Analysis
from sparsekin.engine.pattern import build_pattern
from sparsekin.model.units import Cycle, Repeat, Step, Unit

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
    assemblers = Assembler(Discretization(repeated, a)), Assembler(Discretization(by_hand, b))
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
    with pytest.raises(ModelError, match=r'^vary."drivers\[0\].law.amplitude": copy 16 takes 1.06e\+15: the varied value '
                                         r"must be a finite number of magnitude at most 1e\+15$"):  # fmt: skip
        # copy 16 is the first beyond 1e15: 1e14 + 16 · 6e13; refused by the repeat itself, before any use
        Repeat(driven, count=40, vary={"drivers[0].law.amplitude": Step(6e13)})
    assert Repeat(driven, count=16, vary={"drivers[0].law.amplitude": Step(6e13)}).count == 16  # up to copy 15: fine


def test_a_point_variation_is_checked_by_the_repeat_not_when_drawn():
    with pytest.raises(ModelError, match=r'^vary."points.R".step: expected \[x, y\], got 0.5$'):
        Repeat(arm_unit(), count=3, vary={"points.R": Step(0.5)})
    with pytest.raises(ModelError, match=r'^vary."points.R".cycle\[1\]\[0\]: expected a finite number, got nan$'):
        Repeat(arm_unit(), count=3, vary={"points.R": Cycle(((0.0, 0.5), (math.nan, 0.5)))})
    repeat = Repeat(arm_unit(), count=3, vary={"points.R": Cycle(([0, 1], (0.5, 0.5)))})  # canonical: float pairs
    assert repeat.vary["points.R"] == Cycle(((0.0, 1.0), (0.5, 0.5)))


def law_unit(law) -> Unit:
    """A wheel on its own pivot, turned by `law`."""
    return Unit("spin", points={"S": (0.0, 0.0)}, bodies=[Body("wheel", origin="S", points=("S",))],
                joints=[Revolute(("wheel", "ground"), at="S")], drivers=[RotationalDriver(("wheel", "ground"), law=law)])  # fmt: skip


@pytest.mark.parametrize(("law", "path", "variation", "message"), [
    (Polynomial((0.0, 1.0)), "drivers[0].law.coefficients", Step(0.1), "coefficients of a polynomial law is a list"),
    (Spline((0.0, 1.0), (0.0, 1.0)), "drivers[0].law.times", Cycle([(0.0, 2.0)]), "times of a spline law is a list"),
    (Spline((0.0, 1.0), (0.0, 1.0)), "drivers[0].law.values", Step(1.0), "values of a spline law is a list"),
])  # fmt: skip
def test_a_list_valued_law_key_cannot_vary(law, path, variation, message):
    with pytest.raises(ModelError, match=rf'^vary\."{re.escape(path)}": {message}, not a number: vary steps or cycles'):
        Repeat(law_unit(law), count=3, vary={path: variation})


def test_a_copy_whose_varied_law_is_refused_is_named():
    class Positive(Linear):  # a law with a check of its own, which a varied rate may fail
        def __post_init__(self):
            super().__post_init__()
            if self.rate <= 0:
                raise ModelError(f"expected a positive rate, got {self.rate}", element="rate")

    # rates 1.0, 0.5, 0.0, -0.5: the last copy, checked as the mechanism is made, is refused
    with pytest.raises(ModelError, match=r"^repeat\[0\] copy 3: units\.spin\.drivers\[0\]\.rate: expected a positive "
                                         r"rate, got -0\.5$"):  # fmt: skip
        Mechanism(points={}, bodies=[], repeats=[
            Repeat(law_unit(Positive(rate=1.0)), count=4, vary={"drivers[0].law.rate": Step(-0.5)})
        ])  # fmt: skip
    rates = [1.0] * 70
    rates[65] = 0.0  # beyond the 64 copies of a cycle checked as the mechanism is made
    mechanism = Mechanism(points={}, bodies=[], repeats=[
        Repeat(law_unit(Positive(rate=1.0)), count=70, vary={"drivers[0].law.rate": Cycle(rates)})
    ])  # fmt: skip
    with pytest.raises(ModelError, match=r"^repeat\[0\] copy 65: units\.spin\.drivers\[0\]\.rate: expected a positive"):
        mechanism.drivers[65]  # built on demand: still named


# ---------------------------------------------------------------------- mistakes caught as the file is read
REPEAT_FIRST = 'first = { "prev.crank" = "crank0" }'
UNIT_JOINT = 'bodies = ["coupler", "prev.crank"]'
COUPLER = '[units.loop.bodies.coupler]\norigin = "T"'


def unit_driver(law: str, vary: str = "", name: str = "") -> tuple[tuple[str, str], ...]:
    """Edits that give the unit a driver with `law`, and the repeat a `vary` table."""
    driver = f'[[units.loop.drivers]]\ntype = "rotational"\nbodies = ["crank", "ground"]\nlaw = {law}\n{name}\n'
    edits = (("[[repeat]]", driver + "[[repeat]]"),)
    return edits + (((REPEAT_FIRST, f"{REPEAT_FIRST}\nvary = {vary}"),) if vary else ())


def unit_load(name: str) -> str:
    return f'[[units.loop.loads]]\ntype = "torque"\nbody = "crank"\nvalue = 1.0\nname = "{name}"\n\n'


HARMONIC = '{ type = "harmonic", amplitude = 0.1, omega = 1.0 }'
FILE_MISTAKES = {
    "vary a polynomial's coefficients": (
        unit_driver('{ type = "polynomial", coefficients = [0.0, 1.0] }',
                    '{ "drivers[0].law.coefficients" = { step = 0.1 } }'),
        r'repeat\[0\]\.vary\."drivers\[0\]\.law\.coefficients": coefficients of a polynomial law is a list, not a '
        r"number: vary steps or cycles a law's number parameters only$",
    ),
    "cycle a spline's times": (
        unit_driver('{ type = "spline", times = [0.0, 2.0], values = [0.0, 1.0] }',
                    '{ "drivers[0].law.times" = { cycle = [[0.0, 1.0], [0.0, 3.0]] } }'),
        r'repeat\[0\]\.vary\."drivers\[0\]\.law\.times": times of a spline law is a list, not a number',
    ),
    "step a point by a number": (
        ((REPEAT_FIRST, f'{REPEAT_FIRST}\nvary = {{ "points.Q" = {{ step = 0.5 }} }}'),),
        r'repeat\[0\]\.vary\."points\.Q"\.step: expected \[x, y\], got 0\.5$',
    ),
    "cycle a phase through a word": (
        unit_driver(HARMONIC, '{ "drivers[0].law.phase" = { cycle = [0.0, "half"] } }'),
        r'repeat\[0\]\.vary\."drivers\[0\]\.law\.phase"\.cycle\[1\]: expected a number, got \'half\'$',
    ),
    "step an amplitude beyond 1e15": (
        unit_driver('{ type = "harmonic", amplitude = 1e14, omega = 1.0 }',
                    '{ "drivers[0].law.amplitude" = { step = 6e13 } }'),
        r'repeat\[0\]\.vary\."drivers\[0\]\.law\.amplitude": copy 16 takes 1\.06e\+15: the varied value must be a '
        r"finite number of magnitude at most 1e\+15$",
    ),
    "step an offset left at initial": (
        unit_driver(HARMONIC, '{ "drivers[0].law.offset" = { step = 0.1 } }'),
        r'repeat\[0\]\.vary\."drivers\[0\]\.law\.offset": cannot step a parameter left at its default: give offset',
    ),
    "unknown com of a unit body": (
        ((COUPLER, f'{COUPLER}\ncom = "W"'),),
        r'repeat\[0\] copy 0: units\.loop\.bodies\.coupler\.com: unknown point "W" \(known: O0, A0, u0\.T, u0\.P … '
        r"u999\.P, u999\.Q\)$",
    ),
    "unknown origin of a unit body": (
        ((COUPLER, '[units.loop.bodies.coupler]\norigin = "X"'),),
        r'repeat\[0\] copy 0: units\.loop\.bodies\.coupler\.origin: unknown point "X" \(known: O0, A0, u0\.T, u0\.P … '
        r"u999\.P, u999\.Q\)$",
    ),
    "duplicate load names in a unit": (
        (("[[repeat]]", unit_load("w") + unit_load("w") + "[[repeat]]"),),
        r'units\.loop\.loads\[1\]\.name: duplicate load name "w"$',
    ),
    "own load named like a copy's": (
        (("[[repeat]]", unit_load("w") + "[[repeat]]"),
         ("[units.loop.points]", '[[loads]]\ntype = "torque"\nbody = "crank0"\nvalue = 1.0\nname = "u3.w"\n\n'
                                 "[units.loop.points]")),
        r'repeat\[0\]\.prefix: "u3\.w" is also the name of copy 3\'s w$',
    ),
    "unit driver named like a unit joint": (
        ((UNIT_JOINT, f'{UNIT_JOINT}\nname = "pin"'), *unit_driver(HARMONIC, name='name = "pin"')),
        r'units\.loop\.drivers\[0\]\.name: driver name "pin" is also the name of joints\[2\]: joints and drivers need '
        r"distinct names$",
    ),
}


@pytest.mark.parametrize(("edits", "message"), FILE_MISTAKES.values(), ids=FILE_MISTAKES.keys())
def test_a_mistake_in_a_unit_or_its_variations_is_one_line_naming_it(edits, message, tmp_path):
    text = FILE_HEAD
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / "chain.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ModelError, match=r"^" + re.escape(str(path)) + ": " + message) as caught:
        load_model(path)
    assert "\n" not in str(caught.value)


def test_an_unknown_point_lists_a_few_names_without_walking_the_copies(monkeypatch):
    from sparsekin.model.units import Copies

    calls = []
    name = Copies.name
    monkeypatch.setattr(Copies, "name", lambda self, k, local: calls.append(k) or name(self, k, local))
    with pytest.raises(ModelError, match=r'^bodies\[0\]\.points\[2\]: unknown point "Z" \(known: O, A, a0\.P, a0\.Q … '
                                         r"a999999\.Q, a999999\.R\)$"):  # fmt: skip
        base_model(bodies=[Body("crank0", origin="O", angle=math.pi / 2, points=("O", "A", "Z"))],
                   repeats=[Repeat(arm_unit(), count=10**6, prefix="a", offset=(1.0, 0.0), first={"prev.crank": "crank0"})])
    assert len(calls) < 100  # a million copies, three points each: not one name each


# ---------------------------------------------------------------------- points and outputs of a repeat
def test_a_model_point_that_a_unit_body_lists_rides_on_the_first_copy():
    unit = replace(arm_unit(), bodies=(*arm_unit().bodies[:1], replace(arm_unit().bodies[1], points=("R", "Q", "M"))))
    mechanism = base_model(points={"O": (0.0, 0.0), "A": (0.0, 0.5), "M": (0.5, 1.0)},
                           repeats=[Repeat(unit, count=3, prefix="a", offset=(1.0, 0.0), first={"prev.crank": "crank0"})])
    expanded = mechanism.expanded()
    assert expanded.bodies[2].name == "a0.rod" and "M" in expanded.bodies[2].points  # the first body that lists M
    times = np.linspace(0.0, 1.0, 11)
    result, reference = solve_kinematics(mechanism, times), solve_kinematics(expanded, times)
    motion, expected = result.point("M"), reference.point("M")
    for got, want in zip(motion, expected):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert np.ptp(motion.position[:, 0]) > 0.1  # it moves with copy 0's rod, not with the ground


def test_the_point_names_of_a_repeat_index_like_a_list():
    from sparsekin.engine.pattern import build_point_map

    mechanism = base_model(repeats=[
        Repeat(arm_unit(), count=4, prefix="a", offset=(1.0, 0.0), first={"prev.crank": "crank0"}),
        Repeat(Unit("empty"), count=2, prefix="e"),  # no points: no names
        Repeat(replace(arm_unit(), name="more"), count=3, prefix="b", offset=(1.0, 0.0), first={"prev.crank": "a3.crank"}),
    ])  # fmt: skip
    names, expected = build_point_map(mechanism).names, list(mechanism.points)
    assert len(names) == len(expected) == 2 + 3 * 4 + 3 * 3
    assert [names[k] for k in range(len(names))] == expected
    assert [names[k] for k in range(-len(names), 0)] == expected
    assert names[3:9:2] == expected[3:9:2] and names[::-5] == expected[::-5]
    assert (names[-1], names[13], names[14]) == ("b2.R", "a3.R", "b0.P")
    with pytest.raises(IndexError):
        names[len(names)]
    result = solve_kinematics(replace(mechanism, repeats=mechanism.repeats[:1]), np.linspace(0.0, 0.2, 3))
    assert result.point_names[-1] == "a3.R" and result.point_names[-3:] == ["a3.P", "a3.Q", "a3.R"]


def test_an_own_driver_on_a_copy_beyond_the_short_chain_takes_superlus_order():
    from helpers import solve_with

    from sparsekin.engine.ordering import tiled_ordering
    from sparsekin.solve.policy import Thresholds

    long_chain = load_model(EXAMPLES / "four_bar_chain.toml")
    chain = replace(long_chain, analysis=Analysis(), repeats=(replace(long_chain.repeats[0], count=10),))
    at_the_end = replace(chain, drivers=(RotationalDriver(("u9.crank", "ground"), law=Linear(rate=1.0)),))
    assert tiled_ordering(discretize(chain)) is not None  # the tiling applies to the chain itself
    assert tiled_ordering(discretize(at_the_end)) is None  # its short chain has no u9.crank
    times = np.linspace(0.0, 1.0, 11)
    tile = Thresholds(min_tiled_coordinates=0)  # tile even this short chain
    result = solve_with(at_the_end, times, linear_solver="refactor", thresholds=tile)
    angle = math.pi / 2 + times  # driven from the far end, every crank still turns alike
    np.testing.assert_allclose(result.point("A0").position, np.c_[np.cos(angle), np.sin(angle)], atol=1e-9)
