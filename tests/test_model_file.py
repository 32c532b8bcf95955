"""The TOML model file: what it reads, what it writes back, and how it reports mistakes."""

from __future__ import annotations

import copy
import json
import math
import re
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sparsekin.errors import ModelError
from sparsekin.model.laws import Harmonic, Linear, Polynomial, Spline
from sparsekin.model.elements import (
    AbsoluteDriver,
    Actuator,
    DistanceDriver,
    Gear,
    PathDriver,
    PinInSlot,
    RackPinion,
    Revolute,
    Rigid,
    RotationalDriver,
    RotationalSpring,
    Translational,
    TranslationalDriver,
)
from sparsekin.model.mechanism import Analysis, Body, Mechanism
from sparsekin.model.modelfile import load_model, save_model

TASK5 = Path(__file__).resolve().parents[1] / "examples" / "task5.toml"

# ------------------------------------------------------------------ a file with every element

EVERY_ELEMENT_TOML = """\
name = "every-element"

[points]
O = [0.0, 0.0]
A = [0.1, 0.0]
B = [0.4, 0.0]
C = [0.4, 0.2]
"D 1" = [0.6, 0.2]

[bodies.crank]
origin = "O"
angle = 0.25
points = ["O", "A"]
mass = 1.5
inertia = 0.002
com = "A"
velocity = [0.0, 0.0, 2.5]

[bodies.rod]
origin = [0.1, 0.0]
points = ["A", "B"]
com = [0.25, 0.0]

[bodies.slider]
origin = "B"
points = ["B"]

[bodies.arm]
origin = "C"
points = ["C", "D 1"]

[bodies."tool tip"]
origin = "D 1"

[[joints]]
name = "pivot"
type = "revolute"
bodies = ["crank", "ground"]
at = "O"

[[joints]]
type = "revolute"
bodies = ["crank", "rod"]
at = [0.1, 0.0]

[[joints]]
name = "guide"
type = "translational"
bodies = ["ground", "slider"]
axis = ["O", "B"]

[[joints]]
name = "rail"
type = "translational"
bodies = ["slider", "arm"]
at = "C"
direction = [0.0, 1.0]

[[joints]]
name = "weld"
type = "rigid"
bodies = ["arm", "tool tip"]

[[joints]]
name = "slot"
type = "pin_in_slot"
bodies = ["rod", "arm"]
at = "C"
direction = [1.0, 0.5]
limits = [-0.1, 0.2]

[[joints]]
type = "gear"
bodies = ["crank", "rod"]
ratio = -2.5
carrier = "slider"

[[joints]]
type = "gear"
bodies = ["crank", "arm"]
ratio = 3

[[joints]]
name = "rack"
type = "rack_pinion"
bodies = ["slider", "crank"]
at = "A"
direction = [1.0, 0.0]
radius = 0.05

[[joints]]
type = "revolute"
bodies = ["arm", "ground"]
at = "C"
limits = [-1.5, 1.5]

[[drivers]]
name = "stroke"
type = "translational"
joint = "guide"
law = { type = "harmonic", amplitude = 0.05, omega = 1.5, phase = 0.5, offset = 0.3 }

[[drivers]]
type = "translational"
joint = "rail"
law = { type = "harmonic", amplitude = 0.01, omega = 2.0, offset = "initial" }

[[drivers]]
type = "rotational"
bodies = ["crank", "ground"]
law = { type = "linear", rate = 6.283185307179586, start = 0.25 }

[[drivers]]
type = "rotational"
bodies = ["rod", "crank"]
law = { type = "linear", rate = -1.0, start = "initial" }

[[drivers]]
type = "absolute"
body = "tool tip"
coordinate = "x"
law = { type = "polynomial", coefficients = ["initial", 0.1, -0.02] }

[[drivers]]
type = "absolute"
body = "tool tip"
coordinate = "y"
law = { type = "polynomial", coefficients = [0.2, 0, 1e-3] }

[[drivers]]
type = "absolute"
body = "arm"
coordinate = "angle"
law = { type = "spline", file = "laws/arm.csv" }

[[drivers]]
type = "absolute"
body = "slider"
coordinate = "angle"
law = { type = "spline", times = [0.0, 1.0, 2.0], values = [0.0, 0.5, 0.0] }

[[drivers]]
name = "cylinder"
type = "distance"
points = ["O", "D 1"]
bodies = ["ground", "tool tip"]
law = { type = "linear", rate = 0.01 }
limits = [0.5, 0.8]

[[drivers]]
type = "path"
body = "rod"
point = "B"
law_x = { type = "linear", rate = 0.1 }
law_y = { type = "harmonic", amplitude = 0.02, omega = 3.0, offset = 0.0 }

[[loads]]
type = "rotational_spring"
bodies = ["arm", "crank"]
stiffness = 5.0
free_angle = 0.3
damping = 0.01

[[loads]]
name = "push"
type = "actuator"
joint = "guide"
value = { type = "spline", times = [0.0, 0.5, 2.0], values = [0.0, 120.0, 80.0] }

[[loads]]
type = "actuator"
joint = "pivot"
value = 1.5

[analysis]
t_end = 2.0
steps = 201
points = ["A", "B", "D 1"]
max_step = 0.001
"""

