"""Small models per step, same run: sparsekin's compiled loop, its Python stepper, and Exudyn.

Issue 25: "A01, A03 and Task 5 with masses per step within 2× of Exudyn at the same step and
accuracy, same run".  For each model, in rounds that interleave the three (the ratio is what
to quote: absolute times move 2× between runs on this shared machine):

* **time per step** — the whole run (start included) over the steps of Exudyn's `timing`
  measurement (benchmarks/peers/exudyn_models.py: A01 1000 steps of 1 ms, A03 300 of 10 µs,
  Task 5 500 of 1 ms, an output at every step), divided by the steps taken; Exudyn's is its
  ``seconds_per_step_unclocked`` (its whole solve of a fresh system, start-up included,
  divided by the steps), measured in a fresh interpreter;
* **accuracy** — each over the benchmark's horizon against the same reference
  (tests/dynamics_reference.py): A01's point path over 10 s, A03's seven angles at 30 ms
  against the published solution, Task 5's tool point K over 0.5 s against the prescribed
  (kinematic) motion whose inverse-dynamics forces drive the linkage.

"Same accuracy": where Exudyn is less accurate at the same step (A01: its model is a mass point
on a distance constraint), Exudyn also at the step of `EQUAL_ACCURACY_STEP`, timed per
millisecond of motion (its time per step × the steps of a millisecond) beside sparsekin's.

Also the IFToMM A02 (N = 40, 81 bars) over 20 s at 1 ms on sparsekin's "auto" path, against
Exudyn's same run (``accuracy a02 --step 1e-3``).

    python3 benchmarks/measure_small_dynamics.py [--rounds 3] [--skip-a02] [--json PATH] [--out JSONL]

``--out benchmarks/small_dynamics.jsonl`` appends the run (commit, UTC time, load) as one line:
benchmarks/RESULTS.md's section (`results_section`, `make_results.py`) is made from those lines.

Exudyn is the optional extra ``peers``; without it the Exudyn columns are left out.
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
#: model: (Exudyn's name, step, steps timed, accuracy horizon, output interval of the accuracy run)
MODELS = {
    "A01": ("a01", 1e-3, 1000, 10.0, 0.01),
    "A03": ("a03", 1e-5, 300, 0.03, 1e-3),
    "Task 5": ("task5", 1e-3, 500, 0.5, 1e-3),
}
#: Exudyn's step at which its error is at most sparsekin's at the step of `MODELS` (A01:
#: 2.9e-5 m at 0.5 ms against sparsekin's 2.35e-5 m at 1 ms; benchmarks/peers/README.md).
EQUAL_ACCURACY_STEP = {"A01": 5e-4}
#: The lines `--out` appends, for RESULTS.md.
SMALL_DYNAMICS = Path(__file__).resolve().with_name("small_dynamics.jsonl")


def _reference():
    sys.path.insert(0, str(ROOT / "tests"))
    import dynamics_reference

    return dynamics_reference


def models() -> dict:
    import sparsekin as sk

    sys.path.insert(0, str(ROOT / "tests"))
    from helpers import actuator_round_trip

    task5, kinematic = actuator_round_trip(0.5, 1e-3)  # Exudyn's horizon and force sampling
    return {
        "A01": (sk.load_model(ROOT / "examples" / "dynamics" / "pendulum.toml"), None),
        "A03": (sk.load_model(ROOT / "examples" / "dynamics" / "andrews.toml"), None),
        "Task 5": (task5, kinematic),
    }


def run(mechanism, times, step, path: str, **request):
    """`run_dynamics` on the compiled loop or the Python stepper (the solver plan's thresholds)."""
    from sparsekin.engine.discretization import discretize
    from sparsekin.solve.dynamics import run_dynamics
    from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions
    from sparsekin.solve.policy import Thresholds

    thresholds = Thresholds() if path == "compiled" else Thresholds(compiled_saddle_max_size=0)
    return run_dynamics(discretize(mechanism), np.asarray(times, dtype=float), SolveOptions(1e-10, thresholds=thresholds),
                        DynamicsOptions(step), Request(energy=True, **request))  # fmt: skip


def error(name: str, result, kinematic) -> float:
    """The benchmark's error of a run over its horizon (m or rad)."""
    reference = _reference()
    if name == "A01":
        exact, _ = reference.pendulum_point(result.times)
        return float(np.abs(result.point("P").position - exact).max())
    if name == "A03":
        angles = reference.andrews_angles_from_bodies(result.coordinates[-1, 2::3])
        return float(np.abs(angles - reference.ANDREWS_REFERENCE_ANGLES).max())
    return float(np.abs(result.point("K").position - kinematic.point("K").position).max())


def per_step(mechanism, step: float, n_steps: int, path: str) -> float:
    """Seconds per step of a run of `n_steps` steps with an output at every one."""
    times = np.linspace(0.0, n_steps * step, n_steps + 1)
    start = time.perf_counter()
    result = run(mechanism, times, step, path)
    seconds = time.perf_counter() - start
    assert result.complete and result.n_steps == n_steps, (result.complete, result.n_steps)
    return seconds / n_steps


def measure(rounds: int, a02: bool, with_exudyn: bool) -> dict:
    if with_exudyn:
        sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))
        from exudyn_models import in_subprocess
    rows = {}
    for name, (mechanism, kinematic) in models().items():
        peer, step, n_steps, horizon, interval = MODELS[name]
        times = np.linspace(0.0, horizon, int(round(horizon / interval)) + 1)
        row = {"step": step, "n_steps": n_steps}
        for path in ("compiled", "python"):
            per_step(mechanism, step, 2, path)  # compile or load the cache
            row[f"{path}_error"] = error(name, run(mechanism, times, step, path, points="all"), kinematic)
        timings = {"compiled": [], "python": [], "exudyn": [], "exudyn_equal_accuracy": []}
        equal = EQUAL_ACCURACY_STEP.get(name) if with_exudyn else None
        for _ in range(rounds):  # interleaved
            for path in ("compiled", "python"):
                timings[path].append(per_step(mechanism, step, n_steps, path))
            if with_exudyn:
                measured = in_subprocess("timing", peer, "--steps", str(n_steps), "--step", f"{step:g}", "--repeat", "1")
                timings["exudyn"].append(measured["seconds_per_step_unclocked"])
            if equal:  # the same motion in steps of `equal`: its time per step of `step`
                steps = int(round(n_steps * step / equal))
                measured = in_subprocess("timing", peer, "--steps", str(steps), "--step", f"{equal:g}", "--repeat", "1")
                timings["exudyn_equal_accuracy"].append(measured["seconds_per_step_unclocked"] * step / equal)
        if with_exudyn:
            accuracy = in_subprocess("accuracy", peer, "--step", f"{step:g}")
            row["exudyn_error"] = accuracy.get("path_error_m", accuracy.get("angle_error_rad"))
        if equal:
            accuracy = in_subprocess("accuracy", peer, "--step", f"{equal:g}")
            row["exudyn_equal_accuracy_step"] = equal
            row["exudyn_equal_accuracy_error"] = accuracy.get("path_error_m", accuracy.get("angle_error_rad"))
        for path, values in timings.items():
            if values:
                row[f"{path}_per_step"] = statistics.median(values)
                row[f"{path}_runs"] = values
        rows[name] = row
        print(name, json.dumps(row), flush=True)
    if a02:
        rows["A02"] = measure_a02(with_exudyn)
        print("A02", json.dumps(rows["A02"]), flush=True)
    return rows


