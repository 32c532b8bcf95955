"""The compiled dynamics loop's dense and banded LU, and the Python stepper, per step, same run.

Where `sparsekin.solve.policy.plan_compiled_factorization` switches: for each model, its
saddle size and bandwidths in reverse Cuthill–McKee order, and the time per step of

* ``dense``  — the compiled loop on its dense LU (up to 1500 unknowns),
* ``banded`` — the compiled loop on its banded LU (whatever the band),
* ``python`` — the Python stepper on the "auto" solver (dense LU up to 400 unknowns, the
  sparse refactorization above),

each the difference of two runs from the start (to `--t-end` and to a third of it) over the
steps between (3000 and 1000 compiled, a fifth on the Python stepper), so that the start
(the Python stepper's, common to all) drops out; rounds
alternate the paths, medians.  Models: the IFToMM N-four-bar at several N (`--loops`), A03,
Task 5 with masses, and driven lattices with masses (`--lattices`, rows×cols).

    python3 benchmarks/measure_compiled_band.py [--loops 2 4 8 16 40 400] [--lattices 4x8] \\
        [--rounds 3] [--out benchmarks/compiled_band.jsonl]
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

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DENSE_LIMIT = 1500
#: The lines `--out` appends, for RESULTS.md (`results_section`, `make_results.py`).
COMPILED_BAND = Path(__file__).resolve().with_name("compiled_band.jsonl")
PATHS = ("dense", "banded", "python")


def thresholds(path: str):
    from sparsekin.solve.policy import Thresholds

    if path == "dense":
        return Thresholds(compiled_saddle_max_size=10**6, saddle_dense_max_size=10**6, min_banded_saddle_size=10**9)
    if path == "banded":
        return Thresholds(min_banded_saddle_size=1, max_band_fraction=1.0, max_banded_work=10**12,
                          compiled_banded_max_size=10**9)  # fmt: skip
    return Thresholds(compiled_saddle_max_size=0)


def models(loops, lattices) -> dict:
    import sparsekin as sk
    from sparsekin import testset

    found = {f"N-four-bar N={n}": (testset.n_four_bar(n), 1e-3) for n in loops}
    found["A03"] = (sk.load_model(ROOT / "examples" / "dynamics" / "andrews.toml"), 1e-5)
    found["Task 5"] = (sk.load_model(ROOT / "examples" / "task5_dynamics.toml"), 1e-3)
    for shape in lattices:
        rows, cols = (int(k) for k in shape.split("x"))
        found[f"lattice {shape}"] = (testset.with_masses(testset.lattice(rows, cols), 1.0, 1.0 / 12.0), 1e-3)
    return found


def elapsed(mechanism, step: float, n_steps: int, path: str) -> float:
    from sparsekin.engine.discretization import discretize
    from sparsekin.solve.dynamics import run_dynamics
    from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions

    times = np.linspace(0.0, n_steps * step, 3)
    start = time.perf_counter()
    result = run_dynamics(discretize(mechanism), times, SolveOptions(1e-10, thresholds=thresholds(path)),
                          DynamicsOptions(step), Request(forces=None))  # fmt: skip
    seconds = time.perf_counter() - start
    assert result.complete, path
    return seconds, result.n_steps


def per_step(mechanism, step: float, n_steps: int, path: str) -> float:
    """Seconds per step between a run of `n_steps` and one of a third of them."""
    short, short_steps = elapsed(mechanism, step, n_steps // 3, path)
    long, long_steps = elapsed(mechanism, step, n_steps, path)
    return (long - short) / (long_steps - short_steps)


def measure(loops, lattices, rounds: int, n_steps: int) -> dict:
    from sparsekin.engine.discretization import discretize
    from sparsekin.engine.saddle import DynamicSystem
    from sparsekin.solve._saddle_factorization import saddle_band_order

    rows = {}
    for name, (mechanism, step) in models(loops, lattices).items():
        saddle = DynamicSystem(discretize(mechanism)).saddle
        _, lower, upper = saddle_band_order(saddle.indptr, saddle.indices)
        paths = [path for path in PATHS if path != "dense" or saddle.size <= DENSE_LIMIT]
        for path in paths:
            elapsed(mechanism, step, 3, path)  # compile or load the cache
        timings = {path: [] for path in paths}
        for _ in range(rounds):
            for path in paths:  # the Python stepper's steps are 10-100 times slower: fewer
                timings[path].append(per_step(mechanism, step, n_steps if path != "python" else n_steps // 5, path))
        row = {"size": saddle.size, "lower": lower, "upper": upper, "step": step, "n_steps": n_steps}
        row |= {f"{path}_per_step": statistics.median(values) for path, values in timings.items()}
        row |= {f"{path}_runs": values for path, values in timings.items()}
        rows[name] = row
        shown = ", ".join(f"{path} {row[f'{path}_per_step'] * 1e6:.1f} µs" for path in paths)
        print(f"{name}: {saddle.size} unknowns, bandwidths {lower}/{upper}: {shown}", flush=True)
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loops", type=int, nargs="+", default=[2, 4, 8, 16, 24, 32, 40])
    parser.add_argument("--lattices", nargs="*", default=[])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=3000, help="steps of the compiled loop's long run (Python's: a fifth)")
    parser.add_argument("--out", type=Path, help="append the run as one JSON line")
    arguments = parser.parse_args(argv)
    before = os.getloadavg()[0]
    rows = measure(arguments.loops, arguments.lattices, arguments.rounds, arguments.steps)
    if arguments.out:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], check=False, capture_output=True, text=True,
                                cwd=ROOT).stdout.strip()  # fmt: skip
        line = {"utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "commit": commit,
                "load_average": [before, os.getloadavg()[0]], "rounds": arguments.rounds, "rows": rows}  # fmt: skip
        with arguments.out.open("a") as file:
            file.write(json.dumps(line) + "\n")


def _micro(seconds: float | None) -> str:
    if seconds is None:
        return "—"
    return f"{seconds * 1e3:.3g} ms" if seconds >= 1e-3 else f"{seconds * 1e6:.3g} µs"


def results_section(runs: list[dict]) -> list[str]:
    """benchmarks/RESULTS.md's section (`make_results.py`) from the lines of `COMPILED_BAND`."""
    lines = [
        "## Compiled dynamics loop: dense or banded LU, and the Python stepper (`measure_compiled_band.py`)",
        "",
        "`benchmarks/compiled_band.jsonl` holds the runs of",
        "`python3 benchmarks/measure_compiled_band.py [--loops …] [--lattices …] --out benchmarks/compiled_band.jsonl`",
        "(issue 25, A02 in under 5 s). Per model and step, in one process, rounds alternating, medians:",
        "the compiled loop on its dense LU, on its banded LU (the saddle's unknowns in reverse",
        "Cuthill–McKee order, its bandwidths below/above given), and the Python stepper on the \"auto\"",
        "solver (dense LAPACK up to 400 unknowns, the sparse refactorization above), each the",
        "difference of a run to 3000 steps and one to 1000 over the 2000 between (the Python stepper:",
        "a fifth), so the common start drops out. The machine was loaded (2 cores, load given): the",
        "ratios are what to read. `sparsekin.solve.policy.plan_compiled_factorization`'s thresholds",
        "(`MIN_BANDED_SADDLE_SIZE`, `MAX_BAND_FRACTION`, `MAX_BANDED_WORK`) come from these.",
        "The banded kernels changed between runs: at 0254ef7 the solves ran over the whole band, at",
        "49ce1e6 over each column's reach, from 94baf90 on over the factors' nonzeros (each 1.6–1.8×",
        "faster a solve than the one before; a step of A02 is mostly solves).",
    ]
    for run in runs:
        before, after = run["load_average"]
        lines += ["", f"Run at commit {run['commit']}, {run['utc']} UTC, {run['rounds']} rounds, load average "
                      f"{before:.1f} → {after:.1f}:", "",
                  "| model | unknowns | kl/ku | dense | banded | Python stepper | dense / banded | Python / banded |",
                  "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for name, row in run["rows"].items():
            dense, banded, python = (row.get(f"{path}_per_step") for path in PATHS)
            cells = [name, str(row["size"]), f"{row['lower']}/{row['upper']}", _micro(dense), _micro(banded),
                     _micro(python), f"{dense / banded:.2f}×" if dense else "—",
                     f"{python / banded:.2f}×" if python else "—"]  # fmt: skip
            lines.append("| " + " | ".join(cells) + " |")
    return lines


if __name__ == "__main__":
    main()