ARM_CSV = "t, value\n0.0,0.0\n 0.5, 0.1\n\n1.0,0.3\n2.0,0.2\n"


def every_element_mechanism() -> Mechanism:
    """The mechanism of `EVERY_ELEMENT_TOML`, built with the Python API."""
    return Mechanism(
        name="every-element",
        points={"O": (0.0, 0.0), "A": (0.1, 0.0), "B": (0.4, 0.0), "C": (0.4, 0.2), "D 1": (0.6, 0.2)},
        bodies=[
            Body("crank", origin="O", angle=0.25, points=("O", "A"), mass=1.5, inertia=0.002, com="A", velocity=(0.0, 0.0, 2.5)),
            Body("rod", origin=(0.1, 0.0), points=("A", "B"), com=(0.25, 0.0)),
            Body("slider", origin="B", points=("B",)),
            Body("arm", origin="C", points=("C", "D 1")),
            Body("tool tip", origin="D 1"),
        ],
        joints=[
            Revolute(("crank", "ground"), at="O", name="pivot"),
            Revolute(("crank", "rod"), at=(0.1, 0.0)),
            Translational(("ground", "slider"), axis=("O", "B"), name="guide"),
            Translational(("slider", "arm"), at="C", direction=(0.0, 1.0), name="rail"),
            Rigid(("arm", "tool tip"), name="weld"),
            PinInSlot(("rod", "arm"), at="C", direction=(1.0, 0.5), name="slot", limits=(-0.1, 0.2)),
            Gear(("crank", "rod"), ratio=-2.5, carrier="slider"),
            Gear(("crank", "arm"), ratio=3.0),
            RackPinion(("slider", "crank"), at="A", direction=(1.0, 0.0), radius=0.05, name="rack"),
            Revolute(("arm", "ground"), at="C", limits=(-1.5, 1.5)),
        ],
        drivers=[
            TranslationalDriver(
                "guide", Harmonic(amplitude=0.05, omega=1.5, phase=0.5, offset=0.3), name="stroke"
            ),
            TranslationalDriver("rail", Harmonic(amplitude=0.01, omega=2.0)),
            RotationalDriver(("crank", "ground"), Linear(rate=6.283185307179586, start=0.25)),
            RotationalDriver(("rod", "crank"), Linear(rate=-1.0)),
            AbsoluteDriver("tool tip", "x", Polynomial((None, 0.1, -0.02))),
            AbsoluteDriver("tool tip", "y", Polynomial((0.2, 0.0, 1e-3))),
            AbsoluteDriver("arm", "angle", Spline((0.0, 0.5, 1.0, 2.0), (0.0, 0.1, 0.3, 0.2))),
            AbsoluteDriver("slider", "angle", Spline((0.0, 1.0, 2.0), (0.0, 0.5, 0.0))),
            DistanceDriver(("O", "D 1"), ("ground", "tool tip"), Linear(rate=0.01), name="cylinder", limits=(0.5, 0.8)),
            PathDriver("rod", "B", law_x=Linear(rate=0.1), law_y=Harmonic(amplitude=0.02, omega=3.0, offset=0.0)),
        ],
        loads=[
            RotationalSpring(("arm", "crank"), stiffness=5.0, free_angle=0.3, damping=0.01),
            Actuator("guide", Spline((0.0, 0.5, 2.0), (0.0, 120.0, 80.0)), name="push"),
            Actuator("pivot", 1.5),
        ],
        analysis=Analysis(t_end=2.0, steps=201, points=("A", "B", "D 1"), max_step=0.001),
    )


