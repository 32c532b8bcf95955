"""Sweeps on Dask against serial runs of the same variants, built here without the sweep's paths.

The references are `solve_kinematics` runs of Task 5 whose laws are replaced by hand
(`dataclasses.replace`), one after the other in this process; the sweeps run on a local
cluster of two worker processes shared by the module, on a cluster that loses a worker
mid-sweep, and on a scheduler and a worker started as ``dask scheduler`` / ``dask worker``
subprocesses.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
pytest.importorskip("zarr")

import sparsekin as sk  # noqa: E402
from sparsekin.cli import main  # noqa: E402
from sparsekin.results.schema import result_arrays  # noqa: E402
from sparsekin.studies.sweeps import VariantSet, resolve_path, write_variants_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TASK5 = ROOT / "examples" / "task5.toml"
#: 0.03 … 0.07 m in nine values, and 0.054 m: the largest amplitude that does not lock up.
AMPLITUDES = np.sort(np.append(np.linspace(0.03, 0.07, 9), 0.054))
BOTH = ("drivers[0].law.amplitude", "drivers[1].law.amplitude")
#: 2 s at 10 ms: every lock-up of these amplitudes happens in the first quarter period (1.05 s).
TIMES = np.linspace(0.0, 2.0, 201)
RECORD = dict(coordinates=True, points=["K", "A"], joints="all")


@pytest.fixture(scope="module")
def task5():
    return sk.load_model(TASK5)


@pytest.fixture(scope="module")
def client():
    import logging

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  silence_logs=logging.ERROR) as cluster, distributed.Client(cluster) as client:  # fmt: skip
        yield client


def with_amplitude(mechanism, amplitude):
    """Task 5 with both actuators' amplitude set by hand."""
    drivers = tuple(
        dataclasses.replace(driver, law=sk.Harmonic(amplitude=amplitude, omega=driver.law.omega))
        for driver in mechanism.drivers
    )
    return dataclasses.replace(mechanism, drivers=drivers)


def serial_run(mechanism, times=TIMES, **record):
    """(status, result, t_failure) of one run, as a sweep should report it."""
    try:
        return "complete", sk.solve_kinematics(mechanism, times, **(record or RECORD)), np.nan
    except sk.SingularJacobianError as error:
        return "singular", error.result, error.time
    except sk.ConvergenceError as error:
        return "no_convergence", error.result, error.time


@pytest.fixture(scope="module")
def serial(task5):
    return [serial_run(with_amplitude(task5, amplitude)) for amplitude in AMPLITUDES]


@pytest.fixture(scope="module")
def swept(task5, client):
    return sk.sweep(task5, {BOTH: AMPLITUDES}, TIMES, client, variants_per_task=3, **RECORD)


def assert_equals_serial(result, serial_runs, variants=None):
    """Every variant's status, times and recorded arrays equal the serial run's, bit for bit."""
    for k, (status, run, t_failure) in zip(variants or range(len(serial_runs)), serial_runs):
        assert result.status[k] == status, k
        n = run.n_times
        assert result.t_stop[k] == run.times[-1]
        np.testing.assert_array_equal(result.t_failure[k], t_failure)
        for swept_array, serial_array in ((result.coordinates, run.coordinates), (result.velocities, run.velocities),
                                          (result.accelerations, run.accelerations),
                                          (result.point_tracks, run.point_tracks),
                                          (result.joint_tracks, run.joint_tracks)):  # fmt: skip
            values = np.asarray(swept_array[k])
            np.testing.assert_array_equal(values[:n], serial_array)
            assert np.isnan(values[n:]).all()


# ---------------------------------------------------------------------- results
def test_sweep_equals_serial_runs_bit_for_bit(swept, serial):
    assert swept.n_variants == AMPLITUDES.size and swept.n_tasks == 4
    np.testing.assert_array_equal(swept.parameters, np.column_stack([AMPLITUDES, AMPLITUDES]))
    assert_equals_serial(swept, serial)


