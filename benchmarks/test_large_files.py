"""Large chains from small files, end to end through ``sparsekin run``, each in a fresh process.

`benchmarks/measure_file_run.py` writes the model file (``examples/task5_chain.toml`` or
``examples/four_bar_chain.toml`` with another `count`), runs the command on it and reports
the time to read it, to build its pattern, to the first sample from the start of the
process, per sample after it, and the process's peak resident memory.

* ``setup``: reading the file and building the pattern (issue 10's target at 10^6 bodies:
  at most 2 s together);
* ``run``: 100 samples keeping three points (first sample within 5 s of the start, peak
  memory at most 2 GB at 10^6 bodies), and 10 samples at 10^7 bodies;
* ``streamed``: every coordinate streamed to a Zarr store, 50 and 500 samples: peak
  memory must not grow with the number of samples.

``--sizes=smoke`` (the test suite) runs small chains; ``--sizes=full`` the sizes above
(about 10 minutes, 15 GB at 10^7 bodies).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parent / "measure_file_run.py"
THREE_POINTS = {"task5_chain": "u0.K,u{half}.K,u{last}.K", "four_bar_chain": "A0,u{half}.Q,u{last}.Q"}
CASES = {
    # name: (family, copies at smoke size, copies at full size, samples, extra options)
    "setup task5_chain": ("task5_chain", 100, 100_000, 0, ()),
    "run task5_chain": ("task5_chain", 100, 100_000, 100, ("points",)),
    "run task5_chain, largest": ("task5_chain", 200, 1_000_000, 10, ("points",)),
    "run four_bar_chain, largest": ("four_bar_chain", 500, 5_000_000, 10, ("points",)),
    "streamed 50 samples": ("task5_chain", 100, 10_000, 50, ("zarr",)),
    "streamed 500 samples": ("task5_chain", 100, 10_000, 500, ("zarr",)),
}


@pytest.fixture
def size(request):
    return request.config.getoption("--sizes")


@pytest.mark.parametrize("case", CASES)
def test_large_file(benchmark, case, size, tmp_path):
    family, smoke, full, samples, extras = CASES[case]
    copies = full if size == "full" else smoke
    options = []
    if "points" in extras:
        options += ["--points", THREE_POINTS[family].format(half=copies // 2, last=copies - 1)]
    if "zarr" in extras:
        options += ["--format", "zarr", "--coordinates", "--points", "none", "--joints", "none"]
    arguments = [sys.executable, str(SCRIPT), family, str(copies), str(samples), str(tmp_path), *options]

    def measure():
        return json.loads(subprocess.run(arguments, check=True, capture_output=True, text=True).stdout)

    measured = benchmark.pedantic(measure, rounds=1, iterations=1)
    assert measured["peak_rss_bytes"] > 0 and measured["file_bytes"] < 20_000  # a small file, however long the chain
    benchmark.extra_info.update(measured, case=case)