@pytest.fixture
def every_element_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """`EVERY_ELEMENT_TOML` in a folder of its own, with its spline CSV beside it.

    The working directory is elsewhere, so the CSV is only found relative to the model.
    """
    folder = tmp_path / "model"
    (folder / "laws").mkdir(parents=True)
    (folder / "laws" / "arm.csv").write_text(ARM_CSV, encoding="utf-8")
    path = folder / "every.toml"
    path.write_text(EVERY_ELEMENT_TOML, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    return path


# ------------------------------------------------------------------ reading


def test_task5_loads():
    mechanism = load_model(TASK5)

    assert mechanism.name == "task5"
    assert mechanism.body_names == tuple(f"c{k}" for k in range(1, 11))
    assert len(mechanism.joints) == 14
    assert [type(joint) for joint in mechanism.joints].count(Translational) == 2
    assert [driver.joint for driver in mechanism.drivers] == ["actuator1", "actuator2"]
    assert all(driver.law == Harmonic(amplitude=0.05, omega=1.5) for driver in mechanism.drivers)
    assert mechanism.analysis == Analysis(t_end=10.0, steps=1001, points=("A", "J", "K"))


@pytest.mark.filterwarnings("ignore::sparsekin.UnjoinedPointWarning")  # a file of every key, not a linkage
def test_every_element_loads_as_built_in_python(every_element_file: Path):
    assert load_model(every_element_file) == every_element_mechanism()


def test_name_defaults_to_the_file_stem(tmp_path: Path):
    path = tmp_path / "crank-only.toml"
    path.write_text('[points]\nO = [0.0, 0.0]\n\n[bodies.crank]\norigin = "O"\n', encoding="utf-8")

    expected = Mechanism(points={"O": (0.0, 0.0)}, bodies=[Body("crank", origin="O")], name="crank-only")
    assert load_model(path) == expected


def test_byte_order_mark_is_accepted(tmp_path: Path):
    path = tmp_path / "bom.toml"
    path.write_bytes("\ufeffname = \"bom\"\n".encode("utf-8"))

    assert load_model(path).name == "bom"


# ------------------------------------------------------------------ writing


@pytest.mark.filterwarnings("ignore::sparsekin.UnjoinedPointWarning")  # a file of every key, not a linkage
@pytest.mark.parametrize("source", ["every-element", "task5"])
def test_save_then_load_gives_an_equal_mechanism(source: str, every_element_file: Path, tmp_path: Path):
    mechanism = load_model(every_element_file if source == "every-element" else TASK5)
    path = tmp_path / "saved.toml"

    save_model(mechanism, path)

    assert load_model(path) == mechanism


@pytest.mark.filterwarnings("ignore::sparsekin.UnjoinedPointWarning")  # a file of every key, not a linkage
def test_saved_spline_is_written_inline(every_element_file: Path, tmp_path: Path):
    path = tmp_path / "saved.toml"
    save_model(load_model(every_element_file), path)

    text = path.read_text(encoding="utf-8")

    assert "file =" not in text
    assert 'law = { type = "spline", times = [0.0, 0.5, 1.0, 2.0], values = [0.0, 0.1, 0.3, 0.2] }' in text


def test_names_that_are_not_bare_keys_are_quoted(tmp_path: Path):
    awkward = ['a "quoted" point', "back\\slash", "dotted.name", "new\nline", "é ünïcode", "tab\tdel\x7f"]
    mechanism = Mechanism(
        name='model "x"',
        points={name: (float(k), 0.0) for k, name in enumerate(awkward)},
        bodies=[Body(name, origin=name, points=(name,)) for name in awkward],
    )
    path = tmp_path / "awkward.toml"

    save_model(mechanism, path)

    assert load_model(path) == mechanism


class _SquareWave:
    """A user's law: any object with `evaluate`."""

    def evaluate(self, t, initial):
        return (initial + (1.0 if math.sin(t) >= 0 else -1.0), 0.0, 0.0)


def test_a_user_law_cannot_be_saved(tmp_path: Path):
    mechanism = Mechanism(
        points={},
        bodies=[Body("crank", origin=(0.0, 0.0))],
        drivers=[
            RotationalDriver(("crank", "ground"), law=Linear(rate=1.0)),
            AbsoluteDriver("crank", "x", _SquareWave()),
        ],
    )
    path = tmp_path / "user-law.toml"

    expected = r"^drivers\[1\]\.law: cannot write a _SquareWave to a model file"
    with pytest.raises(ModelError, match=expected) as caught:
        save_model(mechanism, path)

    assert "\n" not in str(caught.value)
    assert not path.exists()


# ------------------------------------------------------------------ round trip of any mechanism

_FINITE = st.floats(min_value=-1e15, max_value=1e15, allow_nan=False) | st.integers(-(10**6), 10**6)
_NON_NEGATIVE = _FINITE.map(abs)
_NAMES = st.text(st.characters(blacklist_categories=("Cs",)), min_size=1, max_size=6).filter(
    lambda name: name.strip() and name != "ground"
)


def _laws() -> st.SearchStrategy:
    spline_times = st.lists(st.integers(-400, 400), min_size=2, max_size=6, unique=True).map(
        lambda times: tuple(time / 8 for time in sorted(times))
    )
    return st.one_of(
        st.builds(Harmonic, amplitude=_FINITE, omega=_FINITE, phase=_FINITE, offset=st.none() | _FINITE),
        st.builds(Linear, rate=_FINITE, start=st.none() | _FINITE),
        st.lists(_FINITE, min_size=1, max_size=4).flatmap(
            lambda coefficients: st.sampled_from([coefficients, [None, *coefficients[1:]]]).map(Polynomial)
        ),
        spline_times.flatmap(
            lambda times: st.lists(_FINITE, min_size=len(times), max_size=len(times)).map(
                lambda values: Spline(times, values)
            )
        ),
    )


def _two_different(names: list[str]) -> st.SearchStrategy:
    return st.lists(st.sampled_from(names), min_size=2, max_size=2, unique=True).map(tuple)


@st.composite
def mechanisms(draw: st.DrawFn) -> Mechanism:
    """Valid mechanisms using every element, with awkward names and numbers."""
    point_names = draw(st.lists(_NAMES, min_size=2, max_size=5, unique=True))
    n_points = len(point_names)
    coordinates = draw(
        st.lists(st.tuples(_FINITE, _FINITE), min_size=n_points, max_size=n_points, unique=True)
    )
    points = dict(zip(point_names, coordinates))
    point_references = st.sampled_from(point_names) | st.tuples(_FINITE, _FINITE)
    body_names = draw(st.lists(_NAMES, min_size=2, max_size=4, unique=True))
    bodies = [
        Body(
            name,
            origin=draw(point_references),
            angle=draw(_FINITE),
            points=tuple(draw(st.lists(st.sampled_from(point_names), max_size=3))),
            mass=draw(st.none() | _NON_NEGATIVE),
            inertia=draw(st.none() | _NON_NEGATIVE),
            com=draw(st.none() | point_references),
            velocity=draw(st.none() | st.tuples(_FINITE, _FINITE, _FINITE)),
        )
        for name in body_names
    ]
    body_pairs = _two_different([*body_names, "ground"])
    two_points = _two_different(point_names)
    nonzero_direction = st.tuples(_FINITE, _FINITE).filter(lambda direction: math.hypot(*direction) > 0.0)
    limits = st.tuples(_FINITE, _FINITE).filter(lambda pair: pair[0] < pair[1]) | st.none()
    positive = _FINITE.filter(lambda value: value > 0)
    nonzero = _FINITE.filter(lambda value: value != 0)

    def gears(name):
        return body_pairs.flatmap(lambda pair: st.builds(
            Gear, st.just(pair), nonzero, carrier=st.sampled_from([b for b in [*body_names, "ground"] if b not in pair]),
            name=st.just(name),
        ))  # fmt: skip

    joint_kinds = [
        lambda name: st.builds(Revolute, body_pairs, point_references, name=st.just(name), limits=limits),
        lambda name: st.builds(
            PinInSlot, body_pairs, point_references, nonzero_direction, name=st.just(name), limits=limits
        ),
        gears,
        lambda name: st.builds(RackPinion, body_pairs, point_references, nonzero_direction, positive, name=st.just(name)),
        lambda name: st.builds(Translational, body_pairs, axis=two_points, name=st.just(name), limits=limits),
        lambda name: st.builds(
            Translational, body_pairs, at=point_references, direction=nonzero_direction, name=st.just(name),
            limits=limits,
        ),
        lambda name: st.builds(Rigid, body_pairs, name=st.just(name)),
    ]
    joints = []
    for k in range(draw(st.integers(0, 4))):
        kind = draw(st.sampled_from(joint_kinds))
        joints.append(draw(kind(draw(st.sampled_from([None, f"joint {k}"])))))
    named_sliders = [joint.name for joint in joints if isinstance(joint, Translational) and joint.name]
    driver_kinds = [
        st.builds(RotationalDriver, body_pairs, _laws(), name=st.none() | _NAMES),
        st.builds(DistanceDriver, two_points, body_pairs, _laws(), name=st.none() | _NAMES, limits=limits),
        st.builds(PathDriver, st.sampled_from(body_names), point_references, _laws(), _laws()),
        st.builds(AbsoluteDriver, st.sampled_from(body_names), st.sampled_from(["x", "y", "angle"]), _laws()),
    ]
    if named_sliders:
        driver_kinds.append(st.builds(TranslationalDriver, st.sampled_from(named_sliders), _laws()))
    drivers = draw(
        st.lists(
            st.one_of(driver_kinds),
            max_size=3,
            unique_by=lambda driver: driver.name if driver.name is not None else object(),
        )
    )
    analysis = draw(
        st.builds(
            Analysis,
            t_end=st.none() | st.floats(0.0, 1e3),
            steps=st.none() | st.integers(1, 10**6),
            points=st.none() | st.lists(st.sampled_from(point_names)).map(tuple),
            type=st.sampled_from(Analysis.types),
            max_step=st.none() | _FINITE.filter(lambda value: value > 0),
        )
    )
    return Mechanism(points, bodies, joints, drivers, name=draw(_NAMES), analysis=analysis)


@pytest.mark.filterwarnings("ignore::sparsekin.UnjoinedPointWarning")  # drawn points need not be joined
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mechanism=mechanisms())
def test_any_mechanism_round_trips(mechanism: Mechanism, tmp_path_factory: pytest.TempPathFactory):
    path = tmp_path_factory.mktemp("round-trip") / "model.toml"

    save_model(mechanism, path)

    assert load_model(path) == mechanism


