"""Hostile input: damaged model files and bad arguments give one clear error, never a crash.

Three valid model files are damaged at random, by hypothesis, in the ways users damage
them: a value of the wrong type, a missing key, NaN, infinity, 1e308, an unknown or a
duplicate name, a degenerate axis, an empty section, bytes that are not UTF-8, a file cut
short.  For every damaged file:

* `load_model` returns a `Mechanism` or raises a one-line `ModelError` naming the file;
* a mechanism that loads is analysed: `solve_kinematics` on three samples succeeds or
  raises a `SparsekinError` (nothing else), and `check_model` returns a report;
* on the command line (``sparsekin.cli.main`` called in-process), ``check`` and ``run``
  exit with 2 and exactly one line on stderr for a file that does not load, and never
  print a traceback.

Each example is cheap (tens of milliseconds) and hypothesis' deadline catches a hang.  The
Python API is checked the same way: every bad argument is refused with a message naming
it.
"""

from __future__ import annotations

import copy
import json
import math
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.sparse import csr_array

from sparsekin import ModelError, SparsekinError, load_model, solve_kinematics
from sparsekin.cli import main
from sparsekin.analysis.check import check_model
from sparsekin.analysis.rank import analyse_jacobian
from sparsekin.testset import task5

ROOT = Path(__file__).resolve().parents[1]
#: tests/data/slider_crank.toml with the other form of translational joint (at + direction)
#: and a spline law, so that the damage reaches both.
SLIDER_CRANK = (
    (ROOT / "tests" / "data" / "slider_crank.toml")
    .read_text(encoding="utf-8")
    .replace('axis = ["O", "B"]', 'at = "B"\ndirection = [1.0, 0.0]')
    .replace(
        'law = { type = "linear", rate = 6.283185307179586 }',
        'law = { type = "spline", times = [0.0, 0.5, 1.0], values = [0.0, 0.6, 1.0] }',
    )
    .replace("t_end = 2.0\nsteps = 201", "t_end = 1.0\nsteps = 11")
)
MODELS = {
    "task5": (ROOT / "examples" / "task5.toml").read_text(encoding="utf-8"),
    "triple_parallelogram": (ROOT / "tests" / "data" / "triple_parallelogram.toml").read_text(encoding="utf-8"),
    "slider_crank": SLIDER_CRANK,
}
DOCUMENTS = {name: tomllib.loads(text) for name, text in MODELS.items()}
#: The samples solved for every damaged mechanism that loads.
TIMES = [0.0, 0.01, 0.02]
#: Per example: a damaged file is loaded, solved on 3 samples, checked, and run through
#: the command line twice.  Tens of milliseconds each on a quiet machine, but 0.3–1.9 s on
#: a loaded one (load 5 on 2 cores: threaded OpenBLAS on the rank analysis' tiny dense
#: blocks; 0.05–0.08 s with OPENBLAS_NUM_THREADS=1), and the examples' number is bounded
#: (`max_examples`): the deadline only catches a hang, far above any load.  (A 3 s deadline
#: failed whole-suite runs at 4.6 and 5.3 s; speed is measured in benchmarks/, not here.)
EXAMPLE_DEADLINE_MS = 60_000


# ---------------------------------------------------------------------- damage
def _toml(value: object) -> str:
    """A parsed TOML value as TOML text (tables inline), NaN and infinities included."""
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{json.dumps(key)} = {_toml(item)}" for key, item in value.items()) + " }"
    if isinstance(value, list):
        return "[" + ", ".join(_toml(item) for item in value) + "]"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else {"nan": "nan", "inf": "inf", "-inf": "-inf"}[repr(value)]
    if isinstance(value, int):
        return str(value)
    return json.dumps(value, ensure_ascii=False)


def _document_text(document: dict) -> str:
    """A whole document: top-level tables and arrays of tables written out, the rest inline."""
    lines = []
    for key, value in document.items():
        if isinstance(value, dict) and key in ("points", "analysis"):
            lines.append(f"[{json.dumps(key)}]")
            lines += [f"{json.dumps(k)} = {_toml(v)}" for k, v in value.items()]
        elif key == "bodies" and isinstance(value, dict) and all(isinstance(v, dict) for v in value.values()):
            for name, table in value.items():
                lines.append(f"[bodies.{json.dumps(name)}]")
                lines += [f"{json.dumps(k)} = {_toml(v)}" for k, v in table.items()]
        elif key in ("joints", "drivers") and isinstance(value, list) and all(isinstance(v, dict) for v in value):
            for table in value:
                lines.append(f"[[{key}]]")
                lines += [f"{json.dumps(k)} = {_toml(v)}" for k, v in table.items()]
        else:
            lines.insert(0, f"{json.dumps(key)} = {_toml(value)}")
    return "\n".join(lines) + "\n"


