"""Overconstrained mechanisms at scale (issue 18): check, first sample, per step, memory.

Each case is one fresh process (`measure_redundancy.py`): the rotating squares (n×n,
(n − 2)² redundant equations) beside a `lattice` of about the same number of bodies and
no redundancy, and the parallel-bar chain with three bars per cell (one redundant equation
per cell) beside its two-bar twin, in the same run.  make_results.py renders them, with
the exponent of the squares' setup time (check and first sample) against the bodies.

Targets (issue 18): 100×100 squares `check` ≤ 10 s, first sample ≤ 10 s, peak ≤ 2 GB;
300×300 squares: 10 samples ≤ 120 s, ≤ 8 GB; the chain of 10^4 cells: setup ≤ 3× and per
step ≤ 1.5× the two-bar chain; the exponent of the setup time over 30×30 … 300×300 ≤ 1.3.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path


#: (family, size) per ``--sizes``: squares per side, or cells.
CASES = {
    "smoke": (("rotating_squares", 4), ("parallel_bar_chain_3", 10)),
    "full": (
        ("rotating_squares", 30), ("lattice_like_squares", 30),
        ("rotating_squares", 60), ("lattice_like_squares", 60),
        ("rotating_squares", 100), ("lattice_like_squares", 100),
        ("rotating_squares", 200), ("rotating_squares", 300), ("lattice_like_squares", 300),
        ("parallel_bar_chain_3", 1_000), ("parallel_bar_chain_2", 1_000),
        ("parallel_bar_chain_3", 10_000), ("parallel_bar_chain_2", 10_000),
    ),
}  # fmt: skip
#: Time steps after the first sample, whose median is the time per step.
STEPS = 10


def pytest_generate_tests(metafunc):
    if metafunc.function is test_overconstrained:
        cases = CASES[metafunc.config.getoption("--sizes")]
        metafunc.parametrize("family, size", cases, ids=[f"{family}-{size}" for family, size in cases])


def test_overconstrained(benchmark, family, size):
    script = Path(__file__).resolve().parent / "measure_redundancy.py"

    def measure():
        output = subprocess.run(
            [sys.executable, str(script), family, str(size), str(STEPS)], check=True, capture_output=True, text=True
        )
        return json.loads(output.stdout)

    measured = benchmark.pedantic(measure, rounds=1, iterations=1)
    assert measured["rank"] == measured["coordinates"]
    assert measured["redundant"] == measured["left_out"] == measured["equations"] - measured["rank"]
    if family == "rotating_squares":  # the closed-form error is recorded (the tests check accuracy)
        assert measured["redundant"] == (size - 2) ** 2
    benchmark.extra_info.update(measured)
