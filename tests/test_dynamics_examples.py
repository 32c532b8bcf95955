"""The forward-dynamics benchmark files (examples/dynamics/{pendulum,n_four_bar,andrews}.toml)
state the benchmarks that tests/dynamics_reference.py solves: geometry, masses, initial
velocities and loads, read from the TOML itself; and the mechanism they describe loads and
assembles with sparsekin's loader.

Until the loader knows the forward-dynamics keys (body `velocity`, `[analysis] type` and
`max_step`: MODEL_FORMAT.md, "Forward dynamics"), those keys are taken out before loading; every
other key is the kinematic format's.  The files live in examples/dynamics/, apart from the
kinematic gallery of examples/*.toml; the gallery runs those of its ``DYNAMICS_GALLERY``
(docs/_ext/sparsekin_docs.py) by forward dynamics.
"""

import tomllib

import dynamics_reference as ref
import numpy as np
import pytest
from examples_loader import EXAMPLES

from sparsekin import check_model, load_model

DYNAMICS_EXAMPLES = EXAMPLES / "dynamics"
#: The benchmark files (the struck lattice beside them is a gallery example, over-constrained
#: by design: tests/test_dynamic_gallery.py).
BENCHMARKS = ("andrews", "n_four_bar", "pendulum")
#: Keys of the fourth wave that the kinematic loader does not read yet.
DYNAMICS_ONLY = {"bodies": ("velocity",), "analysis": ("type", "max_step")}


def read(name: str) -> dict:
    return tomllib.loads((DYNAMICS_EXAMPLES / f"{name}.toml").read_text())


def without_dynamics_keys(text: str) -> str:
    """The file's text without the lines that set a forward-dynamics-only key: `velocity` in a
    body's table, `type` and `max_step` in [analysis]."""
    kept, table = [], ""
    for line in text.splitlines():
        stripped = line.split("#")[0].strip()
        if stripped.startswith("["):
            table = stripped.strip("[]").split(".")
            table = "analysis" if table == ["analysis"] else "bodies" if "bodies" in table else ""
        elif table and stripped.split("=")[0].strip() in DYNAMICS_ONLY.get(table, ()):
            continue
        kept.append(line)
    return "\n".join(kept)


@pytest.fixture
def load_kinematic(tmp_path):
    def load(name: str):
        path = tmp_path / f"{name}.toml"
        path.write_text(without_dynamics_keys((DYNAMICS_EXAMPLES / f"{name}.toml").read_text()))
        return load_model(path)

    return load


@pytest.mark.parametrize("name", BENCHMARKS)
def test_dynamics_example_loads_and_assembles_with_one_degree_of_freedom(name, load_kinematic):
    document = read(name)
    assert document["analysis"]["type"] == "dynamics" and "drivers" not in document
    mechanism = load_kinematic(name)
    report = check_model(mechanism)
    assert report.assembled and not report.redundant
    assert report.n_coordinates - report.rank == 1  # one degree of freedom, no driver
    assert report.massless_bodies == ()


def test_pendulum_file_is_the_a01_benchmark():
    document = read("pendulum")
    body = document["bodies"]["pendulum"]
    length = np.hypot(*np.subtract(document["points"][body["com"]], document["points"][body["origin"]]))
    assert (length, body["mass"], body["inertia"], body["velocity"]) == (1.0, 1.0, 0.0, [0.0, 0.0, 0.0])
    assert document["gravity"] == [0.0, -ref.GRAVITY]
    position, _ = ref.pendulum_point([0.0])
    np.testing.assert_allclose(document["points"]["P"], position[0], atol=1e-15)  # released horizontal


def test_n_four_bar_file_is_the_a02_benchmark_and_starts_on_the_reference_velocities():
    document = read("n_four_bar")
    n_loops = document["repeat"][0]["count"]
    assert n_loops == 40 and document["analysis"]["steps"] == 401 and document["analysis"]["t_end"] == 20.0
    unit = document["units"]["window"]
    bars = [document["bodies"]["crank0"], unit["bodies"]["crank"], unit["bodies"]["coupler"]]
    points = {**document["points"], **unit["points"]}
    for bar, (start, end) in zip(bars, (("A0", "B0"), ("A", "B"), ("T", "B"))):
        ends = np.array([points[start], points[end]])
        assert np.hypot(*(ends[1] - ends[0])) == 1.0 and bar["mass"] == 1.0
        assert bar["inertia"] == pytest.approx(1.0 / 12.0, rel=1e-15)
        np.testing.assert_array_equal(bar["com"], ends.mean(axis=0))  # uniform bar
    motion = ref.n_four_bar_motion([0.0])
    _, b0_velocity = ref.n_four_bar_b0([0.0])
    for crank in bars[:2]:  # the pivot (frame origin) is fixed; the crank turns at theta'(0)
        assert crank["velocity"] == [0.0, 0.0, motion.rate[0]]
    np.testing.assert_allclose(
        bars[2]["velocity"], [*b0_velocity[0], 0.0], atol=1e-15
    )  # translates with the tips


def test_andrews_file_states_the_reference_geometry_masses_and_loads():
    """Every number of the file against andrews_geometry (whose absolute-coordinate model meets
    the published solution at 30 ms: test_dynamics_reference.py)."""
    document = read("andrews")
    geometry = ref.andrews_geometry()
    assert set(document["points"]) == set(geometry["points"])
    for name, position in geometry["points"].items():
        np.testing.assert_allclose(document["points"][name], position, rtol=1e-15, atol=1e-18)
    assert list(document["bodies"]) == list(geometry["bodies"])
    for name, body in geometry["bodies"].items():
        stated = document["bodies"][name]
        assert (stated["origin"], tuple(stated["points"]), stated["mass"], stated["inertia"]) == (
            body["origin"],
            tuple(body["points"]),
            body["mass"],
            body["inertia"],
        )
        assert stated["angle"] == pytest.approx(body["angle"], abs=1e-15)
        np.testing.assert_allclose(stated["com"], body["com"], rtol=1e-15, atol=1e-18)
        assert stated["velocity"] == [0.0, 0.0, 0.0]
    joints = [(tuple(joint["bodies"]), joint["at"]) for joint in document["joints"]]
    assert joints == [((i, j), at) for i, j, at in geometry["joints"]]
    assert all(joint["type"] == "revolute" for joint in document["joints"])
    spring, torque = document["loads"]
    assert (spring["type"], tuple(spring["bodies"]), tuple(spring["points"])) == (
        "spring",
        geometry["spring"]["bodies"],
        geometry["spring"]["points"],
    )
    assert (spring["stiffness"], spring["free_length"]) == (ref.ANDREWS["c0"], ref.ANDREWS["l0"])
    assert (torque["type"], torque["body"], torque["value"]) == ("torque", "b1", ref.ANDREWS["mom"])
    assert "gravity" not in document


def test_andrews_file_loads_with_the_published_angles(load_kinematic):
    mechanism = load_kinematic("andrews")
    angles = [mechanism.frame(f"b{k}")[2] for k in range(1, 8)]
    np.testing.assert_allclose(ref.andrews_angles_from_bodies(angles), ref.ANDREWS_INITIAL_ANGLES, atol=1e-15)