# ------------------------------------------------------------------ mistakes

#: A valid model that the mistakes below edit (also the base of tests/test_hostile_input.py).
SLIDER_CRANK = (Path(__file__).resolve().parent / "data" / "slider_crank.toml").read_text(encoding="utf-8")

GUIDE = 'axis = ["O", "B"]'
LAW = 'law = { type = "linear", rate = 6.283185307179586 }'
DRIVEN = 'type = "rotational"\nbodies = ["crank", "ground"]'


def _harmonic(fields: str) -> tuple[str, str]:
    """An edit replacing the slider-crank's law by a harmonic law with `fields`."""
    return (LAW, f'law = {{ type = "harmonic", {fields} }}')


#: (edit of SLIDER_CRANK: text replaced and replacement, element, expected reason as a regex)
MISTAKES = {
    # unknown keys
    "unknown top-level key": (
        ("[bodies.crank]", "[bodys.crank]"),
        "",
        r'unknown key "bodys" \(expected one of: name, points, bodies, joints',
    ),
    "unknown body key": (
        ("angle = 0.0", "angl = 0.0"),
        "bodies.crank",
        r'unknown key "angl" \(expected one of: origin, angle, points',
    ),
    "unknown joint key": (
        ('at = "A"', 'att = "A"'),
        "joints[1]",
        r'unknown key "att" \(expected one of: type, bodies, at, name, limits\)',
    ),
    "unknown law key": (
        _harmonic("amplitud = 0.05, omega = 1.5"),
        "drivers[0].law",
        r'unknown key "amplitud" \(expected one of: type, amplitude, omega, phase, offset\)',
    ),
    "unknown analysis key": (("steps = 201", "step = 201"), "analysis", r'unknown key "step"'),
    # missing keys
    "missing joint key": (
        ('bodies = ["crank", "rod"]\nat = "A"', 'bodies = ["crank", "rod"]'),
        "joints[1]",
        r'missing key "at"$',
    ),
    "missing body origin": (('origin = "A"\n', ""), "bodies.rod", r'missing key "origin"$'),
    "missing joint type": (
        ('type = "revolute"\nbodies = ["rod", "slider"]', 'bodies = ["rod", "slider"]'),
        "joints[2]",
        r'missing key "type" \(expected one of: revolute, translational, rigid, pin_in_slot, gear, rack_pinion\)',
    ),
    "missing law": ((LAW, ""), "drivers[0]", r'missing key "law"$'),
    "missing law type": (
        (LAW, "law = { rate = 1.0 }"),
        "drivers[0].law",
        r'missing key "type" \(expected one of: harmonic, linear, polynomial, spline\)',
    ),
    "missing law field": (_harmonic("amplitude = 0.05"), "drivers[0].law", r'missing key "omega"$'),
    "missing spline samples": (
        (LAW, 'law = { type = "spline" }'),
        "drivers[0].law",
        r'missing keys "times" and "values" or key "file"$',
    ),
    "missing spline values": (
        (LAW, 'law = { type = "spline", times = [0.0, 1.0] }'), "drivers[0].law", r'missing key "values"$',
    ),
    "missing slider axis": ((GUIDE, ""), "joints[3]", r'missing key "axis" or keys "at" and "direction"$'),
    "missing slider direction": ((GUIDE, 'at = "O"'), "joints[3]", r'missing key "direction"$'),
    "both slider forms": (
        (GUIDE, GUIDE + "\ndirection = [1.0, 0.0]"),
        "joints[3]",
        r'give either key "axis" or keys "at" and "direction", not both',
    ),
    "spline samples and file": (
        (LAW, 'law = { type = "spline", times = [0.0, 1.0], values = [0.0, 1.0], file = "a.csv" }'),
        "drivers[0].law",
        "give either",
    ),
    # wrong types
    "string for a number": (
        ("angle = 0.0", 'angle = "zero"'), "bodies.crank.angle", r"expected a number, got 'zero'",
    ),
    "number for a point": (
        ('at = "A"', "at = 3"), "joints[1].at", r"expected a point name or \[x, y\], got 3",
    ),
    "one coordinate": (("A = [0.1, 0.0]", "A = [0.1]"), "points.A", r"expected \[x, y\], got \[0.1\]"),
    "float steps": (
        ("steps = 201", "steps = 201.0"), "analysis.steps", r"expected a whole number, got 201.0",
    ),
    "boolean rate": (
        (LAW, 'law = { type = "linear", rate = true }'),
        "drivers[0].law.rate",
        r"expected a number, got True",
    ),
    "misspelt initial": (
        (LAW, 'law = { type = "linear", rate = 1.0, start = "inital" }'),
        "drivers[0].law.start",
        r'expected a number or "initial", got \'inital\'',
    ),
    "law not a table": (
        (LAW, "law = 5"),
        "drivers[0].law",
        r'expected an inline table \{ type = "...", ... \}, got the number 5',
    ),
    "coefficients not an array": (
        (LAW, 'law = { type = "polynomial", coefficients = 1.0 }'),
        "drivers[0].law.coefficients",
        r"expected an array of numbers",
    ),
    "empty coefficients": (
        (LAW, 'law = { type = "polynomial", coefficients = [] }'),
        "drivers[0].law.coefficients",
        r"expected a non-empty list of numbers",
    ),
    "bad coordinate": (
        (DRIVEN, 'type = "absolute"\nbody = "crank"\ncoordinate = "z"'),
        "drivers[0].coordinate",
        r'expected one of "x", "y", "angle", got \'z\'',
    ),
    # non-finite numbers
    "nan coordinate": (
        ("A = [0.1, 0.0]", "A = [nan, 0.0]"), "points.A[0]", r"expected a finite number, got nan",
    ),
    "infinite law field": (
        (LAW, 'law = { type = "linear", rate = inf }'),
        "drivers[0].law.rate",
        r"expected a finite number, got inf",
    ),
    "nan spline value": (
        (LAW, 'law = { type = "spline", times = [0.0, 1.0], values = [0.0, -nan] }'),
        "drivers[0].law.values[1]",
        "expected a finite number, got nan",
    ),
    "huge mass": (
        ("angle = 0.0", "mass = 1e300"),
        "bodies.crank.mass",
        r"expected a number of magnitude at most 1e\+15",
    ),
    "negative mass": (("angle = 0.0", "mass = -2.0"), "bodies.crank.mass", r"expected a number >= 0, got -2\.0"),
    # unknown names
    "unknown body": (
        ('bodies = ["rod", "slider"]', 'bodies = ["rod", "slidr"]'),
        "joints[2].bodies[1]",
        r'unknown body "slidr" \(known: crank, rod, slider, ground\)',
    ),
    "unknown point": (('at = "A"', 'at = "Q"'), "joints[1].at", r'unknown point "Q" \(known: O, A, B\)'),
    "unknown point of a body": (
        ('points = ["A", "B"]', 'points = ["A", "X"]'), "bodies.rod.points[1]", r'unknown point "X"',
    ),
    "unknown origin": (('origin = "B"', 'origin = "Z"'), "bodies.slider.origin", r'unknown point "Z"'),
    "unknown analysis point": (
        ('steps = 201\npoints = ["A", "B"]', 'steps = 201\npoints = ["A", "P"]'),
        "analysis.points[1]",
        r'unknown point "P"',
    ),
    "unknown driven joint": (
        (DRIVEN, 'type = "translational"\njoint = "guid"'),
        "drivers[0].joint",
        r'unknown joint "guid" \(known translational joints: guide\)',
    ),
    "driven joint not a slider": (
        (DRIVEN, 'type = "translational"\njoint = "pivot"'),
        "drivers[0].joint",
        r'joint "pivot" is revolute; expected a translational joint',
    ),
    "newline in a body name": (
        ('bodies = ["rod", "slider"]', 'bodies = ["rod", "sli\\nder"]'),
        "joints[2].bodies[1]",
        r'unknown body "sli\\nder"',
    ),
    # duplicate names
    "duplicate joint name": (
        ('bodies = ["crank", "rod"]', 'bodies = ["crank", "rod"]\nname = "pivot"'),
        "joints[1].name",
        r'duplicate joint name "pivot"',
    ),
    "duplicate driver name": (
        (LAW, f'{LAW}\nname = "spin"\n\n[[drivers]]\nname = "spin"\ntype = "rotational"\nbodies = ["rod", "ground"]\n{LAW}'),
        "drivers[1].name",
        r'duplicate driver name "spin"',
    ),
    "driver named like a joint": (
        (LAW, f'{LAW}\nname = "guide"'),
        "drivers[0].name",
        r'driver name "guide" is also the name of joints\[3\]: joints and drivers need distinct names$',
    ),
    "duplicate point": (
        ("B = [0.4, 0.0]", "B = [0.4, 0.0]\nA = [0.2, 0.0]"),
        "line 7, column 15",
        r'duplicate key "A": each key may be given only once in a table',
    ),
    "duplicate body table": (
        ("[[joints]]", '[bodies.rod]\norigin = "B"\n\n[[joints]]'),
        "line 21, column 12",
        r"duplicate table \[bodies.rod\]: each table may be declared only once",
    ),
    "duplicate inline key": (
        (LAW, 'law = { type = "linear", rate = 1.0, rate = 2.0 }'),
        "line 46, column 48",
        r'duplicate key "rate" in an inline table',
    ),
    # geometry
    "axis a table": (
        (GUIDE, 'axis = { P = "O", Q = "B" }'), "joints[3].axis", r"expected two points \[P, Q\], got a table"
    ),
    "zero-length axis": (
        (GUIDE, 'axis = ["O", "O"]'), "joints[3].axis", r"zero-length axis: P and Q are the same point O",
    ),
    "coinciding axis points": (
        (GUIDE, 'axis = ["O", [0.0, 0.0]]'), "joints[3].axis", r"zero-length axis: O and \(0, 0\) coincide",
    ),
    "zero direction": (
        (GUIDE, 'at = "O"\ndirection = [0.0, 0.0]'), "joints[3].direction", r"zero-length direction",
    ),
    "same body twice": (
        ('bodies = ["rod", "slider"]', 'bodies = ["rod", "rod"]'),
        "joints[2].bodies",
        r'expected two different bodies, got "rod" twice',
    ),
    # types
    "unknown joint type": (
        ('type = "revolute"\nbodies = ["rod", "slider"]', 'type = "revolut"\nbodies = ["rod", "slider"]'),
        "joints[2].type",
        r'expected one of "revolute", "translational", "rigid", "pin_in_slot", "gear", "rack_pinion", got \'revolut\'',
    ),
    "unknown driver type": (
        ('type = "rotational"', 'type = "rotary"'),
        "drivers[0].type",
        r'expected one of "translational", "rotational", "absolute", "distance", "path", got \'rotary\'',
    ),
    "unknown law type": (
        (LAW, 'law = { type = "sine", amplitude = 0.05 }'),
        "drivers[0].law.type",
        r'expected one of "harmonic", "linear", "polynomial", "spline", got \'sine\'',
    ),
    # the ground
    "ground as a body table": (
        ("[bodies.slider]", "[bodies.ground]"), "bodies.ground", r'"ground" is reserved for the fixed body',
    ),
    "driving the ground": (
        (DRIVEN, 'type = "absolute"\nbody = "ground"\ncoordinate = "x"'),
        "drivers[0].body",
        r"the ground cannot be driven",
    ),
    # syntax
    "unterminated string": (('at = "A"', 'at = "A'), "line 30, column 8", r"invalid TOML: Illegal character"),
    "missing value": (("steps = 201", "steps = "), "line 50, column 9", r"invalid TOML: Invalid value"),
}


