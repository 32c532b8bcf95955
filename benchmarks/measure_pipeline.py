"""Speed of the run pipeline against another source tree, interleaved in one session.

Issue 24 moved the time loop behind a stepper protocol and a generic run driver; this
measures that the user-facing runs kept their speed.  Each case runs in a fresh process of
each tree in turn (``--rounds`` rounds, trees alternating), so that both see the same
machine load:

* ``task5`` — `solve_kinematics` on Task 5 over 10 s at 1 ms (the compiled loop): seconds
  per sample of the whole run;
* ``chain_1e4``, ``chain_1e6`` and ``lattice_1e5`` — `solve_kinematics` on the test-set
  family of about that many bodies at 10 ms steps: the median over the run's steps of the
  time between two calls of its ``progress`` callback (one per sample on this path), so
  each step is timed with its recording and without the setup.

Usage (from the repository root)::

    python3 benchmarks/measure_pipeline.py --against /tmp/base24 --rounds 5 --cases task5 chain_1e4

prints one line per case and tree (median seconds, and the ratio to the other tree).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
#: case -> (family, bodies, steps)
CASES = {
    "task5": ("task5", 10, 10_000),
    "chain_1e4": ("task5_chain", 10_000, 30),
    "chain_1e6": ("task5_chain", 1_000_000, 4),
    "lattice_1e5": ("lattice", 100_000, 6),
}

CHILD = r"""
import json, math, sys, time
import numpy as np
from sparsekin import solve_kinematics, testset
family, bodies, steps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
if family == "task5":
    mechanism = testset.task5()
    times = np.linspace(0.0, 10.0, steps + 1)
    solve_kinematics(mechanism, times[:3])  # compiled outside the timing
    start = time.perf_counter()
    result = solve_kinematics(mechanism, times)
    seconds = (time.perf_counter() - start) / times.size
    assert result.complete and result.linear_solver == "compiled", result.linear_solver
    print(json.dumps({"seconds": seconds, "path": result.linear_solver}))
    raise SystemExit
if family == "task5_chain":
    mechanism = testset.task5_chain(max(1, bodies // 10))
else:
    rows = max(1, round(math.sqrt(bodies / 2)))
    mechanism = testset.lattice(rows, max(1, round((bodies / rows - 1) / 2)))
times = 0.01 * np.arange(steps + 1)
warm = testset.task5_chain(2) if family == "task5_chain" else testset.lattice(3, 4)
solve_kinematics(warm, times[:3], linear_solver="refactor")  # compiled outside the timing
stamps = []
start = time.perf_counter()
result = solve_kinematics(mechanism, times, coordinates=False, progress=lambda done, total: stamps.append(time.perf_counter()))
assert result.complete and len(stamps) == times.size
print(json.dumps({"seconds": float(np.median(np.diff(stamps))), "setup": stamps[0] - start,
                  "path": result.linear_solver, "bodies": mechanism.n_bodies}))
"""


def measure(tree: Path, case: str) -> dict:
    family, bodies, steps = CASES[case]
    env = dict(os.environ, PYTHONPATH=str(tree))
    done = subprocess.run([sys.executable, "-c", CHILD, family, str(bodies), str(steps)], env=env, cwd=tree,
                          capture_output=True, text=True, check=True)  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, required=True, help="the other source tree (the baseline)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    arguments = parser.parse_args()
    trees = {"baseline": arguments.against.resolve(), "this": HERE}
    for case in arguments.cases:
        seconds = {name: [] for name in trees}
        setups = {name: [] for name in trees}
        info = {}
        for _ in range(arguments.rounds):
            for name, tree in trees.items():
                outcome = measure(tree, case)
                seconds[name].append(outcome["seconds"])
                setups[name].append(outcome.get("setup", float("nan")))
                info[name] = outcome
        medians = {name: statistics.median(values) for name, values in seconds.items()}
        for name in trees:
            print(f"{case:12s} {name:8s} median {medians[name]:.4g} s per step over {arguments.rounds} rounds "
                  f"(min {min(seconds[name]):.4g}, max {max(seconds[name]):.4g}); setup and first sample: median "
                  f"{statistics.median(setups[name]):.4g} s; path {info[name]['path']}")
        print(f"{case:12s} ratio this/baseline {medians['this'] / medians['baseline']:.3f}", flush=True)
        time.sleep(0)


if __name__ == "__main__":
    main()