def test_task5_amplitudes_above_0054_lock_up_when_a_single_run_does(swept, task5):
    complete = AMPLITUDES <= 0.054
    assert complete.sum() == 6 and (swept.status[complete] == "complete").all()
    assert (swept.status[~complete] == "singular").all()
    k = int(np.flatnonzero(np.isclose(AMPLITUDES, 0.06))[0])
    assert (
        round(float(swept.t_failure[k]), 6) == 0.755244
    )  # the single run of README: "singular ... t = 0.755244 s"
    assert swept.t_stop[k] == 0.75
    assert "singular configuration" in swept.messages[k] and swept.messages[0] == ""
    # README: the lock-ups of 0.055 … 0.07 m (t_failure) and the last samples solved before them
    # (t_stop); each the single run's, bit for bit (test_sweep_equals_serial_runs_bit_for_bit)
    locking = np.flatnonzero(AMPLITUDES >= 0.055)
    assert np.round(swept.t_failure[locking], 3).tolist() == [0.944, 0.755, 0.66, 0.592]
    np.testing.assert_allclose(swept.t_stop[locking], [0.94, 0.75, 0.65, 0.59], rtol=0, atol=1e-12)


def test_the_sweeps_motion_gives_each_variant_what_its_run_gives(swept, serial):
    """`SweepResult.motion` has a run's accessors with the variant first: recorded points and
    joints, and what is derived from the coordinates (a point not recorded, a driver's
    coordinate), each variant's row the serial run's, NaN after its last sample."""
    motion = swept.motion
    assert motion.point("K").position.shape == (AMPLITUDES.size, TIMES.size, 2)
    for k, (_, run, _) in enumerate(serial):
        n = run.n_times
        for swept_motion, run_motion in ((motion.point("K"), run.point("K")), (motion.point("B"), run.point("B")),
                                         (motion.joint("actuator1"), run.joint("actuator1")),
                                         (motion.driver(0), run.driver(0))):  # fmt: skip
            for swept_array, run_array in zip(swept_motion, run_motion):
                np.testing.assert_array_equal(swept_array[k, :n], run_array)
                assert np.isnan(swept_array[k, n:]).all()


def test_a_sweep_labels_its_dataset_as_a_run_does(swept, task5):
    """In memory as in a store, the labels of a sweep's Dataset are those of one run's."""
    _, run, _ = serial_run(task5)
    labelled = run.to_xarray()
    dataset = swept.to_xarray()
    for name in labelled.coords:
        if name != "t":
            assert dataset[name].dims == labelled[name].dims
            np.testing.assert_array_equal(dataset[name].values, labelled[name].values)
    assert {"joint_quantity", "joint_unit", "coordinate", "point", "joint"} <= set(dataset.coords)


def test_a_sweep_records_the_forces_of_each_variant_as_a_serial_run_does(client, tmp_path):
    task5_dynamics = sk.load_model(ROOT / "examples" / "task5_dynamics.toml")
    amplitudes = [0.04, 0.06]  # one complete, one that locks up
    result = sk.sweep(task5_dynamics, {BOTH: amplitudes}, TIMES, client, coordinates=False, store=tmp_path / "s.zarr")
    assert result.force_labels[:2] == ("cylinder1.force", "cylinder1.power")
    stored = result.to_xarray()
    for k, amplitude in enumerate(amplitudes):
        status, run, _ = serial_run(with_amplitude(task5_dynamics, amplitude), coordinates=False)
        assert result.status[k] == status and run.force_labels == result.force_labels
        np.testing.assert_array_equal(stored["forces"].values[k, : run.n_times], run.force_tracks)
        assert np.isnan(stored["forces"].values[k, run.n_times :]).all()


def test_tolerance_study_with_zero_sigma_repeats_the_nominal_run(task5, client):
    result = sk.sweep(task5, VariantSet(samples=3, perturb_points=0.0, seed=7), TIMES, client, **RECORD)
    nominal = serial_run(task5)
    assert_equals_serial(result, [nominal] * 3)
    assert result.columns == tuple(f"deviation.{p}.{c}" for p in task5.points for c in "xy")
    assert not result.parameters.any()


def test_tolerance_study_moves_every_point_reproducibly(task5):
    design = VariantSet(samples=4, perturb_points=1e-3, seed=11).bind(task5)
    columns, table = design.table()
    for k in range(4):
        moved = design.variant(k).points
        for p, name in enumerate(task5.points):
            expected = np.add(task5.points[name], table[k, 2 * p : 2 * p + 2])
            assert moved[name] == tuple(expected.tolist())
    again = VariantSet(samples=4, perturb_points=1e-3, seed=11).bind(task5).table()[1]
    np.testing.assert_array_equal(table, again)
    assert 0.5e-3 < table.std() < 2e-3


