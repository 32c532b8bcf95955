"""Work–precision of forward dynamics on Andrews' squeezing mechanism (IFToMM A03), beside Exudyn.

The error is the largest of the seven angles at t = 0.03 s against the Test Set's published
reference (tests/dynamics_reference.py); the work is the wall time of the solve.  Series:

* ``sparsekin fixed``: `solve_dynamics` at fixed steps h (the compiled small-model loop);
* ``sparsekin fixed (Python)``: the same steps on the Python stepper, the path of models
  the compiled loop does not take;
* ``sparsekin rtol``: error-controlled steps (`rtol`, largest step `RTOL_MAX_STEP`; the
  compiled loop since branch c25rtolc, the Python stepper before);
* ``Exudyn fixed``: Exudyn 1.13.6's generalized-α (index 3, ρ∞ 0.9, modified Newton,
  EigenSparse) at fixed steps, each in a fresh interpreter (benchmarks/peers/exudyn_models.py,
  its ``seconds``: ``SolveDynamic`` alone).  Exudyn's implicit solver has no error control:
  its "adaptive" step only reduces the step after a Newton failure, which does not happen
  here, so its adaptive runs are its fixed ones.

sparsekin runs in this process after one warm-up run of each path (the kernels compiled and
cached); a run's time is the median of `REPEATS` runs (one run above 2 s).  The load average
is recorded beside each line: only the ratios within one run mean anything on a shared machine.

Commands (from the repository root)::

    python3 benchmarks/measure_andrews_work_precision.py run      # writes ANDREWS_WORK_PRECISION (~5 min)
    python3 benchmarks/measure_andrews_work_precision.py figure   # docs/images/andrews_work_precision.png

``make_results.py`` puts the table (`results_section`) in RESULTS.md.
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

ROOT = Path(__file__).resolve().parents[1]
#: The lines `run` writes and `figure` and RESULTS.md read.
ANDREWS_WORK_PRECISION = Path(__file__).resolve().with_name("andrews_work_precision.jsonl")
FIGURE = ROOT / "docs" / "images" / "andrews_work_precision.png"
FIXED_STEPS = (4e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6)
PYTHON_FIXED_STEPS = (1e-5, 5e-6, 2e-6)
RTOLS = (1e-7, 1e-8, 1e-9, 1e-10, 1e-11)
RTOL_MAX_STEP = 1e-4
EXUDYN_STEPS = (4e-5, 2e-5, 1e-5, 5e-6, 2.5e-6, 1.25e-6)
REPEATS = 3
#: The issue's target: the seven angles within 1e-6 rad.
TARGET = 1e-6


def sparsekin_run(mechanism, h: float, rtol: float | None = None, python: bool = False) -> dict:
    """One `solve_dynamics` to 0.03 s (median time of `REPEATS` runs, one above 2 s)."""
    import numpy as np
    from dynamics_reference import ANDREWS_REFERENCE_ANGLES, andrews_angles_from_bodies

    import sparsekin as sk
    from sparsekin.engine.discretization import discretize
    from sparsekin.solve.dynamics import MAX_ITERATIONS, run_dynamics
    from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions
    from sparsekin.solve.policy import Thresholds

    times = np.array([0.0, 0.03])

    def solve():
        if not python:
            return sk.solve_dynamics(mechanism, times, max_step=h, rtol=rtol, forces=None)
        options = SolveOptions(1e-10, MAX_ITERATIONS, "dense", Thresholds(compiled_saddle_max_size=0))
        return run_dynamics(discretize(mechanism), times, options, DynamicsOptions(h, 0.9, rtol), Request(energy=True))

    seconds = []
    while len(seconds) < REPEATS and sum(seconds) < 2.0:
        start = time.perf_counter()
        result = solve()
        seconds.append(time.perf_counter() - start)
    error = np.abs(andrews_angles_from_bodies(result.coordinates[-1, 2::3]) - ANDREWS_REFERENCE_ANGLES).max()
    series = "sparsekin rtol" if rtol is not None else "sparsekin fixed (Python)" if python else "sparsekin fixed"
    return {"series": series, "step": h, "rtol": rtol, "error_rad": float(error), "seconds": statistics.median(seconds),
            "steps": int(result.n_steps), "newton": int(np.sum(result.newton_iterations)),
            "load_average": os.getloadavg()[0]}  # fmt: skip


def exudyn_run(h: float) -> dict:
    """Exudyn at fixed step `h` in a fresh interpreter."""
    sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))
    from exudyn_models import in_subprocess

    line = in_subprocess("accuracy", "a03", "--step", repr(h), "--fixed")
    return {"series": "Exudyn fixed", "step": h, "rtol": None, "error_rad": line["angle_error_rad"],
            "seconds": line["seconds"], "steps": round(0.03 / h), "finished": line["finished"],
            "exudyn": line["exudyn"], "load_average": line["load_average"]}  # fmt: skip


def run(path: Path) -> None:
    """Every series, one line each as it is measured, into `path`."""
    sys.path.insert(0, str(ROOT / "tests"))
    import sparsekin as sk

    mechanism = sk.load_model(ROOT / "examples" / "dynamics" / "andrews.toml")
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout
    sparsekin_run(mechanism, 1e-4)  # warm-up: the compiled loop and the Python stepper's kernels
    sparsekin_run(mechanism, 1e-4, rtol=1e-6)
    lines = [*(lambda h=h: sparsekin_run(mechanism, h) for h in FIXED_STEPS),
             *(lambda h=h: sparsekin_run(mechanism, h, python=True) for h in PYTHON_FIXED_STEPS),
             *(lambda r=r: sparsekin_run(mechanism, RTOL_MAX_STEP, rtol=r) for r in RTOLS),
             *(lambda h=h: exudyn_run(h) for h in EXUDYN_STEPS)]  # fmt: skip
    with path.open("w") as out:
        for measure in lines:
            line = {**measure(), "commit": commit.strip()}
            print(json.dumps(line), flush=True)
            out.write(json.dumps(line) + "\n")
            out.flush()


def read(path: Path = ANDREWS_WORK_PRECISION) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def figure(path: Path, target: Path) -> None:
    """Error against wall time, one line per series, log–log, the 1e-6 rad target dashed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise SystemExit('the figure needs matplotlib: pip install "sparsekin[plot]"') from None
    rows = read(path)
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    styles = {"sparsekin fixed": "o-", "sparsekin fixed (Python)": "s:", "sparsekin rtol": "D-", "Exudyn fixed": "^--"}
    for series, style in styles.items():
        points = sorted((row["seconds"], row["error_rad"], row) for row in rows if row["series"] == series)
        if not points:
            continue
        ax.loglog([p[0] for p in points], [p[1] for p in points], style, label=series)
        for seconds, error, row in points:
            label = f"{row['rtol']:.0e}" if row["rtol"] is not None else f"{row['step'] * 1e6:g} µs"
            ax.annotate(label, (seconds, error), textcoords="offset points", xytext=(4, 3), fontsize=7)
    ax.axhline(TARGET, color="grey", lw=0.8, ls="--")
    ax.text(ax.get_xlim()[0], TARGET, " 1e-6 rad", va="bottom", fontsize=8, color="grey")
    loads = [row["load_average"] for row in rows]
    ax.set_xlabel("wall time of the solve, s")
    ax.set_ylabel("largest angle error at t = 0.03 s, rad")
    ax.set_title(f"Andrews' squeezing mechanism (A03), load {min(loads):.1f}–{max(loads):.1f} on 2 cores", fontsize=9)
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    target.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(target, dpi=110)
    print(f"wrote {target}")