def measure_a02(with_exudyn: bool) -> dict:
    """The IFToMM A02 (N = 40) over 20 s at 1 ms: sparsekin's "auto" path (the whole run,
    start included) and Exudyn's same run, with B0's errors."""
    import sparsekin as sk
    from sparsekin.testset import n_four_bar

    reference = _reference()
    mechanism = n_four_bar(40)
    times = np.linspace(0.0, 20.0, 401)
    sk.solve_dynamics(mechanism, times[:2], max_step=1e-3, forces=None)  # compile or load the cache
    start = time.perf_counter()
    result = sk.solve_dynamics(mechanism, times, max_step=1e-3, forces=None, points=["B0"])
    row = {"seconds": time.perf_counter() - start, "linear_solver": result.linear_solver, "n_steps": result.n_steps,
           "compiled_lu": _compiled_lu(mechanism)}  # fmt: skip
    position, velocity = reference.n_four_bar_b0(result.times)
    row["position_error_m"] = float(np.abs(result.point("B0").position - position).max())
    row["velocity_error_m_s"] = float(np.abs(result.point("B0").velocity - velocity).max())
    if with_exudyn:
        sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))
        from exudyn_models import in_subprocess

        peer = in_subprocess("accuracy", "a02", "--step", "1e-3")
        row["exudyn"] = {key: peer.get(key) for key in ("seconds", "finished", "position_error_m", "velocity_error_m_s")}
    return row