def _assert_model_error(path: str, element: str, reason: str) -> ModelError:
    """Load `path` and check that the error reads ``<path>: <element>: <reason>`` on one line."""
    prefix = f"{path}: {element}: " if element else f"{path}: "
    with pytest.raises(ModelError, match="^" + re.escape(prefix) + reason) as caught:
        load_model(path)
    assert "\n" not in str(caught.value)
    return caught.value


@pytest.fixture
def in_tmp_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Work in `tmp_path`, so that files are given by a short relative path."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_slider_crank_of_the_mistakes_is_valid(in_tmp_path: Path):
    Path("model.toml").write_text(SLIDER_CRANK, encoding="utf-8")

    assert load_model("model.toml").name == "slider-crank"


@pytest.mark.parametrize(("edit", "element", "reason"), MISTAKES.values(), ids=MISTAKES.keys())
def test_a_mistake_names_file_element_and_expectation(
    edit: tuple[str, str], element: str, reason: str, in_tmp_path: Path
):
    old, new = edit
    assert SLIDER_CRANK.count(old) >= 1, f"the edit does not apply: {old!r}"
    Path("model.toml").write_text(SLIDER_CRANK.replace(old, new, 1), encoding="utf-8")

    _assert_model_error("model.toml", element, reason)


#: (whole file, element, expected reason as a regex)
WRONG_TOP_LEVEL_TYPES = {
    "name a number": ("name = 5\n", "name", r"expected a non-empty name, got 5"),
    "points an array": (
        "points = [[0.0, 0.0]]\n", "points", r"expected a table \[points\] of name = \[x, y\], got an array",
    ),
    "bodies an array": ('bodies = ["crank"]\n', "bodies", r"expected tables \[bodies.NAME\], got an array"),
    "body a number": (
        "bodies.crank = 1\n", "bodies.crank", r"expected a table \[bodies.crank\], got the number 1",
    ),
    "joints a table": (
        '[joints]\ntype = "rigid"\n', "joints", r"expected an array of tables \[\[joints\]\], got a table",
    ),
    "joint a string": (
        'joints = ["pivot"]\n', "joints[0]", r"expected a table \[\[joints\]\], got the string 'pivot'",
    ),
    "drivers a date": (
        "drivers = 2024-01-01\n",
        "drivers",
        r"expected an array of tables \[\[drivers\]\], got a date or time",
    ),
    "analysis a boolean": (
        "analysis = true\n", "analysis", r"expected a table \[analysis\], got the boolean true",
    ),
}


