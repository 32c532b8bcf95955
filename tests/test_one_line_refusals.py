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