def test_grid_is_the_product_of_axes_with_paths_varied_together(task5):
    variants = VariantSet.from_arguments([f"{BOTH[0]},{BOTH[1]}=0.04:0.05:3", "points.M.x=0.19:0.21:2"])
    assert variants.shape == (3, 2, 1)
    design = variants.bind(task5)
    variant = design.variant(2)  # the second amplitude, the first x (first axis slowest)
    assert variant.drivers[0].law.amplitude == variant.drivers[1].law.amplitude == 0.045
    assert variant.points["M"] == (0.19, 0.6)
    assert design.geometry_varies


def test_unit_parameters_change_every_copy():
    chain = sk.load_model(ROOT / "examples" / "task5_chain.toml")
    unit = chain.copies[0].unit.name
    path = f"units.{unit}.drivers[0].law.amplitude"
    variant = VariantSet({path: [0.02]}).bind(chain).variant(0)
    assert variant.copies[0].unit.drivers[0].law.amplitude == 0.02
    assert variant.drivers[chain.n_drivers - 2].law.amplitude == 0.02  # the last copy's first driver
    assert variant.n_bodies == chain.n_bodies


# ---------------------------------------------------------------------- mistakes
@pytest.mark.parametrize("text, message", [
    ("drivers[0].law.amplitude=0.03:0.07", r"--vary drivers\[0\]\.law\.amplitude=0\.03:0\.07: expected PATH=START:STOP:N"),
    ("drivers[0].law.amplitude=0.03:0.07:x", r"expected N, a whole number >= 1, got 'x'"),
    ("drivers[0].law.amplitude=a:0.07:3", r"expected START as a number or x,y, got 'a'"),
    ("points.M=0.2,0.6:0.3:3", r"START and STOP must both be numbers or both x,y pairs"),
    (",drivers[0].law.amplitude=0:1:2", r"empty path"),
])  # fmt: skip
def test_bad_vary_is_one_line_naming_it(text, message):
    with pytest.raises(ValueError, match=message):
        VariantSet.from_arguments([text])


@pytest.mark.parametrize("path, message", [
    ("drivers[2].law.amplitude", r"drivers\[2\]\.law\.amplitude: the model has 2 drivers"),
    ("drivers.lift.law.amplitude", r'drivers\.lift\.law\.amplitude: the model has no driver named "lift"'),
    ("drivers[0].law.amplitud", r"the Harmonic law of drivers\[0\] has no parameter amplitud \(its parameters: "
                                r"amplitude, omega, phase, offset\)"),
    ("points.Q", r'points\.Q: the model has no point "Q"'),
    ("units.loop.points.P", r'units\.loop\.points\.P: unknown unit "loop"'),
    ("joints[0].at", r"joints\[0\]\.at: expected drivers\[i\]\.law\.KEY"),
])  # fmt: skip
def test_bad_path_names_the_path_and_what_was_expected(task5, path, message):
    with pytest.raises(sk.ModelError, match=message):
        resolve_path(task5, path)


def test_values_a_parameter_refuses_name_the_path(task5):
    with pytest.raises(sk.ModelError, match=r"points\.M: expected x,y pairs"):
        VariantSet({"points.M": [0.1, 0.2]}).bind(task5)
    with pytest.raises(ValueError, match=r"`grid`: values of drivers\[0\]\.law\.amplitude must be finite"):
        VariantSet({BOTH[0]: [0.1, np.nan]})


def run_cli(arguments, capsys):
    status = main([str(a) for a in arguments])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.mark.parametrize("arguments, message", [
    (["--vary", "drivers[0].law.amplitude=0.03:0.07"], "expected PATH=START:STOP:N"),
    (["--vary", "drivers[5].law.amplitude=0.03:0.07:3"], r"drivers\[5\]\.law\.amplitude: the model has 2 drivers"),
    (["--samples", "3"], "nothing to vary"),
    (["--perturb", "points=0.001"], "--perturb needs --samples N"),
    (["--perturb", "joints=0.1", "--samples", "2"], r"--perturb joints=0\.1: expected points=SIGMA"),
    (["--vary", "drivers[0].law.amplitude=0.03:0.07:3", "--workers", "0"], "--workers must be a whole number >= 1"),
    (["--vary", "drivers[0].law.amplitude=0.03:0.07:3", "--samples", "3"], r"--samples 3 needs --perturb points=SIGMA"),
    (["--vary", "drivers[0].law.amplitude=0.03:0.07:3", "--plot-point", "K"], r"--plot-point .*: give --plot with it"),
    (["--vary", "drivers[0].law.amplitude=0.03:0.07:3", "--quasi-static"],
     r"--quasi-static changes the forces, but the model has no mass or load"),
])  # fmt: skip
def test_cli_mistakes_exit_2_with_one_line(arguments, message, capsys, tmp_path):
    status, _, err = run_cli(["sweep", TASK5, *arguments, "--out", tmp_path], capsys)
    assert status == 2
    assert err.count("\n") == 1 and err.startswith("sparsekin: error: ")
    assert __import__("re").search(message, err), err


