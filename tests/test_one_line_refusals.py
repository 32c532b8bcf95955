"""Small hostile inputs that ended in overflow, a bare TypeError or an AttributeError, or
were taken for something else: each is now one error naming the argument or element."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sparsekin import ModelError, Spline, load_model, solve_kinematics
from sparsekin.testset import task5

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_spline_samples_too_close_are_refused():
    with pytest.raises(ModelError, match=r"^times: times\[0\] = 0\.0 and times\[1\] = 1e-300 are 1e-300 s apart: "
                                         r"expected samples at least 1e-09 of the span apart"):  # fmt: skip
        Spline([0.0, 1e-300, 10.0], [0.0, 1.0, 2.0])
    Spline([0.0, 1e-6, 10.0], [0.0, 1e-7, 2.0])  # close, not absurd: accepted


@pytest.mark.parametrize("times, what", [(np.array([0.0, 1j]), "ndarray of complex128"), (["0", "1"], "list of <U1"),
                                         ([True, False], "list of bool"), ("0 1", "str of <U")])  # fmt: skip
def test_times_must_be_real_numbers(times, what):
    """Numbers written as text, complex numbers and booleans were read as real times."""
    with pytest.raises(ValueError, match=rf"^`times` must be an array of numbers, got {what}"):
        solve_kinematics(task5(), times)


@pytest.mark.parametrize("options, expected", [
    ({"coordinates": "no"}, r"^`coordinates` must be True or False, got 'no'\.$"),
    ({"points": [["K"]]}, r"""^`points` must be None, "all" or a list of point names, got \[\['K'\]\]\.$"""),
])  # fmt: skip
def test_recording_options_are_checked(options, expected):
    with pytest.raises(ValueError, match=expected):
        solve_kinematics(task5(), [0.0, 0.1], **options)


def test_a_joint_asked_by_a_number_that_is_no_index_is_one_key_error():
    result = solve_kinematics(task5(), [0.0, 0.1])
    with pytest.raises(KeyError, match=r"expected a joint's name, joints\[i\] or the index i, got 1\.5"):
        result.joint(1.5)
    np.testing.assert_array_equal(result.joint(0).value, result.joint("joints[0]").value)


def test_a_body_that_a_repeat_leaves_out_is_named_as_such(tmp_path):
    """The lattice's last column has no horizontal bar H: a driver of c8_5.H is told so, and
    an unknown body is told the copies' bodies too (not only ``ground``)."""
    text = (EXAMPLES / "lattice.toml").read_text()
    driver = '\n[[drivers]]\ntype = "rotational"\nbodies = ["{}", "ground"]\nlaw = {{ type = "linear", rate = 1.0 }}\n'
    (tmp_path / "left_out.toml").write_text(text + driver.format("c8_5.H"))
    with pytest.raises(ModelError, match=r'drivers\[0\]\.bodies\[0\]: body "c8_5\.H": copy "c8_5" of unit "cell" has '
                                         r'no body "H" \(the repeat leaves it out there\)$'):  # fmt: skip
        load_model(tmp_path / "left_out.toml")
    (tmp_path / "unknown.toml").write_text(text + driver.format("zz"))
    with pytest.raises(ModelError, match=r'unknown body "zz" \(known: ground, c0_0\.V …, c0_0\.H …\)$'):
        load_model(tmp_path / "unknown.toml")


def test_a_built_mechanism_cannot_be_changed():
    """`mechanism.points[...] = ...` changed the points without their checks (a point of a
    body moved without its joints knowing); now every table of a built mechanism refuses,
    and the mechanism still pickles (to Dask workers) and is rebuilt by `replace`."""
    import dataclasses
    import pickle

    mechanism = task5()
    with pytest.raises(TypeError, match=r"^a built mechanism cannot be changed: build a new one"):
        mechanism.points["A"] = (1e9, 0.0)
    for change in (lambda points: points.update(A=(0.0, 0.0)), lambda points: points.pop("A"),
                   lambda points: points.clear(), lambda points: points.setdefault("Z", (0.0, 0.0)),
                   lambda points: points.__ior__({"Z": (0.0, 0.0)}), lambda points: points.__delitem__("A")):  # fmt: skip
        with pytest.raises(TypeError):
            change(mechanism.points)
    assert mechanism.points["A"] == (-1.0, 0.2) and "Z" not in mechanism.points
    grid = load_model(EXAMPLES / "lattice.toml")
    repeat = grid.repeats[0]
    for table in (grid.points.own, repeat.unit.points, repeat.unit.only, repeat.boundary, repeat.vary):
        with pytest.raises(TypeError):
            table["Z"] = (0.0, 0.0)
    assert pickle.loads(pickle.dumps(mechanism)) == mechanism and pickle.loads(pickle.dumps(grid)) == grid
    moved = dataclasses.replace(mechanism, points={**mechanism.points, "A": (-1.0, 0.25)})
    assert moved.points["A"] == (-1.0, 0.25) and mechanism.points["A"] == (-1.0, 0.2)


def _four_bar(crank_tip):
    """A four-bar whose crank turns about O and ends at `crank_tip`."""
    from sparsekin import Body, Linear, Mechanism, Revolute, RotationalDriver

    return Mechanism(
        points={"O": (0.0, 0.0), "A": crank_tip, "B": (0.3, 0.3), "Q": (0.4, 0.0)},
        bodies=[Body("crank", origin="O", points=("O", "A")), Body("coupler", origin="A", points=("A", "B")),
                Body("rocker", origin="Q", points=("Q", "B"))],
        joints=[Revolute(("crank", "ground"), at="O"), Revolute(("crank", "coupler"), at="A"),
                Revolute(("coupler", "rocker"), at="B"), Revolute(("rocker", "ground"), at="Q")],
        drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=1.0))],
    )  # fmt: skip


def test_a_driven_crank_of_zero_length_is_not_sound(tmp_path, capsys):
    """A crank whose tip is drawn at its pivot: rank full, zero degrees of freedom, and it
    ran motionless (only its own angle turns); `check` now names the driver."""
    from sparsekin import check_model
    from sparsekin.cli import main

    zero = _four_bar((0.0, 0.0))
    motion = solve_kinematics(zero, np.linspace(0.0, 1.0, 5)).coordinates
    assert np.ptp(motion, axis=0).tolist() == [0.0, 0.0, 1.0] + [0.0] * 6  # the reproduction: nothing but the crank turns
    report = check_model(zero)
    assert report.rank == 9 and not report.free_motions and not report.redundant
    assert report.problems == ("1 driver moving no point (drivers[0] (angle crank − ground))",)
    assert check_model(_four_bar((0.1, 0.0))).sound  # a crank of 0.1 m: sound, as before
    text = (EXAMPLES / "four_bar.toml").read_text()
    model = tmp_path / "zero_crank.toml"
    model.write_text(text.replace("A = [0.1, 0.0]", "A = [0.0, 0.0]"))  # the crank pin drawn on its pivot
    assert "A = [0.1, 0.0]" in text
    assert main(["check", str(model)]) == 1  # a problem (0: sound)
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1].startswith("verdict: 1 driver moving no point (drivers[0] ("), lines[-1]
    assert sum(line.startswith("drivers moving no point (1): drivers[0] (") for line in lines) == 1