def _locations(value: object, location: tuple = ()) -> list[tuple]:
    """Every location in a parsed document, as a tuple of keys and indices."""
    if isinstance(value, dict):
        children = list(value.items())
    elif isinstance(value, list):
        children = list(enumerate(value))
    else:
        children = []
    found = [location] if location else []
    for key, item in children:
        found.extend(_locations(item, (*location, key)))
    return found


def _names(document: dict) -> list[str]:
    """Names that appear in the document: points, bodies, joints; for look-alike damage."""
    names = []
    for section in ("points", "bodies"):
        if isinstance(document.get(section), dict):
            names += list(document[section])
    if isinstance(document.get("joints"), list):
        names += [joint["name"] for joint in document["joints"] if isinstance(joint, dict) and "name" in joint]
    return names + ["ground", "c11", "", " ", "ground2", "A\nB"]


#: Values that replace a value of the document: wrong types, non-finite and huge numbers,
#: names, degenerate geometry.
REPLACEMENTS = (
    st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 1e16, 5e-324, 0.0, -0.0, 0, -1, 2**63 - 1])
    | st.sampled_from([True, False, "", "initial", "harmonic", "translational", "x", "angle", "law.csv"])
    | st.sampled_from([[], [0.0], [0.0, 0.0], [0.0, 0.0, 0.0], ["A", "A"], [[0.0, 0.0], [0.0, 0.0]], {}, {"type": "linear"}])
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.integers(-(2**70), 2**70)
    | st.text(st.characters(blacklist_categories=("Cs",)), max_size=5)
    | st.lists(st.floats(-10, 10), max_size=4)
)


@st.composite
def damaged_documents(draw: st.DrawFn) -> tuple[str, str]:
    """(model name, TOML text) of a model with one to three values damaged."""
    model = draw(st.sampled_from(sorted(DOCUMENTS)))
    document = copy.deepcopy(DOCUMENTS[model])
    for _ in range(draw(st.integers(1, 3))):
        locations = _locations(document)
        if not locations:
            break
        *parents, last = draw(st.sampled_from(locations))
        container = document
        try:
            for key in parents:
                container = container[key]
        except (KeyError, IndexError, TypeError):  # an earlier damage removed the way there
            continue
        action = draw(st.sampled_from(["replace", "delete", "name", "empty", "duplicate"]))
        if action == "delete" and isinstance(container, (dict, list)):
            del container[last]
        elif action == "name":
            container[last] = draw(st.sampled_from(_names(document)))
        elif action == "empty":
            container[last] = copy.deepcopy(draw(st.sampled_from([{}, [], ""])))
        elif action == "duplicate" and isinstance(container, list):
            container.append(copy.deepcopy(container[last]))
        else:
            container[last] = copy.deepcopy(draw(REPLACEMENTS))  # sampled values are shared objects
    return model, _document_text(document)


@st.composite
def damaged_bytes(draw: st.DrawFn) -> tuple[str, bytes]:
    """(model name, file content) of a model cut short, or with bytes inserted or repeated."""
    model = draw(st.sampled_from(sorted(MODELS)))
    data = MODELS[model].encode("utf-8")
    action = draw(st.sampled_from(["truncate", "insert", "repeat_line", "swap_lines"]))
    if action == "truncate":
        return model, data[: draw(st.integers(0, len(data)))]
    lines = data.split(b"\n")
    if action == "insert":
        where = draw(st.integers(0, len(data)))
        junk = draw(st.sampled_from([b"\xff", b"\xc3", b"\x80\x80", b"\x00", b"\xef\xbb\xbf", b"\r", b"[[", b"]", b"=", b'"']))
        return model, data[:where] + junk + data[where:]
    k = draw(st.integers(0, len(lines) - 1))
    if action == "repeat_line":
        return model, b"\n".join(lines[: k + 1] + lines[k:])
    j = draw(st.integers(0, len(lines) - 1))
    lines[k], lines[j] = lines[j], lines[k]
    return model, b"\n".join(lines)