def no_cluster(workers):
    raise AssertionError("a cluster was started for a sweep that should have been refused before")


def test_times_outside_a_spline_law_are_refused_before_any_cluster(capsys, tmp_path, monkeypatch):
    """As `run` does: one line, exit status 2, not a task failing on the workers (exit 3)."""
    monkeypatch.setattr("sparsekin.studies.sweeps._local_cluster", no_cluster)
    harmonic = 'law = { type = "harmonic", amplitude = 0.05, omega = 1.5 }'
    spline = 'law = { type = "spline", times = [0.0, 0.5, 1.0], values = [0.8246211, 0.84, 0.8246211] }'
    model = tmp_path / "spline.toml"
    model.write_text(TASK5.read_text(encoding="utf-8").replace(harmonic, spline, 1), encoding="utf-8")
    status, _, err = run_cli(["sweep", model, "--vary", f"{BOTH[1]}=0.03:0.07:3", "--t-end", 2, "--steps", 21,
                              "--out", tmp_path / "out"], capsys)  # fmt: skip
    assert status == 2 and err.count("\n") == 1, err
    assert err.startswith("sparsekin: error: `times` span [0, 2] s but the law of driver") and "spline" in err
    assert not (tmp_path / "out").exists()
    with pytest.raises(ValueError, match=r"a spline, is defined on \[0, 1\] s"):
        sk.sweep(sk.load_model(model), {BOTH[1]: [0.04]}, TIMES, workers=1)


@pytest.mark.parametrize("option, message", [
    (dict(tolerance=-1.0), r"`tolerance` must be a positive number|`tolerance` must be a number in"),
    (dict(max_iterations=0), r"`max_iterations` must be a whole number >= 1"),
    (dict(linear_solver="lu"), r"`linear_solver` must be one of"),
])  # fmt: skip
def test_options_every_task_would_refuse_are_refused_before_any_cluster(task5, monkeypatch, option, message):
    monkeypatch.setattr("sparsekin.studies.sweeps._local_cluster", no_cluster)
    with pytest.raises(ValueError, match=message):
        sk.sweep(task5, {BOTH[0]: [0.04, 0.05]}, TIMES, workers=1, **option)


def test_samples_without_a_deviation_are_refused():
    with pytest.raises(ValueError, match=r"`samples` = 3 needs `perturb_points`"):
        VariantSet({BOTH[0]: [0.04, 0.05]}, samples=3)
    assert VariantSet({BOTH[0]: [0.04, 0.05]}, samples=3, perturb_points=0.0).n_variants == 6


def test_variant_sets_compare_by_identity():
    """A frozen dataclass's generated == would compare the dicts of arrays and raise."""
    first, second = VariantSet({BOTH[0]: [0.04, 0.05]}, seed=1), VariantSet({BOTH[0]: [0.04, 0.05]}, seed=1)
    assert first == first and first != second
    assert len({first, second}) == 2


def test_every_worker_thread_counts_beyond_five_workers(task5):
    """Four tasks per worker thread: with six workers, 24 tasks (distributed 2025.4 … 2026.6
    listed at most five workers in scheduler_info, dask/distributed#9045)."""
    import logging

    with distributed.LocalCluster(n_workers=6, threads_per_worker=1, processes=False, dashboard_address=":0",
                                  silence_logs=logging.ERROR) as cluster, distributed.Client(cluster) as client:  # fmt: skip
        client.wait_for_workers(6, timeout=60)
        result = sk.sweep(task5, {BOTH[0]: np.linspace(0.03, 0.05, 48)}, TIMES[:3], client, coordinates=False,
                          points=["K"])  # fmt: skip
    assert result.n_tasks == 24 and (result.status == "complete").all()