@pytest.mark.parametrize(
    ("text", "element", "reason"), WRONG_TOP_LEVEL_TYPES.values(), ids=WRONG_TOP_LEVEL_TYPES.keys()
)
def test_wrong_top_level_type(text: str, element: str, reason: str, in_tmp_path: Path):
    Path("model.toml").write_text(text, encoding="utf-8")

    _assert_model_error("model.toml", element, reason)


def test_missing_file(in_tmp_path: Path):
    _assert_model_error("missing.toml", "", r"cannot read the file: No such file or directory")


def test_folder_instead_of_file(in_tmp_path: Path):
    Path("folder.toml").mkdir()

    _assert_model_error("folder.toml", "", r"cannot read the file: ")


def test_bytes_that_are_not_utf8(in_tmp_path: Path):
    Path("latin1.toml").write_bytes('name = "ok"\n[points]\n"café" = [0.0, 0.0]\n'.encode("latin-1"))

    _assert_model_error("latin1.toml", "line 3", r"not UTF-8 text \(byte 0xe9\); expected a file saved as")


def test_path_is_reported_as_given(tmp_path: Path):
    path = tmp_path / "model.toml"
    path.write_text('name = ""\n', encoding="utf-8")

    _assert_model_error(str(path), "name", "expected a non-empty name")