# ---------------------------------------------------------------------- the checks
def _assert_handled(path: Path, tmp: Path, capsys: pytest.CaptureFixture) -> None:
    """Load, analyse and run `path`; only sparsekin's errors, one line each, no traceback."""
    try:
        mechanism = load_model(path)
    except ModelError as error:
        message = str(error)
        assert message.startswith(f"{path}: ") and "\n" not in message
        mechanism = None
    if mechanism is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # redundant equations left out
            try:
                solve_kinematics(mechanism, TIMES)
            except SparsekinError:
                pass
            except ValueError as error:  # the three samples leave the range of a spline law
                assert "`times` span" in str(error)
        report = check_model(mechanism)
        assert report.sound == (not report.problems)
    capsys.readouterr()
    for arguments in (["check", str(path)],
                      ["run", str(path), "--t-end", "0.02", "--steps", "3", "--out", str(tmp / "out")]):  # fmt: skip
        status = main(arguments)
        captured = capsys.readouterr()
        assert "Traceback" not in captured.err + captured.out
        if mechanism is None:
            assert status == 2, arguments
            (line,) = captured.err.splitlines()
            assert line.startswith(f"sparsekin: error: {path}: ")
        else:
            assert status in ((0, 1, 2) if arguments[0] == "check" else (0, 2, 3)), arguments
            errors = [line for line in captured.err.splitlines() if not line.startswith("sparsekin: warning: ")]
            # nothing on success or a problem found by check; one line for an error; two when a
            # run stops (the reason, then what was written)
            assert len(errors) == {0: 0, 1: 0, 2: 1, 3: 2}[status], captured.err


@pytest.mark.filterwarnings("ignore::sparsekin.UnjoinedPointWarning")  # a damaged file may share a point
@settings(
    max_examples=80, deadline=EXAMPLE_DEADLINE_MS,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)  # fmt: skip
@given(damaged=damaged_documents())
def test_a_damaged_document_gives_one_clear_error(damaged, tmp_path: Path, capsys: pytest.CaptureFixture, warm):
    model, text = damaged
    path = tmp_path / f"{model}.toml"
    path.write_text(text, encoding="utf-8")
    _assert_handled(path, tmp_path, capsys)


@pytest.mark.filterwarnings("ignore::sparsekin.UnjoinedPointWarning")  # a damaged file may share a point
@settings(
    max_examples=60, deadline=EXAMPLE_DEADLINE_MS,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)  # fmt: skip
@given(damaged=damaged_bytes())
def test_damaged_bytes_give_one_clear_error(damaged, tmp_path: Path, capsys: pytest.CaptureFixture, warm):
    model, data = damaged
    path = tmp_path / f"{model}.toml"
    path.write_bytes(data)
    _assert_handled(path, tmp_path, capsys)


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """Each undamaged model through every step of an example once, before the examples:
    the kernels each one needs compiled (or read from numba's cache) and the modules the
    command line imports loaded, outside the examples' time."""
    folder = tmp_path_factory.mktemp("warm")
    for name, text in MODELS.items():
        path = folder / f"{name}.toml"
        path.write_text(text, encoding="utf-8")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            solve_kinematics(load_model(path), TIMES)
            check_model(load_model(path))
            main(["check", str(path)])
            main(["run", str(path), "--t-end", "0.02", "--steps", "3", "--out", str(folder / "out")])


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda d: d["points"].update(A=[math.nan, 0.2]), r"points\.A\[0\]: expected a finite number, got nan"),
        (lambda d: d["points"].update(A=[1e308, 0.2]), r"points\.A\[0\]: expected a number of magnitude at most"),
        (lambda d: d["joints"][12].update(axis=["N", "N"]), r"joints\[12\]\.axis: zero-length axis"),
        (lambda d: d["joints"][0].update(bodies=["c3", "c3"]), r"joints\[0\]\.bodies: expected two different bodies"),
        (lambda d: d["joints"][13].update(name="actuator1"), r'joints\[13\]\.name: duplicate joint name "actuator1"'),
        (lambda d: d["drivers"][0]["law"].update(amplitude=math.inf), r"drivers\[0\]\.law\.amplitude: expected a finite"),
        (lambda d: d["drivers"][0].pop("law"), r'drivers\[0\]: missing key "law"'),
        (lambda d: d.update(points={}), r'bodies\.c1\.origin: unknown point "A"'),
        (lambda d: d["analysis"].update(steps=1.5), r"analysis\.steps: expected a whole number, got 1\.5"),
    ],
    ids=["nan", "1e308", "degenerate-axis", "same-body", "duplicate-name", "inf-law", "missing-law",
         "empty-points", "float-steps"],
)  # fmt: skip
def test_each_kind_of_damage_is_named(edit, expected, tmp_path: Path, capsys: pytest.CaptureFixture):
    document = copy.deepcopy(DOCUMENTS["task5"])
    edit(document)
    path = tmp_path / "damaged.toml"
    path.write_text(_document_text(document), encoding="utf-8")
    with pytest.raises(ModelError, match=expected):
        load_model(path)
    assert main(["check", str(path)]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"sparsekin: error: {path}: ")