def test_cli_without_the_extra_names_it(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    status, _, err = run_cli(["sweep", TASK5, "--vary", f"{BOTH[0]}=0.03:0.07:3", "--out", tmp_path], capsys)
    assert status == 2 and 'pip install "sparsekin[distributed]"' in err and err.count("\n") == 1


# ---------------------------------------------------------------------- the command
def read_variants(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as file:
        return list(csv.DictReader(file))


def assert_store_and_csv_match(directory: Path, serial_runs, columns):
    import xarray as xr

    rows = read_variants(directory / "variants.csv")
    assert list(rows[0])[: len(columns) + 1] == ["variant", *columns]
    assert list(rows[0])[len(columns) + 1 :] == ["status", "t_stop", "t_failure", "message"]
    store = xr.open_zarr(directory / "sweep.zarr")
    assert store.points.dims == ("variant", "time", "point", "component")
    for k, (row, (status, run, t_failure)) in enumerate(zip(rows, serial_runs)):
        assert row["status"] == status == store.status.values[k]
        assert float(row["t_stop"]) == run.times[-1]
        np.testing.assert_array_equal(float(row["t_failure"]), t_failure)
        n = run.n_times
        np.testing.assert_array_equal(store.points.values[k, :n], run.point_tracks)
        assert np.isnan(store.points.values[k, n:]).all()
        np.testing.assert_array_equal(store.t.values, TIMES)


def test_cli_sweep_writes_the_store_and_the_table(task5, capsys, tmp_path):
    vary = f"{BOTH[0]},{BOTH[1]}=0.03:0.07:5"
    status, out, err = run_cli(["sweep", TASK5, "--vary", vary, "--t-end", 2, "--steps", 201, "--points", "K",
                                "--workers", 2, "--out", tmp_path, "--plot"], capsys)  # fmt: skip
    assert status == 0, err
    assert "status: complete 3, singular 2, no_convergence 0, invalid 0" in out
    runs = [serial_run(with_amplitude(task5, a), points=["K"], joints="all", coordinates=True)
            for a in np.linspace(0.03, 0.07, 5)]  # fmt: skip
    assert_store_and_csv_match(tmp_path, runs, BOTH)
    assert (tmp_path / "sweep_paths_K.png").stat().st_size > 0 and (
        tmp_path / "stop_times.png"
    ).stat().st_size > 0


def test_worker_killed_mid_sweep_loses_no_variant(task5, serial):
    import logging

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  silence_logs=logging.CRITICAL) as cluster, distributed.Client(cluster) as client:  # fmt: skip
        client.wait_for_workers(2, timeout=60)
        pids = client.run(os.getpid)
        victim = max(pids.values())
        killed = []

        def kill_once(done, total):
            if not killed:
                os.kill(victim, signal.SIGKILL)  # a worker process dies with tasks submitted to it
                killed.append(done)

        result = sk.sweep(task5, {BOTH: AMPLITUDES}, TIMES, client, variants_per_task=1, progress=kill_once,
                          **RECORD)  # fmt: skip
        assert killed and killed[0] < AMPLITUDES.size
        client.wait_for_workers(2, timeout=60)
        assert victim not in client.run(os.getpid).values()  # the nanny started a new worker process
    assert (result.status != "").all()
    assert_equals_serial(result, serial)


def test_external_scheduler_runs_the_same_sweep(task5, capsys, tmp_path):
    environment = dict(
        os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    )
    scheduler_file = tmp_path / "scheduler.json"
    common = dict(env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp_path)
    scheduler = subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                                  "--no-dashboard", "--scheduler-file", scheduler_file], **common)  # fmt: skip
    worker = None
    try:
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        worker = subprocess.Popen([sys.executable, "-m", "dask", "worker", address, "--nworkers", "1", "--nthreads",
                                   "1", "--no-dashboard"], **common)  # fmt: skip
        with distributed.Client(address, timeout=30) as client:
            client.wait_for_workers(1, timeout=60)
        vary = f"{BOTH[0]},{BOTH[1]}=0.03:0.07:5"
        status, out, err = run_cli(["sweep", TASK5, "--vary", vary, "--t-end", 2, "--steps", 201, "--points", "K",
                                    "--scheduler", address, "--out", tmp_path / "out"], capsys)  # fmt: skip
        assert status == 0, err
        assert "the scheduler's workers" in out
    finally:
        for process in (worker, scheduler):
            if process is not None:
                process.terminate()
                try:
                    process.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    process.kill()
    runs = [serial_run(with_amplitude(task5, a), points=["K"], joints="all", coordinates=True)
            for a in np.linspace(0.03, 0.07, 5)]  # fmt: skip
    assert_store_and_csv_match(tmp_path / "out", runs, BOTH)


def test_unreachable_scheduler_is_a_usage_error():
    """A scheduler that does not answer within the timeout: the usage error of ``--scheduler``
    (a `CommandError`: exit status 2, its message on stderr)."""
    from sparsekin.cli.common import CommandError
    from sparsekin.cli.sweep import _connect

    with pytest.raises(CommandError, match="--scheduler tcp://127.0.0.1:9: cannot reach a Dask scheduler there"):
        _connect("tcp://127.0.0.1:9", timeout=1)


