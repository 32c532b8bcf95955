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

Also the IFToMM A02 (N = 40, 81 bars) over 20 s at 1 ms on sparsekin's "auto" path, against
Exudyn's same run (``accuracy a02 --step 1e-3``).

    python3 benchmarks/measure_small_dynamics.py [--rounds 3] [--skip-a02] [--json PATH]

Exudyn is the optional extra ``peers``; without it the Exudyn columns are left out.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
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
        timings = {"compiled": [], "python": [], "exudyn": []}
        for _ in range(rounds):  # interleaved
            for path in ("compiled", "python"):
                timings[path].append(per_step(mechanism, step, n_steps, path))
            if with_exudyn:
                measured = in_subprocess("timing", peer, "--steps", str(n_steps), "--step", f"{step:g}", "--repeat", "1")
                timings["exudyn"].append(measured["seconds_per_step_unclocked"])
        if with_exudyn:
            accuracy = in_subprocess("accuracy", peer, "--step", f"{step:g}")
            row["exudyn_error"] = accuracy.get("path_error_m", accuracy.get("angle_error_rad"))
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
    row = {"seconds": time.perf_counter() - start, "linear_solver": result.linear_solver, "n_steps": result.n_steps}
    position, velocity = reference.n_four_bar_b0(result.times)
    row["position_error_m"] = float(np.abs(result.point("B0").position - position).max())
    row["velocity_error_m_s"] = float(np.abs(result.point("B0").velocity - velocity).max())
    if with_exudyn:
        sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))
        from exudyn_models import in_subprocess

        peer = in_subprocess("accuracy", "a02", "--step", "1e-3")
        row["exudyn"] = {key: peer.get(key) for key in ("seconds", "finished", "position_error_m", "velocity_error_m_s")}
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--skip-a02", action="store_true")
    parser.add_argument("--json", type=Path)
    arguments = parser.parse_args(argv)
    try:
        import exudyn  # noqa: F401

        with_exudyn = True
    except ImportError:
        print("exudyn is not installed (the `peers` extra): sparsekin only", file=sys.stderr)
        with_exudyn = False
    rows = measure(arguments.rounds, not arguments.skip_a02, with_exudyn)
    rows["load_average"] = os.getloadavg()
    if arguments.json:
        arguments.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
