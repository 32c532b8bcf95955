"""``sparsekin run``: the files it writes, its messages and its exit status."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sparsekin import solve_kinematics
from sparsekin.cli import main
from sparsekin.cli.files import point_table, write_coordinates, write_points_csv
from sparsekin.model.modelfile import load_model

TASK5 = Path(__file__).resolve().parents[1] / "examples" / "task5.toml"
TASK5_BODIES = [f"c{k}" for k in range(1, 11)]
HEADER_A_K = "t,A.x,A.y,A.vx,A.vy,A.ax,A.ay,K.x,K.y,K.vx,K.vy,K.ax,K.ay"


def task5_variant(tmp_path: Path, old: str, new: str, name: str = "variant.toml") -> Path:
    """A copy of task5.toml with every `old` replaced by `new`."""
    text = TASK5.read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return path


def read_csv(path: Path) -> tuple[str, np.ndarray]:
    """The header line and the rows as floats parsed by `float`."""
    header, *rows = path.read_text().splitlines()
    return header, np.array([[float(cell) for cell in row.split(",")] for row in rows]).reshape(
        len(rows), header.count(",") + 1
    )


def error_lines(capsys) -> list[str]:
    return capsys.readouterr().err.splitlines()


@pytest.fixture
def task5_run(tmp_path, capsys):
    """``run task5.toml --t-end 1 --steps 11 --points A,K``: exit status, folder, stdout."""
    out = tmp_path / "out"
    status = main(["run", str(TASK5), "--t-end", "1", "--steps", "11", "--points", "A,K", "--out", str(out)])
    return status, out, capsys.readouterr()


# ---------------------------------------------------------------------- success
def test_run_writes_points_of_the_analysis(task5_run):
    status, out, captured = task5_run
    assert status == 0
    assert captured.err == ""
    header, rows = read_csv(out / "points.csv")
    assert header == HEADER_A_K
    assert rows.shape == (11, 13)
    result = solve_kinematics(load_model(TASK5), np.linspace(0.0, 1.0, 11))
    np.testing.assert_allclose(rows[:, 0], np.linspace(0.0, 1.0, 11), rtol=0, atol=1e-15)
    for first, name in ((1, "A"), (7, "K")):
        expected = np.hstack(result.point(name))
        np.testing.assert_allclose(rows[:, first : first + 6], expected, rtol=1e-12, atol=1e-12)


def test_first_row_is_the_assembly_configuration_of_the_file(task5_run):
    _, out, _ = task5_run
    _, rows = read_csv(out / "points.csv")
    assert (rows[0, 1], rows[0, 2]) == (-1.0, 0.2)  # A = [-1.0, 0.2] in task5.toml
    assert (rows[0, 7], rows[0, 8]) == (-1.2, 0.6)  # K


def test_points_csv_reads_back_bit_identical(tmp_path):
    result = solve_kinematics(load_model(TASK5), np.linspace(0.0, 1.0, 11))
    path = write_points_csv(result, ["A", "K"], tmp_path / "points.csv")
    _, rows = read_csv(path)
    assert np.array_equal(rows, point_table(result, ["A", "K"]))


def test_coordinates_npz_holds_every_body(task5_run):
    _, out, _ = task5_run
    with np.load(out / "coordinates.npz") as arrays:
        assert arrays["t"].shape == (11,)
        for key in ("q", "qd", "qdd"):
            assert arrays[key].shape == (11, 30)
        assert list(arrays["body_names"]) == TASK5_BODIES
        result = solve_kinematics(load_model(TASK5), np.linspace(0.0, 1.0, 11))
        np.testing.assert_allclose(arrays["q"], result.coordinates, rtol=1e-12, atol=1e-12)


def test_summary_names_samples_and_files(task5_run):
    _, out, captured = task5_run
    assert "11 samples" in captured.out
    assert "Newton corrections per step" in captured.out
    assert "factorizations" in captured.out
    assert str(out / "points.csv") in captured.out


def test_defaults_come_from_the_analysis_table(tmp_path, monkeypatch, capsys):
    model = task5_variant(tmp_path, "t_end = 10.0\nsteps = 1001", "t_end = 0.5\nsteps = 6")
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(model)]) == 0
    header, rows = read_csv(tmp_path / "sparsekin-out" / "task5" / "points.csv")
    assert header.split(",")[1::6] == ["A.x", "J.x", "K.x"]
    assert rows[:, 0].tolist() == np.linspace(0.0, 0.5, 6).tolist()


def test_without_analysis_points_every_named_point_is_written(tmp_path, capsys):
    model = task5_variant(tmp_path, 'points = ["A", "J", "K"]', "")
    assert main(["run", str(model), "--t-end", "0.1", "--steps", "2", "--out", str(tmp_path / "out")]) == 0
    header, _ = read_csv(tmp_path / "out" / "points.csv")
    assert header.split(",")[1::6] == [f"{name}.x" for name in "ABDEFGHIJKLMN"]


def test_python_dash_m_runs_the_command(tmp_path):
    out = tmp_path / "out"
    completed = subprocess.run(
        [sys.executable, "-m", "sparsekin", "run", str(TASK5), "--t-end", "1", "--steps", "11",
         "--points", "A,K", "--out", str(out)],
        capture_output=True, text=True, timeout=300,
    )
    assert completed.returncode == 0, completed.stderr
    assert "11 samples" in completed.stdout
    assert (out / "points.csv").read_text().splitlines()[0] == HEADER_A_K


# ---------------------------------------------------------------------- bad model or arguments
def test_bad_model_is_one_line_without_traceback(tmp_path, capsys):
    model = task5_variant(tmp_path, 'bodies = ["c3", "c4"]', 'bodies = ["c3", "c11"]', name="broken.toml")
    assert main(["run", str(model), "--out", str(tmp_path / "out")]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("sparsekin: error: ")
    assert "broken.toml" in lines[0] and "joints[1].bodies" in lines[0] and '"c11"' in lines[0]
    assert "Traceback" not in captured.err
    assert not (tmp_path / "out").exists()


def test_unknown_point_names_it_and_lists_the_known(tmp_path, capsys):
    assert main(["run", str(TASK5), "--t-end", "1", "--points", "A,Q", "--out", str(tmp_path)]) == 2
    (line,) = error_lines(capsys)
    assert '"Q"' in line and "A, B, D" in line


def test_missing_end_time_says_how_to_give_it(tmp_path, capsys):
    model = task5_variant(tmp_path, "t_end = 10.0\n", "")
    assert main(["run", str(model), "--out", str(tmp_path / "out")]) == 2
    (line,) = error_lines(capsys)
    assert "--t-end" in line and "[analysis].t_end" in line


@pytest.mark.parametrize(
    "options",
    [["--steps", "0"], ["--steps", "-3"], ["--t-end", "nan"], ["--t-end", "inf"], ["--t-end", "-1"],
     ["--t-end", "0", "--steps", "5"]],
    ids=["steps-zero", "steps-negative", "t-end-nan", "t-end-inf", "t-end-negative", "t-end-zero"],
)
def test_bad_numbers_are_one_line(tmp_path, capsys, options):
    assert main(["run", str(TASK5), *options, "--out", str(tmp_path / "out")]) == 2
    (line,) = error_lines(capsys)
    assert line.startswith("sparsekin: error: ") and options[-2] in line


@pytest.mark.parametrize(
    "arguments", [[], ["run"], ["run", str(TASK5), "--steps", "many"], ["walk", str(TASK5)]],
    ids=["no-command", "no-model", "steps-not-a-number", "unknown-command"],
)
def test_usage_errors_exit_2(capsys, arguments):
    assert main(arguments) == 2
    assert "usage: sparsekin" in capsys.readouterr().err


def test_plot_without_matplotlib_says_what_to_install(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    assert main(["run", str(TASK5), "--t-end", "1", "--plot", "--out", str(tmp_path / "out")]) == 2
    (line,) = error_lines(capsys)
    assert 'pip install "sparsekin[plot]"' in line
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------- analysis stops
def test_locking_mechanism_keeps_the_samples_before_the_dead_centre(tmp_path, capsys):
    model = task5_variant(tmp_path, "amplitude = 0.05", "amplitude = 0.06")
    out = tmp_path / "out"
    assert main(["run", str(model), "--t-end", "2", "--steps", "201", "--out", str(out)]) == 3
    lines = error_lines(capsys)
    assert len(lines) == 2
    assert lines[0].startswith("sparsekin: analysis stopped: ") and "t = 0.7" in lines[0]
    _, rows = read_csv(out / "points.csv")
    assert 50 < len(rows) < 201
    assert f"wrote {len(rows)} of 201 samples" in lines[1]
    with np.load(out / "coordinates.npz") as arrays:
        assert arrays["q"].shape == (len(rows), 30)
        assert arrays["t"].tolist() == rows[:, 0].tolist()


def test_failure_at_the_first_sample_writes_the_header_only(tmp_path, capsys):
    unreachable = "law = { type = \"polynomial\", coefficients = [5.0] }"  # a 5 m stroke cannot be reached
    model = task5_variant(tmp_path, 'law = { type = "harmonic", amplitude = 0.05, omega = 1.5 }', unreachable)
    out = tmp_path / "out"
    assert main(["run", str(model), "--t-end", "1", "--steps", "11", "--out", str(out)]) == 3
    assert "wrote 0 of 11 samples" in error_lines(capsys)[1]
    assert (out / "points.csv").read_text().splitlines() == ["t" + "".join(
        f",{name}.{column}" for name in "AJK" for column in ("x", "y", "vx", "vy", "ax", "ay"))]
    with np.load(out / "coordinates.npz") as arrays:
        assert arrays["t"].shape == (0,) and arrays["q"].shape == (0, 30)


def test_no_result_writes_empty_files(tmp_path):
    header, rows = read_csv(write_points_csv(None, ["A"], tmp_path / "points.csv"))
    assert header == "t,A.x,A.y,A.vx,A.vy,A.ax,A.ay" and rows.size == 0
    with np.load(write_coordinates(None, ["c1", "c2"], tmp_path / "coordinates.npz")) as arrays:
        assert arrays["qdd"].shape == (0, 6) and list(arrays["body_names"]) == ["c1", "c2"]


# ---------------------------------------------------------------------- figures
def test_plot_writes_the_figures(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    out = tmp_path / "out"
    assert main(["run", str(TASK5), "--t-end", "1", "--steps", "11", "--points", "A,K", "--plot",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for name in ("point_A.png", "point_K.png", "mechanism.png"):
        assert (out / name).read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
        assert str(out / name) in printed


def test_joints_csv_holds_each_joint_coordinate(task5_run):
    """Revolutes by label (no name: joints[i]), then the two actuators' strokes."""
    _, out, _ = task5_run
    header, rows = read_csv(out / "joints.csv")
    columns = header.split(",")
    assert columns[:4] == ["t", "joints[0].angle", "joints[0].rate", "joints[0].accel"]
    assert columns[-6:] == [
        "actuator1.stroke", "actuator1.speed", "actuator1.accel", "actuator2.stroke", "actuator2.speed",
        "actuator2.accel",
    ]  # fmt: skip
    assert len(columns) == 1 + 3 * 14
    result = solve_kinematics(load_model(TASK5), np.linspace(0.0, 1.0, 11))
    assert np.array_equal(rows[:, -6:-3], np.column_stack(result.joint("actuator1")))  # repr: bit for bit
    assert np.array_equal(rows[:, 1:4], np.column_stack(result.joint(0)))


def test_a_model_without_bodies_runs_and_says_so(tmp_path, capsys):
    """Nothing to solve sample by sample: the summary still gives its times (found by the
    hostile-input fuzzing in a run without a hypothesis database: an empty file)."""
    model = tmp_path / "empty.toml"
    model.write_text('name = "empty"\n')
    assert main(["run", str(model), "--t-end", "0.02", "--steps", "3", "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "empty: 0 bodies, 3 samples" in captured.out
