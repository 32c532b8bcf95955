"""What a run keeps and where it writes it: selections, Zarr stores, progress, interrupts,
the command line's defaults on large models, and the tiled first pivot order."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from examples_loader import EXAMPLES
from helpers import solve_with

from sparsekin import AnalysisInterrupted, LimitWarning, SparsekinError, load_model, solve_kinematics, testset
from sparsekin.results import recording
from sparsekin.cli import main
from sparsekin.engine.linalg import RefactorSolver
from sparsekin.solve.stepper import KinematicStepper

xarray = pytest.importorskip("xarray", reason='the Zarr tests need "sparsekin[zarr]"')
ROOT = Path(__file__).resolve().parents[1]

MODELS = {  # the compiled loop, and the refactorization path
    "task5": (lambda: load_model(EXAMPLES / "task5.toml"), np.linspace(0.0, 10.0, 10_001), ["K", "A"]),
    "four_bar_chain(60)": (lambda: testset.four_bar_chain(60), np.linspace(0.0, 1.0, 101), ["u59.Q", "A0"]),
}


@pytest.mark.parametrize("name", MODELS)
def test_a_zarr_store_equals_the_run_in_memory_bit_for_bit(name, tmp_path):
    build, times, points = MODELS[name]
    mechanism = build()
    joints = [k for k, joint in enumerate(mechanism.joints) if type(joint).output_names][:3]
    memory = solve_kinematics(mechanism, times)
    streamed = solve_kinematics(mechanism, times, points=points, joints=joints, store=tmp_path / "run.zarr")
    dataset = xarray.open_zarr(tmp_path / "run.zarr")
    np.testing.assert_array_equal(dataset["t"].values, memory.times)
    for key, array in (("q", memory.coordinates), ("qd", memory.velocities), ("qdd", memory.accelerations)):
        np.testing.assert_array_equal(dataset[key].values, array)
    for p, point in enumerate(points):
        np.testing.assert_array_equal(dataset["points"].values[:, p], np.hstack(memory.point(point)))
        np.testing.assert_array_equal(np.hstack(streamed.point(point)), np.hstack(memory.point(point)))
    for j, joint in enumerate(joints):
        np.testing.assert_array_equal(dataset["joints"].values[:, j], np.column_stack(memory.joint(joint)))
    assert dataset["coordinate"].values[2] == f"{mechanism.body_names[0]}.angle"
    assert list(dataset["component"].values) == ["x", "y", "vx", "vy", "ax", "ay"]
    assert streamed.to_xarray()["q"].shape == memory.coordinates.shape


def test_a_run_without_coordinates_keeps_its_points_and_joints():
    mechanism, times = load_model(EXAMPLES / "task5.toml"), np.linspace(0.0, 2.0, 201)
    memory = solve_kinematics(mechanism, times)
    lean = solve_kinematics(mechanism, times, coordinates=False, points=["K"], joints=["actuator2"])
    assert lean.coordinates is None
    np.testing.assert_array_equal(np.hstack(lean.point("K")), np.hstack(memory.point("K")))
    np.testing.assert_array_equal(np.column_stack(lean.joint("actuator2")), np.column_stack(memory.joint("actuator2")))
    with pytest.raises(KeyError, match=r'point "J" was not recorded: the run kept K and not the coordinates'):
        lean.point("J")
    with pytest.raises(KeyError, match=r"joints\[0\] was not recorded"):
        lean.joint(0)


def test_a_run_in_memory_fills_its_arrays_in_place(monkeypatch):
    """Over several chunks, what the recorder writes to a memory sink is already there (views
    of its arrays): nothing is copied a second time."""
    copied = []
    write = recording.MemorySink.write

    def watched(sink, first, data):
        copied.append({key for key, rows in data.items() if rows.base is not sink.arrays[key]})
        return write(sink, first, data)

    monkeypatch.setattr(recording.MemorySink, "write", watched)
    times = np.linspace(0.0, 10.0, 2 * recording.MAX_CHUNK_SAMPLES + 1)
    result = solve_kinematics(testset.task5(), times, points=["K"], joints="all")
    assert copied == [set()] * 3 and result.n_times == times.size
    derived = solve_kinematics(testset.task5(), times)  # K and the joints derived from the coordinates
    np.testing.assert_array_equal(np.hstack(result.point("K")), np.hstack(derived.point("K")))
    np.testing.assert_array_equal(np.column_stack(result.joint(0)), np.column_stack(derived.joint(0)))


def test_progress_is_reported_up_to_every_sample():
    calls = []
    times = np.linspace(0.0, 10.0, 10_001)
    solve_kinematics(load_model(EXAMPLES / "task5.toml"), times, progress=lambda done, total: calls.append((done, total)))
    assert calls[-1] == (times.size, times.size) and all(total == times.size for _, total in calls)
    assert all(a[0] < b[0] for a, b in zip(calls, calls[1:])) and len(calls) >= 3  # chunk by chunk


@pytest.mark.parametrize("name", MODELS)
def test_an_interrupt_keeps_every_sample_solved(name, tmp_path):
    build, times, points = MODELS[name]
    mechanism = build()
    reference = solve_kinematics(mechanism, times)
    stop_at = times.size // 3

    def interrupt(done, total):
        if done >= stop_at:
            raise KeyboardInterrupt

    with pytest.raises(AnalysisInterrupted) as caught:
        solve_kinematics(mechanism, times, points=points, store=tmp_path / "run.zarr", progress=interrupt)
    result = caught.value.result
    assert isinstance(caught.value, KeyboardInterrupt) and stop_at <= result.n_times < times.size
    # the counts describe the samples returned (task5: between two chunks of the compiled loop)
    assert result.newton_iterations.size == result.n_times and not result.complete
    np.testing.assert_array_equal(np.asarray(result.coordinates), reference.coordinates[: result.n_times])
    dataset = xarray.open_zarr(tmp_path / "run.zarr")
    assert dataset.sizes["time"] == result.n_times
    np.testing.assert_array_equal(dataset["points"].values[:, 0, :2], reference.point(points[0]).position[: result.n_times])


def test_limits_are_watched_in_a_run_without_coordinates(tmp_path):
    from dataclasses import replace

    mechanism = testset.task5()
    joints = tuple(replace(j, limits=(0.7, 0.86)) if j.name == "actuator1" else j for j in mechanism.joints)
    expected = r'joints\[12\] "actuator1" .* left its limits: stroke 0\.86'
    with pytest.warns(LimitWarning, match=expected) as caught:
        solve_kinematics(replace(mechanism, joints=joints), np.linspace(0.0, 2.0, 201), coordinates=False, points=["K"],
                         store=tmp_path / "run.zarr")  # fmt: skip
    limits = [warning.filename for warning in caught if issubclass(warning.category, LimitWarning)]
    assert limits == [__file__]  # the call of solve_kinematics


# ---------------------------------------------------------------------- the command line
def run_until_interrupted(arguments: list[str], out: Path, marker: Path, settle: float) -> subprocess.CompletedProcess:
    """Start ``sparsekin run``, send SIGINT once `marker` exists and `settle` seconds have passed."""
    environment = dict(os.environ, PYTHONPATH=str(ROOT))
    process = subprocess.Popen([sys.executable, "-m", "sparsekin", "run", *arguments, "--out", str(out), "--quiet"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=environment)  # fmt: skip
    deadline = time.monotonic() + 240
    while not marker.exists() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(settle)
    process.send_signal(signal.SIGINT)
    out_text, error_text = process.communicate(timeout=240)
    return subprocess.CompletedProcess(process.args, process.returncode, out_text, error_text)


@pytest.mark.parametrize("format_", ["zarr", "csv"])
def test_ctrl_c_writes_every_sample_solved_and_exits_130(tmp_path, format_):
    model = EXAMPLES / "four_bar_chain.toml"  # 2001 bodies: about a millisecond a step
    out = tmp_path / "out"
    arguments = [str(model), "--t-end", "1.2", "--steps", "200001", "--points", "u999.Q", "--format", format_]
    if format_ == "zarr":  # the time variable appears with the first chunk written: samples are solved
        marker, settle = out / "results.zarr" / "t", 0.5
    else:  # the CSV is written at the end; wait for the run to have begun, and some more
        marker, settle = out, 3.0
    finished = run_until_interrupted(arguments, out, marker, settle)
    assert finished.returncode == 130, finished.stderr
    written = int(finished.stderr.split("interrupted: wrote ")[1].split(" of ")[0])
    assert 0 < written < 200001
    times = np.linspace(0.0, 1.2, 200001)[:written]
    if format_ == "zarr":
        dataset = xarray.open_zarr(out / "results.zarr")
        assert dataset.sizes["time"] == written
        tip = dataset["points"].values[:, 0, :2]
    else:
        tip = np.loadtxt(out / "points.csv", delimiter=",", skiprows=1, ndmin=2)[:, 1:3]
        assert tip.shape[0] == written
    angle = math.pi / 2 + times
    np.testing.assert_allclose(tip, np.c_[1000 + np.cos(angle), np.sin(angle)], atol=1e-8)


def test_ctrl_c_before_the_first_sample_exits_130_without_a_traceback(tmp_path, capsys, monkeypatch):
    from sparsekin.cli import run

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(run, "solve_for_command", interrupted)  # Ctrl-C while the pattern is being built
    assert main(["run", str(EXAMPLES / "task5.toml"), "--out", str(tmp_path / "out")]) == 130
    assert capsys.readouterr().err == "sparsekin: interrupted: nothing solved yet, nothing written\n"
    assert not (tmp_path / "out" / "points.csv").exists()


def test_on_a_large_model_run_writes_what_a_person_reads(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(EXAMPLES / "four_bar_chain.toml"), "--t-end", "0.1", "--steps", "3", "--out", str(out)]) == 0
    error = capsys.readouterr().err
    assert "note: 3001 joints: none written to joints.csv (give --joints J1,J2 or all)" in error
    header = (out / "points.csv").read_text().splitlines()[0]
    assert header.startswith("t,A0.x") and "u999.Q.ay" in header  # [analysis].points
    assert (out / "joints.csv").read_text().splitlines()[0] == "t"
    assert main(["run", str(EXAMPLES / "four_bar_chain.toml"), "--t-end", "0.1", "--steps", "3", "--out", str(out),
                 "--points", "none", "--joints", "joints[0],joints[16]", "--no-coordinates"]) == 0  # fmt: skip
    assert (out / "points.csv").read_text().splitlines()[0] == "t"
    assert (out / "joints.csv").read_text().splitlines()[0].split(",")[1::3] == ["joints[0].angle", "joints[16].angle"]


def test_the_cli_streams_to_zarr(tmp_path):
    out = tmp_path / "out"
    assert main(["run", str(EXAMPLES / "task5.toml"), "--format", "zarr", "--out", str(out), "--quiet"]) == 0
    dataset = xarray.open_zarr(out / "results.zarr")
    assert dataset.sizes == {"time": 1001, "coordinate": 30, "point": 3, "component": 6, "joint": 14, "derivative": 3}
    assert list(dataset["joint_quantity"].values[-2:]) == ["stroke", "stroke"]
    assert not (out / "points.csv").exists()


# ---------------------------------------------------------------------- the first pivot order
def test_a_long_chain_takes_its_first_pivot_order_from_a_short_one():
    mechanism = testset.task5_chain(1000)  # 30 000 coordinates: the tiled order applies
    times = np.linspace(0.0, 0.2, 5)
    stepper = KinematicStepper(mechanism, linear_solver="refactor")
    stepper.start(0.0)
    solver = stepper.linear_solver
    assert isinstance(solver, RefactorSolver) and (solver.n_factorizations, solver.n_fallbacks) == (1, 0)
    assert solver.nnz_factors < 2.0 * stepper.pattern.nnz  # as little fill-in as SuperLU's COLAMD
    tiled = solve_kinematics(mechanism, times, linear_solver="refactor")
    reference = solve_kinematics(mechanism, times, linear_solver="superlu")
    scale = stepper.pattern.length_scale
    np.testing.assert_allclose(tiled.coordinates, reference.coordinates, rtol=0, atol=1e-11 * scale)


# ---------------------------------------------------------------------- errors, interrupts and the store
CHAIN = (lambda: testset.four_bar_chain(60), np.linspace(0.0, 1.0, 101))  # the Python loop, one chunk


ERRORS = [RuntimeError("the caller's own error"), SparsekinError("a sparsekin error")]


@pytest.mark.parametrize("error", ERRORS, ids=["other", "sparsekin"])
def test_any_error_in_the_loop_keeps_the_samples_solved_in_the_store(error, tmp_path):
    build, times = CHAIN
    mechanism = build()
    reference = solve_kinematics(mechanism, times)

    def fail(done, total):
        if done == 40:
            raise error

    with pytest.raises(type(error), match=str(error)) as caught:
        solve_kinematics(mechanism, times, points=["A0"], store=tmp_path / "run.zarr", progress=fail)
    dataset = xarray.open_zarr(tmp_path / "run.zarr")  # the chunk not yet full was written
    np.testing.assert_array_equal(dataset["t"].values, times[:40])
    np.testing.assert_array_equal(dataset["q"].values, reference.coordinates[:40])
    if isinstance(error, SparsekinError):
        result = caught.value.result
        assert result.n_times == result.newton_iterations.size == 40 and not result.complete
        np.testing.assert_array_equal(np.asarray(result.coordinates), reference.coordinates[:40])


def test_a_ctrl_c_during_a_write_never_writes_a_chunk_twice(tmp_path, monkeypatch):
    """SIGINT while a chunk is appended to the store: the interrupt is taken once the
    write is done and counted, so the end of the run does not append the chunk again."""
    build, times = CHAIN
    mechanism = build()
    reference = solve_kinematics(mechanism, times)
    write, calls = recording.ZarrSink.write, []

    def interrupted_write(self, first, data):
        write(self, first, data)
        calls.append(first)
        if len(calls) == 2:
            signal.raise_signal(signal.SIGINT)  # Ctrl-C at the end of the second chunk's append

    monkeypatch.setattr(recording.ZarrSink, "write", interrupted_write)
    with pytest.raises(AnalysisInterrupted) as caught:
        solve_with(mechanism, times, store=tmp_path / "run.zarr", chunk_samples=16)
    result = caught.value.result
    assert calls == [0, 16] and result.n_times == result.newton_iterations.size == 32
    dataset = xarray.open_zarr(tmp_path / "run.zarr")
    np.testing.assert_array_equal(dataset["t"].values, times[:32])
    np.testing.assert_array_equal(dataset["q"].values, reference.coordinates[:32])


def test_to_xarray_in_memory_has_the_variables_and_labels_of_a_store(tmp_path):
    mechanism, times = load_model(EXAMPLES / "task5_dynamics.toml"), np.linspace(0.0, 1.0, 11)
    options = {"points": ["K"], "joints": "all", "forces": "all"}
    memory = solve_kinematics(mechanism, times, **options).to_xarray()
    stored = solve_kinematics(mechanism, times, store=tmp_path / "run.zarr", **options).to_xarray()
    assert set(memory.data_vars) == set(stored.data_vars) == {"q", "qd", "qdd", "points", "joints", "forces"}
    assert set(memory.coords) == set(stored.coords)
    assert {"joint_quantity", "joint_unit", "force_unit"} <= set(memory.coords)
    for name in [*memory.data_vars, *memory.coords]:
        assert memory[name].dims == stored[name].dims, name
        np.testing.assert_array_equal(memory[name].values, stored[name].values, err_msg=name)


def test_a_store_path_is_checked_and_an_old_store_cleared_before_the_run(tmp_path):
    mechanism, times = testset.four_bar_chain(3), np.linspace(0.0, 1.0, 11)
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "keep.txt").write_text("mine")
    with pytest.raises(ValueError, match=r"^`store` '.*notes' is a folder that is not a Zarr store and not "):
        solve_kinematics(mechanism, times, store=folder)
    assert (folder / "keep.txt").read_text() == "mine"
    (tmp_path / "file").write_text("mine")
    with pytest.raises(ValueError, match=r"^`store` '.*file' is a file, not a Zarr store; "):
        solve_kinematics(mechanism, times, store=tmp_path / "file")
    store = tmp_path / "run.zarr"
    solve_kinematics(mechanism, times, store=store)
    later = times + 5.0

    def fail(done, total):
        raise RuntimeError("stopped at the first sample")

    with pytest.raises(RuntimeError, match="stopped at the first sample"):  # the Python loop: sample by sample
        solve_kinematics(mechanism, later, store=store, progress=fail, linear_solver="superlu")
    np.testing.assert_array_equal(xarray.open_zarr(store)["t"].values, later[:1])  # no sample of the old run
    (tmp_path / "empty").mkdir()
    assert solve_kinematics(mechanism, times, store=tmp_path / "empty").n_times == times.size
