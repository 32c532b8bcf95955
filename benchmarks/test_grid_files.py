"""Grids of 10^6 bodies from files of a few kB: reading and building the pattern, in fresh processes.

`benchmarks/measure_file_run.py` writes ``examples/rotating_squares.toml`` (a 2×2 motif of
squares per copy) or ``examples/lattice.toml`` with ``count = [N, N]``, reads it and builds
its pattern, and reports the seconds of each and the process's peak resident memory.
The four-bar chain of the same size is measured in the same run, as the baseline of a
repeat that the grids should match (issue 19's target: read + pattern at most 3 s and at
most 3 GB at 10^6 bodies; solving such a grid is the business of the redundancy and mesh
issues).  Figures are medians of `ROUNDS` processes; quote them as ratios to the chain.

``--sizes=smoke`` (the test suite) runs 3 × 3 copies; ``--sizes=full`` 10^6 bodies.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

#: Fresh processes per measurement (its figures are the medians).
ROUNDS = 3
SCRIPT = Path(__file__).resolve().parent / "measure_file_run.py"
#: Largest file the grids may take, bytes (issue 19: at most 5 kB for 10^6 bodies).
MAX_FILE_BYTES = 5_000
CASES = {
    # name: (family, copies at smoke size, copies at full size); a grid's copies are N × N
    "setup rotating_squares": ("rotating_squares", 3, 500),  # 4 squares a copy: 10^6 bodies
    "setup lattice": ("lattice", 3, 708),  # 2·N − 1 bars a row of copies: 1 001 820 bodies
    "setup four_bar_chain (baseline)": ("four_bar_chain", 20, 500_000),  # 1 000 001 bodies
}


@pytest.fixture
def size(request):
    return request.config.getoption("--sizes")


@pytest.mark.parametrize("case", CASES)
def test_grid_file_setup(benchmark, case, size, tmp_path):
    family, smoke, full = CASES[case]
    copies = full if size == "full" else smoke
    arguments = [sys.executable, str(SCRIPT), family, str(copies), "0", str(tmp_path)]
    runs = []

    def measure():
        runs.append(json.loads(subprocess.run(arguments, check=True, capture_output=True, text=True).stdout))

    benchmark.pedantic(measure, rounds=ROUNDS, iterations=1)
    assert all(run["file_bytes"] <= MAX_FILE_BYTES and run["peak_rss_bytes"] > 0 for run in runs)
    medians = {key: float(np.median([run[key] for run in runs])) for key, value in runs[0].items()
               if isinstance(value, float)}  # fmt: skip
    benchmark.extra_info.update(runs[0], **medians, case=case, rounds=len(runs),
                                peak_rss_bytes=max(run["peak_rss_bytes"] for run in runs))  # fmt: skip