@pytest.mark.parametrize(
    ("data", "expected"),
    [(b"", None), (b"\xff\xfe", r"line 1: not UTF-8 text"), (MODELS["task5"].encode()[:700], r"invalid TOML|unknown|missing"),
     (b"[bodies.c1]\norigin = [0.0, 0.0]\n", None)],
    ids=["empty", "utf16-bom", "truncated", "lone-body"],
)  # fmt: skip
def test_empty_odd_and_cut_files(data, expected, tmp_path: Path, capsys: pytest.CaptureFixture):
    path = tmp_path / "odd.toml"
    path.write_bytes(data)
    if expected is not None:
        with pytest.raises(ModelError, match=expected):
            load_model(path)
    _assert_handled(path, tmp_path, capsys)


def test_an_empty_model_is_checked_and_solved(tmp_path: Path, capsys: pytest.CaptureFixture):
    """No bodies, no joints: nothing to solve, nothing wrong."""
    path = tmp_path / "empty.toml"
    path.write_text("", encoding="utf-8")
    mechanism = load_model(path)
    result = solve_kinematics(mechanism, TIMES)
    assert result.complete and result.coordinates.shape == (3, 0)
    assert check_model(mechanism).sound
    assert main(["check", str(path)]) == 0


# ---------------------------------------------------------------------- the Python API
@pytest.fixture(scope="module")
def mechanism():
    return task5()


@pytest.mark.parametrize(
    ("times", "expected"),
    [
        ([[0.0, 1.0]], r"`times` must be a non-empty 1-D array, got shape \(1, 2\)"),
        ([], r"`times` must be a non-empty 1-D array, got shape \(0,\)"),
        (0.5, r"`times` must be a non-empty 1-D array, got shape \(\)"),
        ([0.0, math.nan], r"`times` must be finite"),
        ([0.0, math.inf], r"`times` must be finite"),
        ([0.0, 1.0, 1.0], r"`times` must be strictly increasing"),
        ([1.0, 0.0], r"`times` must be strictly increasing"),
        (["a", "b"], r"`times` must be an array of numbers, got list"),
        ([0.0, 1j], r"`times` must be an array of numbers, got list"),
        (None, r"`times` must be a non-empty 1-D array, got shape \(\)"),
    ],
    ids=["2-d", "empty", "scalar", "nan", "inf", "repeated", "decreasing", "strings", "complex", "none"],
)
def test_bad_times_are_refused(mechanism, times, expected):
    with pytest.raises(ValueError, match=expected):
        solve_kinematics(mechanism, times)


@pytest.mark.parametrize(
    ("tolerance", "expected"),
    [(True, r"`tolerance` must be a positive number, got True"), ("1e-12", r"`tolerance` must be a positive number"),
     (-1e-12, r"`tolerance` must be a number in \["), (0.0, r"`tolerance` must be a number in \["),
     (math.nan, r"`tolerance` must be a number in \["), (1e-20, r"`tolerance` must be a number in \["),
     (1.0, r"`tolerance` must be a number in \[")],
    ids=["bool", "string", "negative", "zero", "nan", "below-rounding", "one"],
)  # fmt: skip
def test_bad_tolerance_is_refused(mechanism, tolerance, expected):
    with pytest.raises(ValueError, match=expected):
        solve_kinematics(mechanism, [0.0], tolerance=tolerance)