# ------------------------------------------------------------------ mistakes in a spline CSV file

SPLINE_MODEL = """\
[bodies.crank]
origin = [0.0, 0.0]

[[drivers]]
type = "absolute"
body = "crank"
coordinate = "angle"
law = { type = "spline", file = "data/law.csv" }
"""

#: (CSV text, element, expected reason as a regex); the errors name the CSV file.
CSV_MISTAKES = {
    "no header": ("0.0,0.0\n1.0,1.0\n", "line 1", r'expected the header line "t,value", got \'0.0,0.0\''),
    "empty file": ("", "line 1", r'expected the header line "t,value", got \'\''),
    "swapped columns": ("value,t\n0,0\n1,1\n", "line 1", r'expected the header line "t,value"'),
    "not a number": (
        "t,value\n0.0,0.0\n1.0,abc\n", 'line 3, column "value"', r"expected a number, got 'abc'",
    ),
    "nan": ("t,value\n0.0,0.0\nnan,1.0\n", 'line 3, column "t"', r"expected a finite number, got nan"),
    "three cells": ("t,value\n0.0,0.0,1.0\n", "line 2", r"expected two numbers t,value, got '0.0,0.0,1.0'"),
    "one sample": ("t,value\n0.0,0.0\n", 'column "t"', r"expected at least 2 samples, got 1"),
    "times not increasing": (
        "t,value\n0.0,0.0\n2.0,1.0\n1.0,2.0\n", 'column "t"', r"expected strictly increasing times",
    ),
}