def results_section(rows: list[dict]) -> list[str]:
    """benchmarks/RESULTS.md's section (`make_results.py`) from the lines of `ANDREWS_WORK_PRECISION`."""
    loads = [row["load_average"] for row in rows]
    commits = sorted({row.get("commit", "?") for row in rows})
    lines = [
        "## Forward dynamics: work–precision on Andrews' mechanism (issue 25; `measure_andrews_work_precision.py`)",
        "",
        "Not part of the pytest-benchmark run: `benchmarks/andrews_work_precision.jsonl` holds the lines of",
        "`python3 benchmarks/measure_andrews_work_precision.py run` (commit " + ", ".join(commits) + ", load "
        f"{min(loads):.1f}–{max(loads):.1f} on 2 cores). Error: the largest of the seven angles at t = 0.03 s against",
        "the Test Set's reference; time: the solve's wall time (median of up to 3 runs; Exudyn's `SolveDynamic`",
        "in a fresh interpreter); per step: wall time over steps, the solve's start and recording included. The",
        "figure is docs/images/andrews_work_precision.png; the reading of it is in",
        "docs/design-notes.md (error-controlled steps).",
        "",
        "| series | step or rtol | steps | error, rad | wall time | time per step |",
        "|---|---|---|---|---|---|",
    ]
    for row in rows:
        setting = f"rtol {row['rtol']:g} (≤ {row['step']:g} s)" if row["rtol"] is not None else f"h = {row['step']:g} s"
        per_step = row["seconds"] / row["steps"]
        per_step = f"{per_step * 1e3:.3g} ms" if per_step >= 1e-3 else f"{per_step * 1e6:.3g} µs"
        lines.append(f"| {row['series']} | {setting} | {row['steps']} | {row['error_rad']:.2e} | {row['seconds']:.3g} s "
                     f"| {per_step} |")  # fmt: skip
    return lines


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("run", help="measure every series (sparsekin here, Exudyn in subprocesses)").add_argument(
        "--out", type=Path, default=ANDREWS_WORK_PRECISION)
    draw = commands.add_parser("figure", help="the work-precision figure from the lines")
    draw.add_argument("--lines", type=Path, default=ANDREWS_WORK_PRECISION)
    draw.add_argument("--out", type=Path, default=FIGURE)
    arguments = parser.parse_args(argv)
    if arguments.command == "run":
        run(arguments.out)
    else:
        figure(arguments.lines, arguments.out)


if __name__ == "__main__":
    main()