def _compiled_lu(mechanism) -> str | None:
    """The compiled loop's LU of `mechanism` under ``"auto"`` (``"dense"``, ``"banded"``),
    None when the Python stepper runs it."""
    from sparsekin.engine.discretization import discretize
    from sparsekin.engine.saddle import DynamicSystem
    from sparsekin.solve._saddle_factorization import saddle_band_order
    from sparsekin.solve.policy import plan_compiled_factorization

    saddle = DynamicSystem(discretize(mechanism)).saddle
    _, lower, upper = saddle_band_order(saddle.indptr, saddle.indices)
    return plan_compiled_factorization(saddle.size, lower, upper)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--skip-a02", action="store_true")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--out", type=Path, help="append the run as one JSON line (benchmarks/small_dynamics.jsonl)")
    arguments = parser.parse_args(argv)
    try:
        import exudyn  # noqa: F401

        with_exudyn = True
    except ImportError:
        print("exudyn is not installed (the `peers` extra): sparsekin only", file=sys.stderr)
        with_exudyn = False
    before = os.getloadavg()[0]
    rows = measure(arguments.rounds, not arguments.skip_a02, with_exudyn)
    rows["load_average"] = os.getloadavg()
    if arguments.json:
        arguments.json.write_text(json.dumps(rows, indent=1) + "\n")
    if arguments.out:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], check=False, capture_output=True, text=True,
                                cwd=ROOT).stdout.strip()  # fmt: skip
        line = {"utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "commit": commit,
                "load_average": [before, rows.pop("load_average")[0]], "rounds": arguments.rounds, "rows": rows}
        with arguments.out.open("a") as file:
            file.write(json.dumps(line) + "\n")


def _micro(seconds: float | None) -> str:
    return "—" if seconds is None else f"{seconds * 1e6:.3g} µs"


#: The unit of each model's error (`error`).
ERROR_UNIT = {"A01": "m", "A03": "rad", "Task 5": "m"}


