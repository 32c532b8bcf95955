"""A result folder is a complete, consistent record of what was solved, or says what it
holds: files renamed into place once whole, a lock against a second live run, the previous
run's files cleaned, ``run.json`` written last (`sparsekin.cli.outputs`)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sparsekin.cli import main
from sparsekin.cli.outputs import MANIFEST, STAGING_PREFIX

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
TASK5 = EXAMPLES / "task5.toml"
DYNAMICS = EXAMPLES / "task5_dynamics.toml"
CHAIN = EXAMPLES / "four_bar_chain.toml"  # 2001 bodies: a run of many samples lasts


def start_run(arguments: list[str], **options) -> subprocess.Popen:
    """``python -m sparsekin run ARGUMENTS`` in a new process."""
    environment = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "sparsekin", "run", *arguments], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=environment, **options)  # fmt: skip


def wait_for(condition, process: subprocess.Popen, seconds: float = 120.0) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the run did not get there in time"
        time.sleep(0.02)


def staging_exists(out: Path):
    return lambda: any(out.glob(f"{STAGING_PREFIX}*"))


def manifest(out: Path) -> dict:
    return json.loads((out / MANIFEST).read_text())


def test_run_json_says_what_the_folder_holds(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(TASK5), "--t-end", "1", "--steps", "11", "--out", str(out)]) == 0
    record = manifest(out)
    assert record["files"] == ["points.csv", "joints.csv", "coordinates.npz"]
    assert sorted(path.name for path in out.iterdir()) == sorted([*record["files"], MANIFEST])
    assert record["status"] == "complete" and record["exit_status"] == 0
    assert (record["samples_solved"], record["samples_requested"]) == (11, 11)
    assert record["command"] == ["sparsekin", "run", str(TASK5), "--t-end", "1", "--steps", "11", "--out", str(out)]
    import hashlib

    assert record["model_sha256"] == hashlib.sha256(TASK5.read_bytes()).hexdigest()
    assert f"  {out / MANIFEST}" in capsys.readouterr().out.splitlines()


def test_a_reused_folder_keeps_only_this_runs_files(tmp_path, capsys):
    """A run with forces and figures, then one without: forces.csv, the figures and the
    coordinates of the first are removed, a file of the user's is kept."""
    pytest.importorskip("matplotlib")
    out = tmp_path / "out"
    assert main(["run", str(DYNAMICS), "--t-end", "0.5", "--steps", "3", "--out", str(out), "--plot"]) == 0
    first = set(manifest(out)["files"])
    assert {"forces.csv", "coordinates.npz", "forces.png", "mechanism.png"} <= first
    (out / "notes.txt").write_text("mine")
    assert main(["run", str(TASK5), "--t-end", "1", "--steps", "11", "--out", str(out), "--no-coordinates"]) == 0
    assert manifest(out)["files"] == ["points.csv", "joints.csv"]
    assert sorted(path.name for path in out.iterdir()) == ["joints.csv", "notes.txt", "points.csv", MANIFEST]
    assert len((out / "points.csv").read_text().splitlines()) == 12  # the header and 11 samples of the new run
    assert main(["run", str(TASK5), "--t-end", "1", "--steps", "3", "--out", str(out), "--format", "zarr"]) == 0
    assert sorted(path.name for path in out.iterdir()) == ["notes.txt", "results.zarr", MANIFEST]