@pytest.mark.parametrize("max_iterations", [0, -1, 1.5, True, "12", None], ids=str)
def test_bad_max_iterations_is_refused(mechanism, max_iterations):
    with pytest.raises(ValueError, match=r"`max_iterations` must be a whole number >= 1, got"):
        solve_kinematics(mechanism, [0.0], max_iterations=max_iterations)


def test_numpy_numbers_are_accepted(mechanism):
    result = solve_kinematics(mechanism, np.array([0.0, 0.01]), tolerance=np.float64(1e-12), max_iterations=np.int64(5))
    assert result.complete


@pytest.mark.parametrize("not_a_mechanism", [None, "task5.toml", {"bodies": []}], ids=["none", "path", "dict"])
def test_only_a_mechanism_is_solved_or_checked(not_a_mechanism):
    with pytest.raises(TypeError, match=r"`mechanism` must be a Mechanism, got"):
        solve_kinematics(not_a_mechanism, [0.0])
    with pytest.raises(TypeError, match=r"`mechanism` must be a Mechanism, got"):
        check_model(not_a_mechanism)


@pytest.mark.parametrize("time", [math.nan, math.inf, "0", True, None], ids=str)
def test_check_model_refuses_a_bad_time(mechanism, time):
    with pytest.raises(ValueError, match=r"`time` must be a finite number \(s\), got"):
        check_model(mechanism, time=time)


def test_check_command_refuses_a_bad_time(capsys: pytest.CaptureFixture):
    assert main(["check", str(ROOT / "examples" / "task5.toml"), "--time", "nan"]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line == "sparsekin: error: --time must be a finite number (s), got nan"


@pytest.mark.parametrize(
    ("jacobian", "expected"),
    [(csr_array(np.array([[1.0, math.nan]])), r"`jacobian` must have finite entries"),
     (np.ones(3), r"`jacobian` must be a 2-D matrix, got shape \(3,\)")],
    ids=["nan", "1-d"],
)  # fmt: skip
def test_analyse_jacobian_refuses_bad_input(jacobian, expected):
    with pytest.raises(ValueError, match=expected):
        analyse_jacobian(jacobian)


def test_a_polynomial_names_its_bad_coefficient():
    from sparsekin import Polynomial

    with pytest.raises(ModelError, match=r"^coefficients\[1\]: expected a finite number, got nan$"):
        Polynomial((0.0, float("nan")))
    with pytest.raises(ModelError, match=r"^coefficients\[2\]: expected a number, got "):
        Polynomial((None, 1.0, "x"))


def test_a_pattern_of_another_mechanism_is_refused():
    from sparsekin import AbsoluteDriver, Body, Linear, Mechanism, Revolute
    from sparsekin.engine.pattern import build_pattern

    def slider(joints, drivers, origin="O"):
        return Mechanism(points={"O": (0.0, 0.0), "P": (1.0, 0.5)}, bodies=[Body("slider", origin=origin)],
                         joints=joints, drivers=drivers)  # fmt: skip

    def turning(axis="angle"):
        return AbsoluteDriver("slider", axis, law=Linear(rate=1.0))

    pinned = slider([Revolute(("slider", "ground"), at="O")], [turning()])
    times = [0.0, 0.5]
    assert solve_kinematics(pinned, times, pattern=build_pattern(pinned)).complete
    driven = slider([], [turning(axis) for axis in ("x", "y", "angle")])
    moved = slider([Revolute(("slider", "ground"), at="P")], [turning()], origin="P")
    with pytest.raises(ValueError, match=r"^`pattern` must be a ConstraintPattern \(build_pattern\), got dict\.$"):
        solve_kinematics(pinned, times, pattern={})
    cases = [
        (build_pattern(task5()), "it has 10 bodies and 30 equations, `mechanism` 1 and 3"),
        (build_pattern(driven), "its joints and drivers have other numbers of equations"),
        (build_pattern(moved), "its bodies are drawn elsewhere"),
    ]
    for pattern, why in cases:
        with pytest.raises(ValueError, match=rf"^`pattern` must be the ConstraintPattern of a mechanism like "
                           rf"`mechanism`: {why}\.$"):  # fmt: skip
            solve_kinematics(pinned, times, pattern=pattern)