@pytest.mark.parametrize(("csv", "element", "reason"), CSV_MISTAKES.values(), ids=CSV_MISTAKES.keys())
def test_a_mistake_in_a_spline_file_names_that_file_and_line(
    csv: str, element: str, reason: str, in_tmp_path: Path
):
    Path("models/data").mkdir(parents=True)
    Path("models/model.toml").write_text(SPLINE_MODEL, encoding="utf-8")
    Path("models/data/law.csv").write_text(csv, encoding="utf-8")

    error = _load_error("models/model.toml")

    expected = "^" + re.escape(f"{Path('models/data/law.csv')}: {element}: ") + reason
    assert re.search(expected, str(error)), str(error)
    assert "\n" not in str(error)


def test_a_missing_spline_file_is_a_mistake_in_the_model(in_tmp_path: Path):
    Path("model.toml").write_text(SPLINE_MODEL, encoding="utf-8")

    _assert_model_error("model.toml", "drivers[0].law.file", r'cannot read "data/law.csv": No such file')


def test_a_spline_file_that_is_not_utf8(in_tmp_path: Path):
    Path("data").mkdir()
    Path("model.toml").write_text(SPLINE_MODEL, encoding="utf-8")
    Path("data/law.csv").write_bytes(b"t,value\n0.0,0.0\n1.0,1.0 \xb0\n")

    error = _load_error("model.toml")

    expected = "line 3: not UTF-8 text (byte 0xb0); expected a file saved as UTF-8"
    assert str(error) == f"{Path('data/law.csv')}: {expected}"


def _load_error(path: str) -> ModelError:
    with pytest.raises(ModelError) as caught:
        load_model(path)
    return caught.value


# ------------------------------------------------------------------ nothing but ModelError


def _toml_value(value: object) -> str:
    """Any parsed TOML value back as TOML text, tables inline."""
    if isinstance(value, dict):
        return "{ " + ", ".join(_toml_pair(key, item) for key, item in value.items()) + " }"
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)  # nan, inf, -inf are TOML too
    if isinstance(value, (int, float)):
        return repr(value)
    return json.dumps(value, ensure_ascii=False)


def _toml_pair(key: str, value: object) -> str:
    return f"{json.dumps(key)} = {_toml_value(value)}"


def _locations(value: object, location: tuple = ()) -> list[tuple]:
    """Every location in a parsed document: tuples of keys and indices."""
    if isinstance(value, dict):
        children = list(value.items())
    else:
        children = list(enumerate(value)) if isinstance(value, list) else []
    found = [location] if location else []
    for key, item in children:
        found.extend(_locations(item, (*location, key)))
    return found


_JUNK = st.recursive(
    st.booleans()
    | st.integers(-3, 3)
    | st.floats()
    | st.sampled_from(["c1", "A", "ground", "initial", "harmonic", "translational", "x", "", "law.csv"])
    | st.text(st.characters(blacklist_categories=("Cs", "Cc")), max_size=4),
    lambda children: st.lists(children, max_size=3)
    | st.dictionaries(st.sampled_from(["type", "at", "bodies", "law", "zz"]), children, max_size=3),
    max_leaves=6,
)
_TASK5_DOCUMENT = tomllib.loads(TASK5.read_text(encoding="utf-8"))


@pytest.mark.filterwarnings("ignore::sparsekin.UnjoinedPointWarning")  # a damaged file may share a point
@settings(max_examples=300, deadline=None)
@given(data=st.data())
def test_a_damaged_file_gives_a_model_error_or_a_mechanism(
    data: st.DataObject, tmp_path_factory: pytest.TempPathFactory
):
    """Any value replaced or removed in task5.toml gives a Mechanism or a one-line ModelError."""
    document = copy.deepcopy(_TASK5_DOCUMENT)
    *parents, last = data.draw(st.sampled_from(_locations(document)))
    container = document
    for key in parents:
        container = container[key]
    if isinstance(container, dict) and data.draw(st.booleans()):
        del container[last]
    else:
        container[last] = data.draw(_JUNK)
    path = tmp_path_factory.mktemp("damaged") / "model.toml"
    path.write_text("\n".join(_toml_pair(key, value) for key, value in document.items()), encoding="utf-8")

    try:
        load_model(path)
    except ModelError as error:
        assert str(error).startswith(f"{path}: ")
        assert "\n" not in str(error)
