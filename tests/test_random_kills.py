"""A run killed at any moment (SIGKILL or SIGTERM, CSV or Zarr) never leaves a folder whose
files disagree with each other or with a clean run on the samples they hold.

Each trial copies the folder of a previous run (other sample times) to a new folder,
starts ``sparsekin run`` on it in a new process and kills it at one of several times
spread over the length of a clean run from the moment it locks its folder (its imports
done: their length varies most on a loaded machine).  Then:

* every file in the folder (hidden staging files aside) comes from one run: the previous
  one (byte for byte) or the killed one;
* each file of the killed run holds a prefix of the clean run's samples, bit for bit, and
  all of them the same number of samples; ``run.json``, if there, lists exactly them and
  that number;
* a Zarr store opens (with and without its consolidated metadata), with ``t`` and every
  variable of the same length: the samples whose time is written are a prefix of the
  clean run's, every variable's bit for bit, and the others have no time (NaN).

The suite kills once per format, while the files are written (`SUITE_KILLS`); ``python
tests/test_random_kills.py [KILLS]`` runs the full count (20 per format and signal by
default: half timed from the lock, half from the first file written) and prints them.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "four_bar_chain.toml"  # 2001 bodies: a few milliseconds a sample
#: The kill times per format in the suite.
SUITE_KILLS = 1
#: Samples per run: in the suite, one chunk of the store (written at the end); the full
#: count (``__main__``) gives the store 1000, three chunks written while the run goes on.
STEPS = {"csv": 300, "zarr": 300}


def command(out: Path, format_: str, t_end: float) -> list[str]:
    return [sys.executable, "-m", "sparsekin", "run", str(MODEL), "--t-end", str(t_end), "--steps", str(STEPS[format_]),
            "--coordinates", "--points", "u999.Q,A0", "--format", format_, "--out", str(out), "--quiet"]  # fmt: skip


def environment() -> dict:
    return dict(os.environ, PYTHONPATH=str(ROOT))


def started(out: Path) -> bool:
    """Whether the run has its output folder locked (its imports done): its staging folder."""
    return any(out.glob(".sparsekin-staging-*"))


def writing(out: Path) -> bool:
    """Whether the run writes its results: a staged file (CSV), or its store in place (Zarr:
    the previous run's ``run.json`` gone, a store with ``t`` there)."""
    if any(path.stat().st_size for path in out.glob(".sparsekin-staging-*/*")):
        return True
    try:  # the previous run's store (copied with its times) stays until the new one replaces it
        return started(out) and (out / "results.zarr" / "t" / ".zarray").stat().st_mtime > _COPIED.get(out, 0.0)
    except OSError:
        return False


#: When each trial's folder was copied from the previous run's, s since the epoch.
_COPIED: dict[Path, float] = {}


def run_until(out: Path, format_: str, t_end: float, moment: float | None, signum: int = signal.SIGKILL,
              after=started):  # fmt: skip
    """Start the run; from the moment `after(out)` holds (by default: it has locked its
    folder), wait `moment` s and send `signum` (None: let it end).  The exit status, the
    stderr and how long it ran after that moment, s."""
    process = subprocess.Popen(command(out, format_, t_end), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               env=environment())  # fmt: skip
    deadline = time.monotonic() + 300
    while not after(out) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    start = time.monotonic()
    if moment is not None:
        time.sleep(moment)
        process.send_signal(signum)
    _, error = process.communicate(timeout=300)
    return process.returncode, error.decode(), time.monotonic() - start


def clean_runs(base: Path, format_: str) -> tuple[Path, Path, float]:
    """The folders of a previous run (t_end 0.5) and of a clean run (t_end 1), and how long
    the clean run lasted, s: in this process (its imports done, as a killed run's once it
    has locked its folder)."""
    from sparsekin.cli import main as sparsekin

    previous, clean = base / f"previous-{format_}", base / f"clean-{format_}"
    assert sparsekin(command(previous, format_, 0.5)[3:]) == 0
    start = time.monotonic()
    assert sparsekin(command(clean, format_, 1.0)[3:]) == 0
    return previous, clean, time.monotonic() - start


def kill_at(out: Path, format_: str, previous: Path, moment: float, signum: int, after=started) -> int:
    """Copy `previous` to `out`, start the run there and send `signum` `moment` s after
    `after(out)` (it has locked the folder); the exit status."""
    shutil.copytree(previous, out)  # with the previous files' times
    _COPIED[out] = time.time()
    status, error, _ = run_until(out, format_, 1.0, moment, signum, after)
    assert "Traceback" not in error, error
    return status


def check_folder(out: Path, previous: Path, clean: Path) -> str:
    """Check `out` as the module docstring says; which run its files come from and how many
    samples they hold (``"previous"``, ``"new 120"``, ``"empty"``)."""
    names = sorted(path.name for path in out.iterdir() if not path.name.startswith("."))
    if not names:
        return "empty"
    runs, counts = set(), set()
    for name in names:
        if name == "run.json":
            continue
        if name == "results.zarr":
            run, count = _check_store(out / name, previous / name, clean / name)
        elif (previous / name).exists() and _same_bytes(out / name, previous / name):
            run, count = "previous", None
        elif name.endswith(".csv"):
            lines = (out / name).read_text().splitlines()
            assert lines == (clean / name).read_text().splitlines()[: len(lines)], name
            run, count = "new", len(lines) - 1
        else:
            with np.load(out / name) as held, np.load(clean / name) as reference:
                count = held["t"].size
                for key in ("t", "q", "qd", "qdd"):
                    np.testing.assert_array_equal(held[key], reference[key][:count], err_msg=name)
            run = "new"
        runs.add(run)
        if count is not None:
            counts.add(count)
    assert len(runs) <= 1, f"files of two runs: {names}"
    assert len(counts) <= 1, f"files with different numbers of samples: {counts}"
    if "run.json" in names:
        record = json.loads((out / "run.json").read_text())
        if runs == {"new"} or not runs:
            assert sorted(record["files"]) == [name for name in names if name != "run.json"]
            assert not counts or record["samples_solved"] == next(iter(counts))
        else:
            assert _same_bytes(out / "run.json", previous / "run.json")
    run = runs.pop() if runs else "run.json alone"
    return f"{run} {counts.pop()}" if counts else run


def _same_bytes(a: Path, b: Path) -> bool:
    return a.read_bytes() == b.read_bytes()


def _check_store(store: Path, previous: Path, clean: Path) -> tuple[str, int | None]:
    import xarray

    dataset = xarray.open_zarr(store, consolidated=False)
    consolidated = xarray.open_zarr(store)
    assert dict(dataset.sizes) == dict(consolidated.sizes)
    times = dataset["t"].values
    count = int(np.isfinite(times).sum())
    assert np.isfinite(times[:count]).all() and np.isnan(times[count:]).all()
    old, new = xarray.open_zarr(previous), xarray.open_zarr(clean)
    reference, run = (old, "previous") if count > 1 and times[1] == old["t"].values[1] else (new, "new")
    for key in ("t", "q", "qd", "qdd", "points"):
        np.testing.assert_array_equal(dataset[key].values[:count], reference[key].values[:count], err_msg=key)
    return run, count


def moments(duration: float, kills: int, beyond: float = 1.1) -> list[float]:
    """`kills` times spread over the run from the moment it locked its folder to `beyond`
    times its clean length (a loaded machine slows a run down)."""
    return [beyond * duration * (k + 0.5) / kills for k in range(kills)]


@pytest.mark.parametrize("format_", ["csv", "zarr"])
def test_a_run_killed_at_any_moment_leaves_a_consistent_folder(format_, tmp_path):
    if format_ == "zarr":
        pytest.importorskip("xarray")
    previous, clean, duration = clean_runs(tmp_path, format_)
    # SIGKILL while it writes (SIGTERM: tests/test_signals.py; the full count: ``__main__``)
    plan = [(0.1 if format_ == "csv" else 0.02, writing, signal.SIGKILL)]  # the store: one chunk, at the end
    for k, (moment, after, signum) in enumerate(plan[:SUITE_KILLS]):
        out = tmp_path / f"killed-{k}"
        status = kill_at(out, format_, previous, moment, signum, after)
        assert status in (0, -signum, 128 + signum), status
        check_folder(out, previous, clean)


def main(kills: int, formats=("csv", "zarr")) -> None:
    """Run `kills` kill times per format and signal; print what each folder held."""
    import tempfile

    with tempfile.TemporaryDirectory() as base:
        base = Path(base)
        for format_ in formats:
            previous, clean, duration = clean_runs(base, format_)
            print(f"{format_}: a clean run lasts {duration:.2f} s once it has locked its folder")
            for signum in (signal.SIGKILL, signal.SIGTERM):
                outcomes = []
                failures = 0
                # half from the lock on, over the run; half from the first file written on, over
                # the writing (CSV: 0.8 s) or the rest of the run (Zarr)
                tail = 0.8 if format_ == "csv" else 0.8 * duration
                plan = [(moment, started, "lock") for moment in moments(duration, kills // 2, 1.2)]
                plan += [(tail * (k + 0.5) / (kills - kills // 2), writing, "writing")
                         for k in range(kills - kills // 2)]  # fmt: skip
                for k, (moment, after, since) in enumerate(plan):
                    out = base / f"{format_}-{signum}-{k}"
                    status = kill_at(out, format_, previous, moment, signum, after)
                    try:
                        outcomes.append(f"{since} + {moment:.2f} s: exit {status}, "
                                        f"{check_folder(out, previous, clean)}")  # fmt: skip
                    except Exception as error:  # noqa: BLE001 - reported, and the run goes on
                        failures += 1
                        outcomes.append(f"{since} + {moment:.2f} s: exit {status}, INCONSISTENT: {type(error).__name__}: "
                                        f"{' '.join(str(error).split())[:300]}")  # fmt: skip
                    shutil.rmtree(out)
                verdict = "every folder consistent" if not failures else f"{failures} INCONSISTENT"
                print(f"  {signal.Signals(signum).name}: {kills} kills, {verdict}", flush=True)
                for line in outcomes:
                    print(f"    {line}")


if __name__ == "__main__":
    STEPS["zarr"] = 1000
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20, *([sys.argv[2:]] if len(sys.argv) > 2 else []))