def results_section(runs: list[dict]) -> list[str]:
    """benchmarks/RESULTS.md's section (`make_results.py`) from the lines of `SMALL_DYNAMICS`."""
    lines = [
        "## Forward dynamics of small models: compiled loop, Python stepper, Exudyn (`measure_small_dynamics.py`)",
        "",
        "Not part of the pytest-benchmark run: `benchmarks/small_dynamics.jsonl` holds the runs of",
        "`python3 benchmarks/measure_small_dynamics.py --rounds 5 [--skip-a02] --out benchmarks/small_dynamics.jsonl`",
        "(issue 25). Per model, in one process: sparsekin's compiled block stepper",
        "(`sparsekin.solve._compiled_dynamics`, the default of `solve_dynamics` for these models), its",
        "Python stepper (`Thresholds(compiled_saddle_max_size=0)`) and Exudyn 1.13.6",
        "(`benchmarks/peers/exudyn_models.py timing … --repeat 1` in a fresh interpreter), interleaved",
        "rounds, medians. Time per step: the whole run (start included) with an output at every step,",
        "divided by the steps (A01 1000 of 1 ms, A03 300 of 10 µs, Task 5 500 of 1 ms); Exudyn's is its",
        "whole solve of a fresh system divided by the steps (`seconds_per_step_unclocked`). Error: over",
        "the benchmark's horizon against tests/dynamics_reference.py (A01 path over 10 s, A03 angles at",
        "30 ms, Task 5 round trip: the tool point K over 0.5 s against the prescribed motion). Equal",
        "accuracy: Exudyn at a shorter step where it is less accurate at the same one (its time for the",
        "same motion per sparsekin step).",
    ]
    for run in runs:
        lines += ["", f"Run at commit {run['commit']}, {run['utc']} UTC, {run['rounds']} rounds, load average "
                      f"{run['load_average'][0]:.1f} → {run['load_average'][1]:.1f} (2 cores shared by six sessions):",
                  "",
                  "| model | step | compiled | Python stepper | Exudyn | compiled / Exudyn | error compiled | error Exudyn "
                  "| Exudyn at equal accuracy | compiled / that |",
                  "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for name, row in run["rows"].items():
            if name == "A02":
                continue
            exudyn = row.get("exudyn_per_step")
            ratio = f"{row['compiled_per_step'] / exudyn:.2f}×" if exudyn else "—"
            equal, equal_cells = row.get("exudyn_equal_accuracy_per_step"), ["same step", ratio]
            if equal:
                equal_cells = [f"{_micro(equal)} ({row['exudyn_equal_accuracy_step'] * 1e3:g} ms steps, "
                               f"{row['exudyn_equal_accuracy_error']:.3g} {ERROR_UNIT.get(name, '')})",
                               f"{row['compiled_per_step'] / equal:.2f}×"]  # fmt: skip
            unit, step = ERROR_UNIT.get(name, ""), row["step"]
            cells = [f"{name} ({row['n_steps']} steps)", f"{step * 1e3:g} ms" if step >= 1e-3 else f"{step * 1e6:g} µs",
                     _micro(row["compiled_per_step"]), _micro(row.get("python_per_step")), _micro(exudyn), ratio,
                     f"{row['compiled_error']:.3g} {unit}", f"{row['exudyn_error']:.3g} {unit}" if "exudyn_error" in row
                     else "—", *equal_cells]  # fmt: skip
            lines.append("| " + " | ".join(cells) + " |")
        a02 = run["rows"].get("A02")
        if a02:
            peer = a02.get("exudyn") or {}
            exudyn = f"; Exudyn's same run {peer['seconds']:.3g} s" if peer.get("seconds") else ""
            path = (f"the compiled loop on its {a02['compiled_lu']} LU, the start on {a02['linear_solver']}"
                    if a02.get("compiled_lu") else a02["linear_solver"])  # fmt: skip
            lines += ["", f"A02, N = 40 (81 bars), 20 s at 1 ms, `solve_dynamics` (\"auto\": {path}): "
                          f"{a02['seconds']:.3g} s{exudyn}; B0 within {a02['position_error_m']:.2g} m and "
                          f"{a02['velocity_error_m_s']:.2g} m/s of the exact answer."]  # fmt: skip
    lines += [
        "",
        "Where the compiled dense loop pays (`n_four_bar(N)`, 0.5 s at 1 ms, medians of 3, per step;",
        "commit 1a49687, load 4.5–6.7, before the loop lost its reference counts): saddle size 29:",
        "compiled 72 µs, Python dense 387 µs, Python refactor 359 µs; 65: 93, 392, 347 µs; 125: 169,",
        "424, 262 µs; 245: 657, 8056, 879 µs; 365: 1511, 9088, 1428 µs. Hence",
        "`COMPILED_SADDLE_MAX_SIZE = 400`, the dense range of the saddle plan. Chains from 50 unknowns",
        "on (A02 among them) take the compiled loop's banded LU instead: \"Compiled dynamics loop: dense",
        "or banded LU\" below.",
    ]
    return lines


if __name__ == "__main__":
    main()
