"""Sizes at the edges of the machine: a size that would not fit in memory is refused with
one line before any work (`sparsekin.cli.sizes`), a model file that is no model file too,
and a full disk says which file, what was kept, and exits 3."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from sparsekin.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
TASK5 = EXAMPLES / "task5.toml"


def one_error_line(capsys) -> str:
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def repeated(tmp_path: Path, example: str, old: str, new: str) -> Path:
    text = (EXAMPLES / example).read_text()
    assert old in text
    path = tmp_path / example
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize("case", ["chain of 1e10 copies", "grid of 1e5 × 1e5 copies"])
def test_a_model_too_large_to_build_is_refused_before_it_is_built(case, tmp_path, capsys):
    if case.startswith("chain"):
        model, copies = repeated(tmp_path, "four_bar_chain.toml", "count = 1000", "count = 10000000000"), "10000000000"
    else:
        model, copies = repeated(tmp_path, "lattice.toml", "count = [9, 6]", "count = [100000, 100000]"), "100000 × 100000"
    for command in ("run", "check"):
        assert main([command, str(model), "--out", str(tmp_path / "out")][: 2 if command == "check" else 4]) == 2
        line = one_error_line(capsys)
        assert line.startswith("sparsekin: error: needs about ") and f"({copies} copies of unit " in line, line
        assert " TB of memory " in line and "give the repeats fewer copies" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("arguments, expected", [
    (["run", str(TASK5), "--steps", "1000000000000"], "(1000000000000 sample times: 15 TB), "),
    (["animate", str(TASK5), "--duration", "1e9"], "(20000000000 frames: "),
    (["workspace", str(TASK5), "--point", "K", "--grid", "100000"], "(10000000000 grid points: 2.9 TB), "),
    (["run", str(TASK5), "--max-memory", "100M"], ", --max-memory allows 100 MB; "),
])  # fmt: skip
def test_a_size_beyond_the_memory_is_refused_before_any_work(arguments, expected, tmp_path, capsys):
    out = tmp_path / ("out.gif" if arguments[0] == "animate" else "out")
    assert main([*arguments, "--out", str(out)]) == 2
    line = one_error_line(capsys)
    assert line.startswith("sparsekin: error: needs about ") and expected in line, line
    assert not out.exists()


def test_the_limit_comes_from_the_environment_and_sizes_are_checked(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("SPARSEKIN_MAX_MEMORY", "50M")
    assert main(["run", str(TASK5), "--out", str(tmp_path / "out")]) == 2
    assert ", SPARSEKIN_MAX_MEMORY allows 50 MB; " in one_error_line(capsys)
    assert main(["run", str(TASK5), "--max-memory", "lots", "--out", str(tmp_path / "out")]) == 2
    assert one_error_line(capsys) == ("sparsekin: error: --max-memory: expected a size such as 8G, 512M or a number of "
                                      "bytes, got 'lots'")  # fmt: skip
    monkeypatch.setenv("SPARSEKIN_MAX_MEMORY", "64G")  # more than needed: the run goes on
    assert main(["run", str(TASK5), "--steps", "3", "--t-end", "1", "--out", str(tmp_path / "out")]) == 0


def test_a_sweep_too_large_is_refused_before_its_values_are_made(tmp_path, capsys):
    pytest.importorskip("distributed")
    assert main(["sweep", str(TASK5), "--vary", "drivers[0].law.amplitude=0.03:0.07:1000000000", "--out",
                 str(tmp_path / "out")]) == 2  # fmt: skip
    line = one_error_line(capsys)
    assert line.startswith("sparsekin: error: needs about ") and "(1000000000 variants: " in line, line


def limited(kind: int, size: int):
    """A `preexec_fn` setting the soft and hard limit `kind` to `size` bytes (and, for the
    file size, ignoring SIGXFSZ, so that a write beyond it fails with EFBIG)."""

    def limit() -> None:
        resource.setrlimit(kind, (size, size))
        if kind == resource.RLIMIT_FSIZE:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    return limit


def run_limited(arguments: list[str], kind: int, size: int) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sparsekin", *arguments], check=False, capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)), preexec_fn=limited(kind, size))  # fmt: skip


def test_a_model_beyond_an_address_space_limit_is_refused(tmp_path):
    """3·10^6 bodies under ``ulimit -v`` of 3 GB: one line and exit 2, not a MemoryError."""
    model = repeated(tmp_path, "four_bar_chain.toml", "count = 1000", "count = 1500000")
    finished = run_limited(["run", str(model), "--out", str(tmp_path / "out")], resource.RLIMIT_AS, 3 * 2**30)
    assert finished.returncode == 2, finished.stderr
    lines = finished.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("sparsekin: error: needs about "), lines
    assert "the address-space limit (ulimit -v) allows" in lines[0]


@pytest.mark.parametrize("format_", ["csv", "zarr"])
def test_a_full_disk_names_the_file_and_what_was_kept(format_, tmp_path):
    """A file-size limit (``ulimit -f``) of half the largest file the run writes without one:
    coordinates.npz (or the store's first chunk) cannot be written whole.  (A fixed 1 MB
    stopped failing the store once the chain's identical cells came out bit for bit alike
    and its chunks compressed to 110 kB.)"""
    if format_ == "zarr":
        pytest.importorskip("xarray")
    def arguments(out):
        return ["run", str(EXAMPLES / "four_bar_chain.toml"), "--t-end", "0.1", "--steps", "60", "--coordinates",
                "--points", "u999.Q", "--format", format_, "--out", str(out), "--quiet"]  # fmt: skip

    free = run_limited(arguments(tmp_path / "free"), resource.RLIMIT_FSIZE, resource.RLIM_INFINITY)
    assert free.returncode == 0, free.stderr
    sizes = sorted(path.stat().st_size for path in (tmp_path / "free").rglob("*") if path.is_file())
    assert sizes[-2] < sizes[-1] // 2  # only the largest file is over the limit
    out = tmp_path / "out"
    finished = run_limited(arguments(out), resource.RLIMIT_FSIZE, sizes[-1] // 2)
    assert finished.returncode == 3, finished.stderr
    lines = [line for line in finished.stderr.splitlines() if "note:" not in line]
    assert len(lines) == 1, lines
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "disk_full" and record["exit_status"] == 3
    if format_ == "csv":
        assert lines[0] == (f"sparsekin: error: {out / 'coordinates.npz'}: File too large: 60 of 60 samples solved; "
                            f"kept points.csv, joints.csv in {out}")  # fmt: skip
        assert record["files"] == ["points.csv", "joints.csv"] and not (out / "coordinates.npz").exists()
        assert len((out / "points.csv").read_text().splitlines()) == 61
    else:
        # the 60 samples are one chunk, written at the end of the run: none could be kept
        assert lines[0] == (f"sparsekin: error: {out / 'results.zarr'}: File too large: kept the first 0 of 60 samples "
                            "(results.zarr not written)")  # fmt: skip
        assert record["files"] == [] and record["samples_solved"] == 0
    assert sorted(path.name for path in out.iterdir() if not path.name.startswith(".")) == sorted(
        [*record["files"], "run.json"])


@pytest.mark.parametrize("case", ["a device", "nested 500 deep", "larger than 256 MB"])
def test_a_file_that_is_no_model_file_is_one_line(case, tmp_path, capsys):
    if case == "a device":
        model, expected = Path("/dev/zero"), "/dev/zero: not a regular file"
        if not model.exists():
            pytest.skip("no /dev/zero here")
    elif case == "nested 500 deep":
        model, expected = tmp_path / "deep.toml", "deep.toml: arrays or tables nested too deep to read"
        model.write_text("a = " + "[" * 500 + "]" * 500 + "\n")
    else:
        model, expected = tmp_path / "large.toml", "large.toml: larger than 256 MB"
        with open(model, "wb") as file:
            file.truncate(300 * 2**20)  # sparse: no disk used
    assert main(["run", str(model), "--out", str(tmp_path / "out")]) == 2
    line = one_error_line(capsys)
    assert line.startswith("sparsekin: error: ") and expected in line, line
