"""Forward dynamics of lattices per step: the saddle matrix's solvers, and the kinematics of the same lattice.

Issue 29's dynamics item (issue 25's struck metamaterial at scale).  Models (`MODELS`), each
built from the benchmark family ``lattice`` (`families.build`) or the test set:

* ``lattice`` — the test set's lattice, its rows driven (no degree of freedom), bars of
  1 kg and 1/12 kg·m² under gravity (`testset.with_masses`): the saddle of a square
  Jacobian; its kinematic twin is the same model;
* ``free`` — the same lattice with its drivers taken out (one degree of freedom a row,
  its shear), every bar given 1 m/s along x (made consistent by the smallest
  mass-weighted change), under gravity;
* ``squares`` — the rotating squares (n × n, their driver kept), squares of 1 kg and
  1/6 kg·m² under gravity: (n − 2)² redundant equations left out of the saddle.

Paths (`PATHS`): ``superlu`` (``"auto"`` now above `MIN_MESH_SADDLE_SIZE`: a fresh SuperLU,
COLAMD, at every factorization, as ``linear_solver="superlu"``), ``dissection``
(`DissectionSolver` on the saddle, SuperLU's own solves: ``Thresholds(mesh_saddle_solver=
"dissection")``), ``refactor`` (``"auto"`` before: `RefactorSolver`, COLAMD) and
``kinematic`` (`KinematicStepper` on the same model, ``"auto"``; driven models only).  One fresh process per path and round, the paths
alternating: the time from nothing to the first sample (pattern, redundancy, solver, the
consistent start), the first step, then `--steps` steps of 1 ms, each timed (median and
mean: modified Newton refactors on some steps only), the factorizations, solves and Newton
corrections of those steps, the saddle's entries and its factors' (``nnz_factors``), and
the process's peak resident memory.  Commands::

    python3 benchmarks/measure_lattice_dynamics.py table lattice 10000 100000 --rounds 2
    python3 benchmarks/measure_lattice_dynamics.py one free dissection --bodies 100000 --steps 5

``table --out FILE`` appends its lines (with the load average and the commit) to FILE
(benchmarks/lattice_dynamics.jsonl, which make_results.py turns into RESULTS.md's section).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "benchmarks"), str(ROOT)]

STEP = 1e-3
PATHS = ("superlu", "dissection", "refactor", "kinematic")
#: The lines `table --out` wrote for RESULTS.md.
LATTICE_DYNAMICS = Path(__file__).resolve().with_name("lattice_dynamics.jsonl")


def _lattice(bodies: int):
    from families import build

    from sparsekin import testset

    return testset.with_masses(build("lattice", bodies), 1.0, 1.0 / 12.0)


def _free(bodies: int):
    """The driven lattice without its drivers, every bar at 1 m/s along x."""
    from families import build

    from sparsekin import testset

    lattice = build("lattice", bodies)
    repeat = lattice.repeats[0]
    unit = dataclasses.replace(repeat.unit, drivers=(),
                               only={key: value for key, value in repeat.unit.only.items() if key[0] != "drivers"})  # fmt: skip
    free = dataclasses.replace(lattice, repeats=(dataclasses.replace(repeat, unit=unit, vary={}),))
    return testset.with_masses(free, 1.0, 1.0 / 12.0, velocity=(1.0, 0.0, 0.0))


def _squares(bodies: int):
    from sparsekin import testset

    return testset.with_masses(testset.rotating_squares(max(3, round(math.sqrt(bodies)))), 1.0, 1.0 / 6.0)


#: Model name → builder from an approximate number of bodies.
MODELS = {"lattice": _lattice, "free": _free, "squares": _squares}
#: Models with drivers (no degree of freedom): their kinematics is the same model's.
DRIVEN = ("lattice", "squares")


def peak_rss_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def measure(model: str, path: str, bodies: int, steps: int) -> dict:
    """One path on one model in this process (`PATHS`)."""
    from sparsekin.solve.options import SolveOptions
    from sparsekin.solve.policy import Thresholds

    mechanism = MODELS[model](bodies)
    start = time.perf_counter()
    if path == "kinematic":
        from sparsekin.solve.stepper import KinematicStepper

        stepper = KinematicStepper(mechanism)
    else:
        from sparsekin.solve.dynamics import GeneralizedAlphaStepper

        before = SolveOptions(thresholds=Thresholds(min_mesh_saddle_size=2**62))  # "auto" before: the refactorization
        dissection = SolveOptions(thresholds=Thresholds(mesh_saddle_solver="dissection"))
        options = {"dissection": dissection, "refactor": before, "superlu": SolveOptions()}
        stepper = GeneralizedAlphaStepper(mechanism, STEP, options=options[path])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the squares' redundant equations
        stepper.start(0.0)
    start_s = time.perf_counter() - start
    clock = time.perf_counter()
    stepper.advance(STEP)
    first_step_s = time.perf_counter() - clock
    solver = stepper.solver if path != "kinematic" else None
    counts = _counts(stepper)
    times = []
    for k in range(2, steps + 2):
        clock = time.perf_counter()
        stepper.advance(k * STEP)
        times.append(time.perf_counter() - clock)
    after = _counts(stepper)
    row = {"model": model, "path": path, "bodies": mechanism.n_bodies, "taken": stepper.path, "steps": steps,
           "start_s": start_s, "first_step_s": first_step_s, "step_median_s": statistics.median(times),
           "step_mean_s": statistics.fmean(times), "steps_s": times,
           **{f"{name}_per_step": (after[name] - counts[name]) / steps for name in after},
           "peak_rss_bytes": peak_rss_bytes()}  # fmt: skip
    if solver is not None:
        row |= {"saddle_size": stepper.system.size, "saddle_nnz": int(stepper.system.matrix.nnz),
                "redundant": int(stepper.redundant_rows.size)}  # fmt: skip
        if hasattr(solver, "nnz_factors"):
            row["nnz_factors"] = int(solver.nnz_factors)
    return row


def _counts(stepper) -> dict:
    stats = stepper.stats()
    counts = {"factorizations": stats.n_factorizations + stats.n_refactorizations, "solves": stats.n_solves}
    if hasattr(stepper, "n_newton"):
        counts["newton"] = stepper.n_newton
    return counts


def in_subprocess(model: str, path: str, bodies: int, steps: int) -> dict:
    """`measure` in a fresh interpreter (its peak memory its own), with the load and commit."""
    command = [sys.executable, "-W", "ignore", __file__, "one", model, path, "--bodies", str(bodies),
               "--steps", str(steps)]  # fmt: skip
    output = subprocess.run(command, check=True, capture_output=True, text=True, cwd=ROOT,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})  # fmt: skip
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], check=False, capture_output=True, text=True,
                            cwd=ROOT).stdout.strip()  # fmt: skip
    return {**json.loads(output.stdout.strip().splitlines()[-1]), "load_average": os.getloadavg()[0],
            "utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "commit": commit}  # fmt: skip


def table(model: str, sizes: list[int], paths: list[str], rounds: int, steps: int) -> list[dict]:
    """Every size, the paths alternating within each of `rounds` rounds."""
    paths = [path for path in paths if path != "kinematic" or model in DRIVEN]
    rows = []
    for bodies in sizes:
        for round_ in range(rounds):
            for path in paths if round_ % 2 == 0 else paths[::-1]:
                rows.append({**in_subprocess(model, path, bodies, steps), "round": round_})
                print(json.dumps(rows[-1]), flush=True)
    return rows


def markdown(rows: list[dict]) -> str:
    """Medians over the rounds per model, size and path, with the ratios to ``superlu``'s (``"auto"``)."""
    header = ("| model | bodies | path | saddle size | first sample | first step | per step (median) | "
              "÷ superlu's step | factorizations a step | L + U entries | peak | runs (load) |")  # fmt: skip
    lines = [header, "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    keys = sorted({(row["model"], row["bodies"]) for row in rows})
    for model, bodies in keys:
        group = [row for row in rows if row["model"] == model and row["bodies"] == bodies]
        by_path = {}
        for row in group:
            by_path.setdefault(row["path"], []).append(row)
        reference = by_path.get("superlu")
        reference_step = statistics.median(r["step_median_s"] for r in reference) if reference else None
        for path in PATHS:
            if path not in by_path:
                continue
            runs = by_path[path]
            step = statistics.median(r["step_median_s"] for r in runs)
            cells = [model, str(bodies), f"{path} ({runs[0]['taken']})", str(runs[0].get("saddle_size", "")),
                     _seconds(statistics.median(r["start_s"] for r in runs)),
                     _seconds(statistics.median(r["first_step_s"] for r in runs)), _seconds(step),
                     f"{step / reference_step:.2f}×" if reference_step else "",
                     f"{statistics.median(r['factorizations_per_step'] for r in runs):.2f}",
                     f"{runs[0]['nnz_factors'] / 1e6:.1f} M" if "nnz_factors" in runs[0] else "",
                     f"{max(r['peak_rss_bytes'] for r in runs) / 2**30:.2f} GB",
                     ", ".join(f"{r['utc'][11:]} ({r['load_average']:.1f})" for r in runs)]  # fmt: skip
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _seconds(value: float) -> str:
    return f"{value:.3g} s" if value >= 1.0 else f"{value * 1e3:.3g} ms"


def results_section(rows: list[dict]) -> list[str]:
    """benchmarks/RESULTS.md's section (`make_results.py`) from the lines of `LATTICE_DYNAMICS`."""
    return [
        "## Forward dynamics of lattices (issue 29's dynamics item; `measure_lattice_dynamics.py`)",
        "",
        "Not part of the pytest-benchmark run: `benchmarks/lattice_dynamics.jsonl` holds the lines of",
        "`python3 benchmarks/measure_lattice_dynamics.py table MODEL SIZES --rounds R --out",
        "benchmarks/lattice_dynamics.jsonl`. One fresh process per path and round, the paths alternating",
        "(medians over the rounds below; each run's time and load average in the last column). `superlu`:",
        "``\"auto\"`` now (a fresh SuperLU, COLAMD, at every factorization of the saddle); `dissection`:",
        "`DissectionSolver` on the saddle (the bodies' unknowns in the geometric nested dissection, SuperLU's",
        "own solves); `refactor`: ``\"auto\"`` before (`RefactorSolver`, COLAMD); `kinematic`: the",
        "kinematics of the same (driven) model. Steps of 1 ms; first sample: pattern, redundancy analysis,",
        "solver and consistent start; per step: median of the timed steps after the first. Lines of commit",
        "8c7874f (lattice 3003, free 10^5 superlu and refactor) ran `superlu` as ``linear_solver=\"superlu\"``,",
        "the same solver; each line names its commit.",
        "",
        *markdown(rows).splitlines(),
    ]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    one = commands.add_parser("one", help="one measurement in this process")
    one.add_argument("model", choices=tuple(MODELS))
    one.add_argument("path", choices=PATHS)
    one.add_argument("--bodies", type=int, default=10_000)
    one.add_argument("--steps", type=int, default=5)
    many = commands.add_parser("table", help="sizes × paths × rounds, each in a fresh process")
    many.add_argument("model", choices=tuple(MODELS))
    many.add_argument("sizes", type=int, nargs="+")
    many.add_argument("--paths", nargs="+", choices=PATHS, default=list(PATHS))
    many.add_argument("--rounds", type=int, default=2)
    many.add_argument("--steps", type=int, default=5)
    many.add_argument("--out", type=Path, help="append the lines to this file")
    arguments = parser.parse_args(argv)
    if arguments.command == "one":
        print(json.dumps(measure(arguments.model, arguments.path, arguments.bodies, arguments.steps)), flush=True)
        return
    rows = table(arguments.model, arguments.sizes, arguments.paths, arguments.rounds, arguments.steps)
    if arguments.out is not None:
        with arguments.out.open("a", encoding="utf-8") as out:
            out.writelines(json.dumps(row) + "\n" for row in rows)
    print(markdown(rows))


if __name__ == "__main__":
    main()
