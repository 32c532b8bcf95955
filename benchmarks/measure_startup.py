"""How long ``sparsekin run examples/task5.toml`` takes from the shell: warm, cold, imports.

Usage: ``python3 benchmarks/measure_startup.py [SOURCE_TREE] [--warm N] [--cold N]``

Each figure is the median wall time of fresh processes (``python3 -m sparsekin``, the
package taken from SOURCE_TREE, default this checkout):

* ``import``: ``import sparsekin.cli``;
* ``warm``: the whole command with numba's cache filled (one run first fills it);
* ``cold``: the whole command with an empty numba cache (``NUMBA_CACHE_DIR`` set to a new
  folder): the first run after an install, every kernel compiled.

Each figure also has its CPU time (``*_cpu_seconds``: user + system of the child
process), which the other processes of a shared machine disturb far less than the wall
time (issue 21 measured the cold run's wall time at 9–31 s within one hour).

Prints one JSON object.  SOURCE_TREE lets the same script measure an older commit
checked out elsewhere (``git worktree add /tmp/old COMMIT``) in the same session.
"""

from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def wall_time(arguments: list[str], environment: dict, cpu: list | None = None) -> float:
    """Wall time of the command, s; its CPU time (user + system) appended to `cpu`."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(arguments, check=True, env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if cpu is not None:
        cpu.append((after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime))
    return wall


def measure(source: Path, warm: int, cold: int) -> dict:
    environment = dict(os.environ, PYTHONPATH=str(source))
    with tempfile.TemporaryDirectory() as folder:
        run = [sys.executable, "-m", "sparsekin", "run", str(source / "examples" / "task5.toml"), "--out", folder]
        importing = [sys.executable, "-c", "import sparsekin.cli"]
        wall_time(run, environment)  # fills the cache
        figures = {"import_cpu_seconds": [], "warm_cpu_seconds": [], "cold_cpu_seconds": []}
        figures["import_seconds"] = [wall_time(importing, environment, figures["import_cpu_seconds"]) for _ in range(warm)]
        figures["warm_seconds"] = [wall_time(run, environment, figures["warm_cpu_seconds"]) for _ in range(warm)]
        figures["cold_seconds"] = []
        for _ in range(cold):
            with tempfile.TemporaryDirectory() as cache:
                cold_environment = dict(environment, NUMBA_CACHE_DIR=cache)
                figures["cold_seconds"].append(wall_time(run, cold_environment, figures["cold_cpu_seconds"]))
    medians = {key: statistics.median(values) for key, values in figures.items() if values}
    return {"source": str(source), **medians, "runs": figures}


if __name__ == "__main__":
    arguments = sys.argv[1:]
    source = Path(arguments.pop(0)).resolve() if arguments and not arguments[0].startswith("--") else ROOT
    counts = {"--warm": 7, "--cold": 3}
    for option, value in zip(arguments[::2], arguments[1::2]):
        if option not in counts:
            sys.exit(__doc__)
        counts[option] = int(value)
    print(json.dumps(measure(source, counts["--warm"], counts["--cold"])))
