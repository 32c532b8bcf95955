"""``sparsekin run`` on a large chain written as a small file, in this fresh process; print what it cost.

Usage: ``python3 benchmarks/measure_file_run.py FAMILY COPIES SAMPLES FOLDER [RUN OPTIONS...]``
(``SAMPLES`` 0: only read the model and build its pattern, and time those)

Writes ``FOLDER/FAMILY.toml``: ``examples/task5_chain.toml`` or ``examples/four_bar_chain.toml``
with ``count = COPIES``; then runs ``sparsekin run`` on it (``--t-end (SAMPLES - 1) · 0.01``,
``--steps SAMPLES``, ``--quiet``, and the extra options) in this process, and prints one
JSON object: the file's size, the seconds to import sparsekin, to read the model, to the
first sample solved (from the start of this process), per sample after it, and the peak
resident memory of the process (VmHWM).
"""

from __future__ import annotations

import time

_START = time.perf_counter()  # before anything is imported: the start of the "command"

import contextlib  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

_HERE = Path(__file__).resolve().parent
_EXAMPLES = _HERE.parent / "examples"
sys.path.insert(0, str(_HERE.parent))  # sparsekin when not installed

#: The model file of each family, and the line that says how many copies.
FILES = {"task5_chain": "task5_chain.toml", "four_bar_chain": "four_bar_chain.toml",
         "rotating_squares": "rotating_squares.toml", "lattice": "lattice.toml"}  # fmt: skip
#: The grids among them: COPIES is then the number of columns and of rows, ``count = [COPIES, COPIES]``.
GRIDS = ("rotating_squares", "lattice")
#: The time step of the runs, s.
STEP = 0.01


def write_model(family: str, copies: int, folder: Path) -> Path:
    text = (_EXAMPLES / FILES[family]).read_text(encoding="utf-8")
    if family in GRIDS:
        text, n = re.subn(r"(?m)^count = \[\d+, \d+\]", f"count = [{copies}, {copies}]", text)
    else:
        text, n = re.subn(r"(?m)^count = \d+$", f"count = {copies}", text)
    if n != 1:
        raise RuntimeError(f"no single count line in {FILES[family]}")
    # the points the example keeps name copies that a shorter chain may not have: the run names its own
    text = re.sub(r'(?m)^points = \[[^\n]*"[A-Za-z]+\d+(?:_\d+)?\.[^\n]*\][^\n]*\n', "", text, count=1)
    path = folder / f"{family}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def peak_rss_bytes() -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmHWM in /proc/self/status")


def setup(family: str, copies: int, folder: Path) -> dict:
    """Read the model file and build its pattern: what a run does before its first sample."""
    path = write_model(family, copies, folder)
    from sparsekin import load_model
    from sparsekin.engine.pattern import build_pattern

    start = time.perf_counter()
    mechanism = load_model(path)
    read = time.perf_counter()
    build_pattern(mechanism)
    done = time.perf_counter()
    return {"family": family, "bodies": mechanism.n_bodies, "file_bytes": path.stat().st_size,
            "read_seconds": read - start, "pattern_seconds": done - read, "peak_rss_bytes": peak_rss_bytes()}  # fmt: skip


def main(family: str, copies: int, samples: int, folder: Path, options: list[str]) -> dict:
    if samples == 0:
        return setup(family, copies, folder)
    path = write_model(family, copies, folder)
    import sparsekin.cli as cli

    imported = time.perf_counter()
    arguments = ["run", str(path), "--t-end", repr((samples - 1) * STEP), "--steps", str(samples), "--quiet",
                 "--out", str(folder / "out"), *options]  # fmt: skip
    output = io.StringIO()
    with contextlib.redirect_stdout(output):
        status = cli.main(arguments)
    if status != 0:
        raise RuntimeError(f"sparsekin run exited {status}: {output.getvalue()}")
    summary = output.getvalue()
    times = re.search(r"model read in (\S+) s, (?:first sample|first \d+ samples) solved (\S+) s after the start, (\S+) s a sample",
                      summary)  # fmt: skip
    bodies = int(re.search(r": (\d+) bodies", summary)[1])
    read, first, per_sample = (float(x) for x in times.groups())
    startup = imported - _START
    return {
        "family": family,
        "bodies": bodies,
        "samples": samples,
        "options": " ".join(options),
        "file_bytes": path.stat().st_size,
        "import_seconds": startup,
        "read_seconds": read,
        "first_sample_seconds": startup + first,  # from the start of the process
        "seconds_per_sample": per_sample,
        "peak_rss_bytes": peak_rss_bytes(),
    }


if __name__ == "__main__":
    family, copies, samples, folder, *options = sys.argv[1:]
    print(json.dumps(main(family, int(copies), int(samples), Path(folder), options)))
