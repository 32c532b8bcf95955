"""Start-up of ``sparsekin run examples/task5.toml`` from the shell, in fresh processes.

`benchmarks/measure_startup.py` measures ``import sparsekin.cli``, the whole command with
numba's cache filled (warm), and with an empty cache (cold: the first run after an
install).  Issue 13's targets: warm ≤ 0.5 s, cold ≤ 5 s.  ``--sizes=full`` takes 7 warm
and 3 cold processes (about a minute); the smoke size one warm process and no cold one.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parent / "measure_startup.py"


def test_startup(benchmark, request):
    full = request.config.getoption("--sizes") == "full"
    counts = ["--warm", "7", "--cold", "3"] if full else ["--warm", "1", "--cold", "0"]
    runs = []

    def measure():
        output = subprocess.run([sys.executable, str(SCRIPT), *counts], check=True, capture_output=True, text=True)
        runs.append(json.loads(output.stdout))

    benchmark.pedantic(measure, rounds=1, iterations=1)
    (measured,) = runs
    assert measured["warm_seconds"] > 0.0 and measured["warm_cpu_seconds"] > 0.0
    benchmark.extra_info.update({key: value for key, value in measured.items() if key != "source"})