def test_import_sparsekin_does_not_import_dask():
    code = "import sys, sparsekin; assert 'dask' not in sys.modules and 'distributed' not in sys.modules; sparsekin.VariantSet"
    subprocess.run(
        [sys.executable, "-c", code], check=True, cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT))
    )


# ---------------------------------------------------------------------- forward dynamics
PENDULUM = ROOT / "examples" / "dynamics" / "pendulum.toml"
#: Half a second of A01 at 5 ms steps: cheap, and the mass has fallen well off its start.
DYNAMIC_TIMES = np.linspace(0.0, 0.5, 26)
#: A four-bar with masses and no driver, falling under gravity: links 1, 2.5, 2 m on a 2.5 m base.
FALLING_FOUR_BAR = """
name = "falling four-bar"
gravity = [0.0, -9.81]
[points]
O = [0.0, 0.0]
A = [0.0, 1.0]
B = [2.5, 1.0]
C = [2.5, -1.0]
[bodies.crank]
origin = "O"
points = ["O", "A"]
mass = 1.0
inertia = 0.1
com = [0.0, 0.5]
velocity = [0.0, 0.0, -1.0]
[bodies.coupler]
origin = "A"
points = ["A", "B"]
mass = 2.0
inertia = 1.0
com = [1.25, 0.0]
[bodies.rocker]
origin = "C"
points = ["C", "B"]
mass = 1.5
inertia = 0.5
com = [0.0, 1.0]
[[joints]]
type = "revolute"
bodies = ["crank", "ground"]
at = "O"
[[joints]]
type = "revolute"
bodies = ["crank", "coupler"]
at = "A"
[[joints]]
type = "revolute"
bodies = ["coupler", "rocker"]
at = "B"
[[joints]]
type = "revolute"
bodies = ["rocker", "ground"]
at = "C"
[analysis]
type = "dynamics"
max_step = 5.0e-3
"""


def moved_point(mechanism, name: str, x: float):
    """`mechanism` with point `name` drawn at abscissa `x`, built by hand (not by the sweep's paths)."""
    points = dict(mechanism.points)
    points[name] = (x, points[name][1])
    return dataclasses.replace(mechanism, points=points)


def dynamic_run(mechanism, **record):
    """(status, result) of one `solve_dynamics`, as a sweep should report it."""
    try:
        return "complete", sk.solve_dynamics(mechanism, DYNAMIC_TIMES, 5e-3, **record)
    except sk.ModelError:
        return "invalid", None


def test_a_dynamic_sweeps_variant_is_a_single_solve_dynamics_bit_for_bit(client, tmp_path):
    """Each variant's motion, forces, energy and drift, streamed to the store, are those of
    `solve_dynamics` on that variant, and ``variants.csv`` has each one's energy error."""
    model = tmp_path / "four_bar.toml"
    model.write_text(FALLING_FOUR_BAR, encoding="utf-8")
    four_bar = sk.load_model(model)
    values = [2.5, 2.7]  # C.x: the nominal, a longer base and rocker
    result = sk.sweep(four_bar, {"points.C.x": values}, DYNAMIC_TIMES, client, store=tmp_path / "s.zarr",
                      points=["A", "B"], joints="all")  # fmt: skip
    assert result.analysis == "dynamics" and result.status.tolist() == ["complete", "complete"]
    stored = result.to_xarray()
    assert stored.attrs["analysis"] == "dynamics" and stored.attrs["max_step"] == 5e-3
    assert stored.energy.dims == ("variant", "time", "energy_term") and stored.drift_unit.values.tolist() == ["1", "1/s"]
    for k, x in enumerate(values):
        status, run = dynamic_run(moved_point(four_bar, "C", x), points=["A", "B"], joints="all")
        assert status == "complete" and result.t_stop[k] == DYNAMIC_TIMES[-1]
        for name, array in result_arrays(run).items():
            np.testing.assert_array_equal(stored[name].values[k], np.asarray(array), err_msg=name)
        assert result.energy_error[k] == np.max(np.abs(run.energy.balance)) > 0.0
    # the motion is not a copy of the nominal one: the longer base changes it
    assert not np.allclose(stored.points.values[0], stored.points.values[1])
    rows = write_variants_csv(result, tmp_path / "variants.csv").read_text().splitlines()
    assert rows[0] == "variant,points.C.x,status,t_stop,t_failure,energy_error,message"
    assert rows[1].split(",")[5] == repr(float(result.energy_error[0]))