@pytest.mark.parametrize("case", ["points.csv is a folder", "--out is a file", "--out is in a file"])
def test_an_output_that_cannot_be_written_is_refused_before_solving(case, tmp_path, capsys, monkeypatch):
    from sparsekin.cli import run

    def never(*args, **kwargs):
        raise AssertionError("solved before the outputs were checked")

    monkeypatch.setattr(run, "solve_for_command", never)
    out = tmp_path / "out"
    if case == "points.csv is a folder":
        (out / "points.csv").mkdir(parents=True)
        expected = f"sparsekin: error: {out / 'points.csv'}: is a folder where the run writes a file; "
    elif case == "--out is a file":
        out.write_text("mine")
        expected = f"sparsekin: error: --out {out}: is a file; give a folder"
    else:
        (tmp_path / "file").write_text("mine")
        out = tmp_path / "file" / "out"
        expected = f"sparsekin: error: {out}: Not a directory"
    assert main(["run", str(TASK5), "--out", str(out)]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(expected), lines


def test_a_second_live_run_is_refused_and_a_killed_run_leaves_no_stale_lock(tmp_path, capsys):
    out = tmp_path / "out"
    first = start_run([str(CHAIN), "--t-end", "1", "--steps", "100001", "--points", "u999.Q", "--quiet", "--out",
                       str(out)])  # fmt: skip
    try:
        wait_for(staging_exists(out), first)
        assert main(["run", str(TASK5), "--t-end", "1", "--steps", "3", "--out", str(out)]) == 2
        assert capsys.readouterr().err == (f"sparsekin: error: {out}: another sparsekin run is writing this folder; "
                                           "wait for it to end or give another --out\n")  # fmt: skip
        assert first.poll() is None  # untouched
    finally:
        first.kill()
        first.communicate()
    assert main(["run", str(TASK5), "--t-end", "1", "--steps", "3", "--out", str(out)]) == 0
    assert not any(out.glob(f"{STAGING_PREFIX}*"))  # the killed run's staging folder is cleaned
    assert manifest(out)["samples_solved"] == 3


#: Runs ``sparsekin run`` with the solve replaced by a failure: a refusal must come first.
_RUN_WITHOUT_SOLVING = """
import sys
from sparsekin.cli import main, run

def never(*args, **kwargs):
    raise AssertionError("solved before the outputs were checked")

run.solve_for_command = never
sys.exit(main(sys.argv[1:]))
"""


def _without_permission_override():
    """In the child before it runs: as root, drop the capabilities that let root ignore
    permission bits (CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH) from the bounding set, so the
    program it runs is held to a folder's permissions as any other user is (root's own
    folders stay readable: they are root's)."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    for capability in (1, 2):  # CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH
        if libc.prctl(24, capability, 0, 0, 0) != 0:  # PR_CAPBSET_DROP
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP)")


@pytest.mark.parametrize("case", ["--out is read-only", "--out is in a read-only folder"])
def test_a_read_only_out_is_refused_before_solving(case, tmp_path):
    """Root ignores permission bits: run as root, the command runs without the capabilities
    that do so (a non-root user runs it as it is)."""
    parent = tmp_path / "read-only"
    parent.mkdir()
    out = parent if case == "--out is read-only" else parent / "out"
    parent.chmod(0o555)
    script = tmp_path / "run.py"
    script.write_text(_RUN_WITHOUT_SOLVING)
    options = {"preexec_fn": _without_permission_override} if os.geteuid() == 0 else {}
    try:
        done = subprocess.run([sys.executable, str(script), "run", str(TASK5), "--out", str(out)], capture_output=True,
                              text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)), timeout=300, check=False,
                              **options)  # fmt: skip
    except (OSError, subprocess.SubprocessError) as error:
        pytest.skip(f"cannot run without root's permission override here: {error}")
    finally:
        parent.chmod(0o755)
    lines = done.stderr.splitlines()
    assert done.returncode == 2 and len(lines) == 1, (done.returncode, done.stderr[-2000:])
    named = f"--out {out}" if out == parent else f"{out}"  # the folder given, or the one that cannot be made
    expected = f"sparsekin: error: {named}: Permission denied"
    assert lines[0].startswith(expected), lines
    assert list(parent.iterdir()) == []  # nothing written, no staging folder left


def test_a_clip_is_put_in_place_whole_or_not_at_all(tmp_path, capsys, monkeypatch):
    """``animate`` writes its clip at a temporary name beside the target and renames it once
    whole: a clip that fails half-way (a full disk here) leaves the previous clip as it was
    and no partial file; a partial file a killed run left is removed by the next run."""
    pytest.importorskip("matplotlib", reason='the animation needs "sparsekin[plot]"')
    import sparsekin.plots

    out = tmp_path / "clip.gif"
    out.write_bytes(b"the previous clip")
    (tmp_path / ".clip.99999999.partial.gif").write_bytes(b"left by a killed run")

    def half_a_clip(result, path, **options):
        Path(path).write_bytes(b"half a clip")
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(sparsekin.plots, "animate", half_a_clip)
    status = main(["animate", str(TASK5), "--t-end", "0.2", "--steps", "3", "--out", str(out)])
    err = capsys.readouterr().err
    assert status in (2, 3) and "Traceback" not in err and "No space left on device" in err, (status, err)
    assert out.read_bytes() == b"the previous clip"
    assert sorted(path.name for path in tmp_path.iterdir()) == ["clip.gif"]