def test_an_error_controlled_dynamic_sweep_is_its_variants_runs(client, tmp_path):
    """``rtol`` reaches each variant's `solve_dynamics` (bit for bit) and the store says it."""
    pendulum = sk.load_model(PENDULUM)
    result = sk.sweep(pendulum, {"points.P.x": [0.8, 1.2]}, DYNAMIC_TIMES, client, store=tmp_path / "s.zarr",
                      points=["P"], coordinates=False, max_step=0.02, rtol=1e-7)  # fmt: skip
    stored = result.to_xarray()
    assert stored.attrs["rtol"] == 1e-7 and result.status.tolist() == ["complete", "complete"]
    for k, x in enumerate((0.8, 1.2)):
        run = sk.solve_dynamics(moved_point(pendulum, "P", x), DYNAMIC_TIMES, 0.02, rtol=1e-7, points=["P"],
                                coordinates=False)  # fmt: skip
        np.testing.assert_array_equal(stored.points.values[k], run.point_tracks)
        assert run.n_steps > DYNAMIC_TIMES[-1] / 0.02  # the error, not the largest step, chose the steps


def test_cli_sweep_of_a_dynamics_model(client, capsys, tmp_path):
    """``sparsekin sweep`` on a model of ``type = "dynamics"`` (here with ``--max-step``) runs
    forward dynamics: each variant's motion and energy as its own run's.  The mass drawn on
    the pivot (P.x = 0, no inertia) leaves the rotation undetermined: that variant is a
    result, ``invalid`` with its reason, and the others go on."""
    import xarray as xr

    status, out, err = run_cli(["sweep", PENDULUM, "--vary", "points.P.x=0:1.2:3", "--t-end", 0.5, "--steps", 26,
                                "--max-step", 5e-3, "--points", "P", "--scheduler", client.scheduler.address,
                                "--quiet", "--out", tmp_path], capsys)  # fmt: skip
    assert status == 0, err
    assert "pendulum: 3 variants, forward dynamics, 26 samples each" in out
    rows = read_variants(tmp_path / "variants.csv")
    assert [row["status"] for row in rows] == ["invalid", "complete", "complete"]
    assert "the motion is not determined" in rows[0]["message"] and rows[0]["t_stop"] == "nan"
    store = xr.open_zarr(tmp_path / "sweep.zarr")
    assert np.isnan(store.points.values[0]).all() and rows[0]["energy_error"] == "nan"
    pendulum = sk.load_model(PENDULUM)
    for k, x in ((1, 0.6), (2, 1.2)):
        _, run = dynamic_run(moved_point(pendulum, "P", x), points=["P"], coordinates=False)
        np.testing.assert_array_equal(store.points.values[k], run.point_tracks)
        np.testing.assert_array_equal(store.energy.values[k], run.energy_tracks)
        assert float(rows[k]["energy_error"]) == np.max(np.abs(run.energy.balance))


@pytest.mark.parametrize("model, arguments, message", [
    (TASK5, ["--max-step", "1e-3"], r"--max-step is for forward dynamics: give --dynamics"),
    (PENDULUM, ["--quasi-static"], r"--quasi-static"),
    (PENDULUM, ["--max-step", "inf"], r"--max-step: `max_step` must be a positive number, got inf"),
    (TASK5, ["--rtol", "1e-8"], r"--rtol is for forward dynamics: give --dynamics"),
    (PENDULUM, ["--rtol", "0"], r"--rtol must be a number in \[1e-12, 0\.1\], got 0\.0"),
])  # fmt: skip
def test_cli_dynamic_sweep_mistakes_are_one_line(model, arguments, message, capsys, tmp_path, monkeypatch):
    monkeypatch.setattr("sparsekin.studies.sweeps._local_cluster", no_cluster)
    status, _, err = run_cli(["sweep", model, "--vary", "points.P.x=0.8:1.2:3" if model == PENDULUM else
                              f"{BOTH[0]}=0.03:0.05:3", *arguments, "--out", tmp_path / "out"], capsys)  # fmt: skip
    assert status == 2 and err.count("\n") == 1 and err.startswith("sparsekin: error: "), err
    assert __import__("re").search(message, err), err


@pytest.mark.parametrize("analysis, keywords, message", [
    ("kinematics", dict(max_step=1e-3), r"`max_step`, `rho_inf` and `rtol` are for forward dynamics"),
    ("kinematics", dict(rtol=1e-8), r"`max_step`, `rho_inf` and `rtol` are for forward dynamics"),
    ("dynamics", dict(rtol=1.0), r"`rtol` must be a number in \[1e-12, 0\.1\], got 1\.0"),
    ("dynamics", dict(max_iterations=5), r"`max_iterations` is for kinematic sweeps"),
    ("dynamics", dict(rho_inf=1.5), r"`rho_inf` must be a number in \[0, 1\], got 1\.5"),
    ("statics", {}, r"`analysis` must be one of 'kinematics', 'dynamics', got 'statics'"),
])  # fmt: skip
def test_dynamic_sweep_options_are_refused_before_any_cluster(task5, monkeypatch, analysis, keywords, message):
    monkeypatch.setattr("sparsekin.studies.sweeps._local_cluster", no_cluster)
    with pytest.raises(ValueError, match=message):
        sk.sweep(task5, {BOTH[0]: [0.04, 0.05]}, TIMES, workers=1, analysis=analysis, **keywords)


def test_a_dynamic_sweep_varies_a_blow_and_the_springs_of_a_unit(client):
    """The struck lattice over the plate's speed and two of the unit's springs (varied
    together): each variant is `solve_dynamics` of the model changed by hand."""
    lattice = sk.load_model(ROOT / "examples" / "dynamics" / "struck_lattice.toml")
    springs = ("units.cell.loads[0].stiffness", "units.cell.loads[1].stiffness")
    result = sk.sweep(lattice, {"bodies.plate.velocity.vx": [-1.0, -3.0], springs: [2.0, 5.0]}, DYNAMIC_TIMES, client,
                      points=["s0_0.ab"], coordinates=True)  # fmt: skip
    assert result.columns == ("bodies.plate.velocity.vx", *springs) and (result.status == "complete").all()
    for k, (speed, stiffness) in enumerate([(-1.0, 2.0), (-1.0, 5.0), (-3.0, 2.0), (-3.0, 5.0)]):
        plate, *squares = lattice.own("bodies")
        repeat = lattice.repeats[0]
        loads = [dataclasses.replace(load, stiffness=stiffness) if n < 2 else load
                 for n, load in enumerate(repeat.unit.loads)]
        unit = dataclasses.replace(repeat.unit, loads=tuple(loads))
        changed = dataclasses.replace(lattice, bodies=(dataclasses.replace(plate, velocity=(speed, 0.0, 0.0)), *squares),
                                      repeats=(dataclasses.replace(repeat, unit=unit),))  # fmt: skip
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sk.RedundantConstraintWarning)
            _, run = dynamic_run(changed, points=["s0_0.ab"])
        np.testing.assert_array_equal(result.coordinates[k], run.coordinates)
        np.testing.assert_array_equal(result.energy_tracks[k], run.energy_tracks)
    np.testing.assert_allclose(result.energy_tracks[2, 0, 0], 9.0 * result.energy_tracks[0, 0, 0], rtol=1e-12)  # ∝ speed²


@pytest.mark.parametrize("path, message", [
    ("bodies.c99.mass", r'bodies\.c99\.mass: the model has no body "c99" \(known: '),
    ("bodies.c1.colour", r"bodies\.c1\.colour: expected bodies\.NAME\.mass, bodies\.NAME\.inertia or "),
    ("loads[4].damping", r"loads\[4\]\.damping: the model has 1 loads \(loads\[0\] … loads\[0\]\)"),
    ("loads.payload.stiffness", r"loads\.payload\.stiffness: loads\[0\] \(force on c1 at K\) has no number stiffness"),
    ("loads[0].value.amplitude", (r"loads\[0\]\.value\.amplitude: loads\[0\] \(force on c1 at K\) has the value "
                                  r"\(0\.0, -200\.0\): expected a law with the number parameter amplitude")),
])  # fmt: skip
def test_a_bad_body_or_load_path_names_it_and_what_was_expected(path, message):
    with pytest.raises(sk.ModelError, match=message):
        VariantSet({path: [1.0]}).bind(sk.load_model(ROOT / "examples" / "task5_dynamics.toml"))


def test_a_value_a_body_refuses_names_the_path():
    with pytest.raises(sk.ModelError, match=r"^bodies\.c1\.mass: expected a number >= 0, got -1\.0 \(value -1\.0\)$"):
        VariantSet({"bodies.c1.mass": [2.0, -1.0]}).bind(sk.load_model(ROOT / "examples" / "task5_dynamics.toml"))
