"""The N-four-bar chain per step: sparsekin kinematic, sparsekin dynamic and Exudyn, same run.

Issue 25's large-chain must-shows.  For each size (2N + 1 bodies), one fresh process per
measurement, one after the other (their peak memory is their own):

* ``kinematic`` — `KinematicStepper` on the kinematic twin (`four_bar_chain(N, 1.5)`, one
  driver), one output sample per 1 ms step;
* ``dynamic`` — `GeneralizedAlphaStepper` on `n_four_bar(N)` (gravity, released with B0 at
  1 m/s), fixed step 1 ms, one output sample per step; B0's largest position error against
  the exact answer (every crank moves as one four-bar: tests/dynamics_reference.py) over the
  steps taken (a run that stops reports where, ``stopped``, and the error up to there), and
  the largest drifts ‖Φ‖ and ‖Φq q̇ + Φt‖ over the steps (weighted as energy.csv: lengths
  over the model size, ``length_scale_m``);
* ``exudyn`` — Exudyn 1.13.6 on the same chain (benchmarks/peers/exudyn_models.py
  ``timing chain``: generalized-α, modified Newton, its sparse LU, fixed 1 ms steps), the
  largest B0 error over its steps.

Time per step: the mean over the timed steps after two warm-up steps (modified Newton
refactors on some steps only: a mean, not a median); peak memory: the process's
``ru_maxrss`` (build, start and steps; 185 MB of it is the process itself — a 3-body chain's
dynamic run peaks there: the interpreter with numpy, scipy, numba and sparsekin imported,
numba's runtime and registries, the kernels loaded — 172 MB for the kinematic run).
Commands::

    python3 benchmarks/measure_dynamics_chain.py table            # 10^3, 10^4, 10^5 bodies
    python3 benchmarks/measure_dynamics_chain.py table --accuracy  # + 100 steps at 10^5, both
    python3 benchmarks/measure_dynamics_chain.py one dynamic --bodies 1000001 --steps 20
    python3 benchmarks/measure_dynamics_chain.py against /tmp/base --bodies 100001 --rounds 3
    python3 benchmarks/measure_dynamics_chain.py one dynamic --bodies 100001 --steps 102 --step 0.98e-3
    python3 benchmarks/measure_dynamics_chain.py windows --bodies 100001 --steps 1000
    python3 benchmarks/measure_dynamics_chain.py table --accuracy --tolerance 1e-10 1e-8 1e-7 1e-6 1e-5

(the third: the 10^6-body run alone, a fresh process; note it in /work/notes/bigruns.txt
on the shared machine first; the fourth: the dynamic run of this tree and of another
checkout, e.g. ``git archive main | tar -x -C /tmp/base``, alternately in fresh
processes, each with its own sparsekin; the fifth: a shorter step, for a comparison with
Exudyn at equal accuracy over the accuracy run's horizon, (steps + 2) steps; ``windows``:
where a long dynamic run's time goes, per window of steps — CPU, solves, the projections'
residual passes and factorizations a step, through the flat crossing at ~0.72 s; the last:
the kinematic and dynamic runs with each tolerance given to both steppers in turn —
``--tolerance`` of ``one``, ``table``, ``against`` and ``windows``, default the steppers' own, 1e-12 and
1e-10 — and no Exudyn run unless ``default`` is among them: Exudyn keeps its own settings).
Each measurement prints one JSON line (with ``tolerance`` where one was given); ``table``
prints them and a Markdown table with the ratios of the same run, the lines of a given
tolerance in a table of their own (`tolerance_markdown`).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STEP = 1e-3
#: (bodies, timed steps) of the table.
SIZES = ((1001, 50), (10001, 20), (100001, 10))
ACCURACY_STEPS = 100


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure_sparsekin(analysis: str, bodies: int, steps: int, step: float = STEP,
                      tolerance: float | None = None) -> dict:  # fmt: skip
    """Time per step of `analysis` ("kinematic" or "dynamic") on the chain of `bodies`, steps of
    `step` seconds (`STEP` but for an equal-accuracy comparison), Newton (and projection)
    tolerance `tolerance` (None: the stepper's default, 1e-12 kinematic, 1e-10 dynamic)."""
    import numpy as np

    from sparsekin.testset import four_bar_chain, n_four_bar

    loops = (bodies - 1) // 2
    given = {} if tolerance is None else {"tolerance": tolerance}
    start = time.perf_counter()
    if analysis == "kinematic":
        from sparsekin.solve.stepper import KinematicStepper

        stepper = KinematicStepper(four_bar_chain(loops, 1.5), **given)
    else:
        from sparsekin.solve.dynamics import GeneralizedAlphaStepper

        stepper = GeneralizedAlphaStepper(n_four_bar(loops), step, **given)
    stepper.start(0.0)
    start_seconds = time.perf_counter() - start
    tips, drifts = [], [0.0, 0.0]

    def advance(k: int) -> None:
        stepper.advance(k * step)
        if analysis == "dynamic":  # B0, the tip of crank0 (origin at its pivot, 1 m long)
            q = stepper.state.coordinates
            tips.append((k * step, q[0] + np.cos(q[2]), q[1] + np.sin(q[2])))
            drifts[:] = np.maximum(drifts, stepper.recorded()[DRIFT][0])  # energy.csv's ‖Φ‖, ‖Φq q̇ + Φt‖

    from sparsekin.errors import ConvergenceError
    from sparsekin.results.schema import DRIFT

    for k in (1, 2):
        advance(k)
    clock, cpu, stopped, done = time.perf_counter(), time.process_time(), None, steps
    for k in range(3, steps + 3):
        try:
            advance(k)
        except ConvergenceError as error:  # a long run's failure: reported with the error up to there
            stopped, done = str(error), k - 3
            break
    per_step = (time.perf_counter() - clock) / max(done, 1)
    cpu_per_step = (time.process_time() - cpu) / max(done, 1)  # the process's own: less moved by the load
    result = {"analysis": analysis, "bodies": bodies, "steps": done, **({"step_s": step} if step != STEP else {}),
              **given, "seconds_per_step": per_step,
              "cpu_seconds_per_step": cpu_per_step, "start_seconds": start_seconds, "peak_memory_mb": peak_mb()}  # fmt: skip
    if stopped is not None:
        result |= {"stopped": stopped, "stopped_at_s": stepper.time}
    if analysis == "dynamic":
        sys.path.insert(0, str(ROOT / "tests"))
        from dynamics_reference import n_four_bar_b0

        tips = np.array(tips)
        exact, _ = n_four_bar_b0(tips[:, 0], n_loops=loops)
        result["b0_error_m"] = float(np.abs(tips[:, 1:] - exact).max())
        result |= {"newton_per_step": stepper.n_newton / stepper.n_steps, "path": stepper.path,
                   "factorizations": stepper.n_factorizations, "stalls": stepper.n_stalls,
                   "steps_taken": stepper.n_steps, "halvings": stepper.n_subdivisions,
                   # largest over every step (weighted as energy.csv: lengths over the model size)
                   "drift_position": float(drifts[0]), "drift_velocity": float(drifts[1]),
                   "length_scale_m": stepper.pattern.length_scale}  # fmt: skip
    return result


#: (first, last) step of each window of `windows` (the flat crossing at steps ~700–760).
WINDOWS = ((1, 20), (21, 100), (101, 300), (301, 700), (701, 760), (761, 1000))


def windows(bodies: int, steps: int, tolerance: float | None = None) -> list[dict]:
    """The dynamic run of `bodies` over `steps` steps of 1 ms in this process (at `tolerance`,
    None: the default), per window of `WINDOWS`: CPU a step, solves, residual passes of the
    projections' refinement (calls of `DynamicSystem.residuals`, counted through a wrapper),
    factorizations and halvings."""
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper
    from sparsekin.testset import n_four_bar

    given = {} if tolerance is None else {"tolerance": tolerance}
    stepper = GeneralizedAlphaStepper(n_four_bar((bodies - 1) // 2), STEP, **given)
    stepper.start(0.0)
    residuals, passes = stepper.system.residuals, [0]

    def counted(*arguments, **keywords):
        passes[0] += 1
        return residuals(*arguments, **keywords)

    stepper.system.residuals = counted
    per_step = []
    for k in range(1, steps + 1):
        before = (time.process_time(), stepper.solver.n_solves, passes[0], stepper.n_factorizations,
                  stepper.n_subdivisions)  # fmt: skip
        stepper.advance(k * STEP)
        after = (time.process_time(), stepper.solver.n_solves, passes[0], stepper.n_factorizations,
                 stepper.n_subdivisions)  # fmt: skip
        per_step.append([b - a for a, b in zip(before, after)])
    rows = []
    for first, last in WINDOWS:
        window = per_step[first - 1 : min(last, steps)]
        if window:
            cpu, solves, residual_passes, factorizations, halvings = (sum(column) for column in zip(*window))
            rows.append({"bodies": bodies, **given, "first": first, "last": first + len(window) - 1,
                         "cpu_seconds_per_step": cpu / len(window), "solves_per_step": solves / len(window),
                         "residual_passes_per_step": residual_passes / len(window),
                         "factorizations": factorizations, "halvings": halvings})  # fmt: skip
    return rows


def in_subprocess(*arguments: str, tree: Path = ROOT) -> dict:
    """One measurement in a fresh interpreter (with the sparsekin of `tree`), parsed from its
    last output line."""
    command = [sys.executable, "-W", "ignore", *arguments]
    output = subprocess.run(command, check=True, capture_output=True, text=True, cwd=tree,
                            env={**os.environ, "PYTHONPATH": str(tree)})  # fmt: skip
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], check=False, capture_output=True, text=True,
                            cwd=ROOT).stdout.strip()  # fmt: skip
    return {**json.loads(output.stdout.strip().splitlines()[-1]), "load_average": os.getloadavg()[0],
            "utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "commit": commit}  # fmt: skip


def tolerance_arguments(tolerance: float | None) -> tuple[str, ...]:
    return () if tolerance is None else ("--tolerance", repr(tolerance))


def sparsekin_row(analysis: str, bodies: int, steps: int, tolerance: float | None = None) -> dict:
    return in_subprocess(__file__, "one", analysis, "--bodies", str(bodies), "--steps", str(steps),
                         *tolerance_arguments(tolerance))  # fmt: skip


def against(tree: Path, bodies: int, steps: int, rounds: int, tolerance: float | None = None) -> list[dict]:
    """The dynamic run of this tree and of `tree` (another checkout, its own sparsekin; this
    script's measurement, the same for both, at `tolerance`) alternately, `rounds` times each,
    fresh processes: rows with ``against`` (`tree`) and ``tree`` ("this" or "other")."""
    rows = []
    for round_ in range(rounds):
        for name, root in (("other", tree), ("this", ROOT)):
            arguments = ("one", "dynamic", "--bodies", str(bodies), "--steps", str(steps),
                         *tolerance_arguments(tolerance))  # fmt: skip
            row = in_subprocess(__file__, *arguments, tree=root)
            rows.append({**row, "against": str(tree), "tree": name, "round": round_})
            print(json.dumps(rows[-1]), flush=True)
    return rows


def against_markdown(rows: list[dict]) -> str:
    """Per size, its latest commit's rows: median time per step and peak of this tree and of
    the other, their ratios, and the load (times compare only at similar loads)."""
    import statistics

    lines = ["| bodies | commit | rounds | per step, before | per step, after | after / before | CPU after / before "
             "| peak before | peak after | after / before | load |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for bodies, tolerance in sorted({(row["bodies"], row.get("tolerance", 0.0)) for row in rows}):
        mine = [row for row in rows if row["bodies"] == bodies and row.get("tolerance", 0.0) == tolerance]
        commit = mine[-1]["commit"]
        of_size = [row for row in mine if row["commit"] == commit]
        by = {name: [row for row in of_size if row["tree"] == name] for name in ("other", "this")}
        if not (by["other"] and by["this"]):
            continue
        time_, peak = ({name: statistics.median(row[key] for row in by[name]) for name in by}
                       for key in ("seconds_per_step", "peak_memory_mb"))  # fmt: skip
        loads = [row["load_average"] for row in of_size]
        recorded = all("cpu_seconds_per_step" in row for row in of_size)  # (not in the rows made before)
        cpu = None
        if recorded:
            cpu = {name: statistics.median(row["cpu_seconds_per_step"] for row in by[name]) for name in by}
        cpu_ratio = f"{cpu['this'] / cpu['other']:.2f}" if cpu else ""
        label = f"{bodies} (tolerance {tolerance:g})" if tolerance else f"{bodies}"
        lines.append(f"| {label} | {commit} | {len(by['this'])} | {_seconds(time_['other'])} "
                     f"| {_seconds(time_['this'])} | {time_['this'] / time_['other']:.2f} | {cpu_ratio} "
                     f"| {peak['other']:.0f} MB "
                     f"| {peak['this']:.0f} MB | {peak['this'] / peak['other']:.2f} "
                     f"| {min(loads):.1f}–{max(loads):.1f} |")  # fmt: skip
    runs = sorted(row["utc"] for row in rows)
    lines.append(f"\nMedians of alternating fresh processes (before: the other tree, e.g. main's; after: this "
                 f"tree at the commit given); CPU: the processes' own CPU time per step (`time.process_time`, "
                 f"less moved by the load than the wall time); load: the 1-min load average; {runs[0]} to "
                 f"{runs[-1]} UTC.")  # fmt: skip
    return "\n".join(lines)


def exudyn_row(bodies: int, steps: int) -> dict:
    # steps + 2 steps, as sparsekin's (two before the clock): B0's error over the same horizon
    row = in_subprocess(str(ROOT / "benchmarks" / "peers" / "exudyn_models.py"), "timing", "chain",
                        "--bodies", str(bodies), "--steps", str(steps + 2), "--repeat", "1")  # fmt: skip
    return {"analysis": "exudyn", "bodies": bodies, "steps": steps, "seconds_per_step": row["seconds_per_step"],
            **{key: row[key] for key in ("cpu_seconds_per_step",) if key in row},
            "start_seconds": row["start_seconds"], "peak_memory_mb": row["peak_memory_mb"],
            "b0_error_m": row["b0_error_m"], "load_average": row["load_average"], "utc": row["utc"],
            "commit": row["commit"]}  # fmt: skip


def table(accuracy: bool, sizes=SIZES, tolerances=(None,)) -> list[dict]:
    """Every size, kinematic and dynamic at each of `tolerances` (None: the steppers' defaults)
    and Exudyn (at its own settings, once, with the defaults' lines) in turn; with `accuracy`,
    the dynamic runs and Exudyn's over `ACCURACY_STEPS` steps at the largest size."""
    peers = ("exudyn",) if None in tolerances else ()
    plan = [(analysis, bodies, steps, False, tolerance) for bodies, steps in sizes for tolerance in tolerances
            for analysis in ("kinematic", "dynamic", *(peers if tolerance is None else ()))]  # fmt: skip
    if accuracy:
        plan += [("dynamic", sizes[-1][0], ACCURACY_STEPS, True, tolerance) for tolerance in tolerances]
        plan += [(analysis, sizes[-1][0], ACCURACY_STEPS, True, None) for analysis in peers]
    rows = []
    for analysis, bodies, steps, accuracy_run, tolerance in plan:
        row = exudyn_row(bodies, steps) if analysis == "exudyn" else sparsekin_row(analysis, bodies, steps, tolerance)
        rows.append({**row, "accuracy_run": accuracy_run})
        print(json.dumps(rows[-1]), flush=True)
    return rows


def markdown(rows: list[dict]) -> str:
    """The table of a run at the steppers' default tolerances, with the ratios of the same run,
    then the accuracy runs and the load (the lines of another tolerance: `tolerance_markdown`)."""
    rows = [row for row in rows if "tolerance" not in row]
    header = ("| bodies | kinematic | dynamic | dynamic / kinematic | Exudyn | Exudyn / dynamic | CPU: dynamic / "
              "kinematic | CPU: Exudyn / dynamic | peak kinematic | peak dynamic | peak Exudyn |")  # fmt: skip
    lines = [header, "|---|---|---|---|---|---|---|---|---|---|---|"]
    timed = [row for row in rows if not row.get("accuracy_run")]
    for bodies in sorted({row["bodies"] for row in timed}):
        by = {row["analysis"]: row for row in timed if row["bodies"] == bodies}
        kin, dyn, exu = (by.get(a, {}).get("seconds_per_step") for a in ("kinematic", "dynamic", "exudyn"))
        cpu = {a: by.get(a, {}).get("cpu_seconds_per_step") for a in ("kinematic", "dynamic", "exudyn")}
        cells = [f"{bodies}", *(_seconds(t) for t in (kin, dyn)), f"{dyn / kin:.2f}×" if kin and dyn else "",
                 _seconds(exu), f"{exu / dyn:.1f}×" if exu and dyn else "",
                 f"{cpu['dynamic'] / cpu['kinematic']:.2f}×" if cpu["kinematic"] and cpu["dynamic"] else "",
                 f"{cpu['exudyn'] / cpu['dynamic']:.1f}×" if cpu["exudyn"] and cpu["dynamic"] else "",
                 *(f"{by[a]['peak_memory_mb']:.0f} MB" if a in by else "" for a in ("kinematic", "dynamic", "exudyn"))]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    for row in rows:
        if row.get("accuracy_run"):
            cpu = row.get("cpu_seconds_per_step")
            lines.append(f"\n{row['analysis']} at {row['bodies']} bodies, {row['steps']} steps: B0 error "
                         f"{row['b0_error_m']:.3g} m, {_seconds(row['seconds_per_step'])} per step"
                         + (f" ({_seconds(cpu)} of CPU)" if cpu else ""))  # fmt: skip
    return "\n".join(lines + _provenance(rows))


def tolerance_markdown(rows: list[dict]) -> str:
    """The lines of a tolerance given (``tolerance``, the same to both steppers), one table row
    per size and tolerance, the medians of its lines (the rounds of `table`): times and their
    ratio as in `markdown`, the dynamic CPU time against the dynamic lines at the dynamic
    default (1e-10) among them, the largest drifts over the steps of any round (as energy.csv:
    lengths over the model size; the step's bound is tolerance · h for the velocities), the
    most halvings and stalls; then the accuracy runs' medians and the load."""
    import statistics

    from sparsekin.solve.dynamics import DEFAULT_TOLERANCE

    rows = [row for row in rows if "tolerance" in row]
    if not rows:
        return ""

    def lines_of(analysis: str, bodies: int, tolerance: float, accuracy_run: bool = False) -> list[dict]:
        return [row for row in rows if (row["analysis"], row["bodies"], row["tolerance"], bool(row.get("accuracy_run")))
                == (analysis, bodies, tolerance, accuracy_run)]  # fmt: skip

    def median(lines: list[dict], key: str) -> float | None:
        values = [row[key] for row in lines if key in row]
        return statistics.median(values) if values else None

    lines = ["| bodies | tolerance | rounds | kinematic | dynamic | dynamic / kinematic | CPU: dynamic / kinematic "
             "| CPU: dynamic / dynamic at 1e-10 | ‖Φ‖ | ‖Φq q̇ + Φt‖ | halvings | stalls | peak dynamic |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    timed = [row for row in rows if not row.get("accuracy_run")]
    for bodies, tolerance in sorted({(row["bodies"], row["tolerance"]) for row in timed}, key=lambda k: (k[0], -k[1])):
        kin, dyn = (lines_of(analysis, bodies, tolerance) for analysis in ("kinematic", "dynamic"))
        wall = median(kin, "seconds_per_step"), median(dyn, "seconds_per_step")
        cpu = median(kin, "cpu_seconds_per_step"), median(dyn, "cpu_seconds_per_step")
        base = median(lines_of("dynamic", bodies, DEFAULT_TOLERANCE), "cpu_seconds_per_step")
        cells = [f"{bodies}", f"{tolerance:g}", f"{max(len(kin), len(dyn))}", *(_seconds(value) for value in wall),
                 f"{wall[1] / wall[0]:.2f}×" if all(wall) else "", f"{cpu[1] / cpu[0]:.2f}×" if all(cpu) else "",
                 f"{cpu[1] / base:.2f}" if cpu[1] and base else "",
                 *(f"{max(row[key] for row in dyn):.2g}" if dyn else "" for key in ("drift_position", "drift_velocity")),
                 *(f"{max(row[key] for row in dyn)}" if dyn else "" for key in ("halvings", "stalls")),
                 f"{median(dyn, 'peak_memory_mb'):.0f} MB" if dyn else ""]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    accuracy = sorted({(row["bodies"], row["tolerance"]) for row in rows if row.get("accuracy_run")},
                      key=lambda k: (k[0], -k[1]))  # fmt: skip
    for bodies, tolerance in accuracy:
        runs = lines_of("dynamic", bodies, tolerance, True)
        errors = sorted(row["b0_error_m"] for row in runs)
        cpu = median(runs, "cpu_seconds_per_step")
        lines.append(f"\ndynamic at {bodies} bodies, {runs[0]['steps']} steps, tolerance {tolerance:g}: B0 error "
                     f"{errors[0]:.3g}" + (f"–{errors[-1]:.3g}" if errors[-1] != errors[0] else "")
                     + f" m, {_seconds(median(runs, 'seconds_per_step'))} per step"
                     + (f" ({_seconds(cpu)} of CPU)" if cpu else "") + f", {len(runs)} rounds")  # fmt: skip
    return "\n".join(lines + _provenance(rows))


def _provenance(rows: list[dict]) -> list[str]:
    """The lines' load range, times and commits, for the end of a table."""
    lines = []
    loads = [row["load_average"] for row in rows if "load_average" in row]
    if loads:
        lines.append(f"\nLoad average (1 min) during the runs: {min(loads):.1f} to {max(loads):.1f}.")
    runs = sorted({(row["utc"], row["commit"]) for row in rows if "utc" in row})
    if runs:
        commits = ", ".join(sorted({commit for _, commit in runs}))
        lines.append(f"Taken {runs[0][0]} to {runs[-1][0]} UTC at commit {commits} (2 cores shared by six sessions).")
    return lines


def _seconds(value: float | None) -> str:
    if value is None:
        return ""
    return f"{value:.3g} s" if value >= 1.0 else f"{value * 1e3:.3g} ms"


def latest(rows: list[dict]) -> list[dict]:
    """The last line of each measurement (analysis, bodies, accuracy run or not), in the
    order of their last appearance: `DYNAMICS_CHAIN` keeps the earlier runs as history."""
    last = {(row["analysis"], row["bodies"], bool(row.get("accuracy_run")), row.get("tolerance")): row for row in rows}
    return sorted(last.values(), key=rows.index)


def results_section(rows: list[dict]) -> list[str]:
    """benchmarks/RESULTS.md's section (`make_results.py`) from the lines of `DYNAMICS_CHAIN`
    (the latest of each measurement; of the lines of a tolerance given, the latest commit's)."""
    compared = [row for row in rows if "against" in row]
    given = [row for row in rows if "tolerance" in row and "against" not in row]
    # every round of the latest commit's tolerance lines (medians); an earlier commit's stay as history
    given = [row for row in given if row.get("commit") == given[-1].get("commit")] if given else []
    rows = latest([row for row in rows if "against" not in row])
    before = [] if not compared else [
        "", "The dynamic run against the tree before a change (`against`, the lines with ``against``",
        "in the same file): per size, its latest commit's comparison.", "",
        *against_markdown(compared).splitlines(),
    ]  # fmt: skip
    return [
        "## Forward dynamics: the N-four-bar chain (issue 25; `measure_dynamics_chain.py`)",
        "",
        "Not part of the pytest-benchmark run: `benchmarks/dynamics_chain.jsonl` holds the lines of",
        "`python3 benchmarks/measure_dynamics_chain.py table --accuracy --out benchmarks/dynamics_chain.jsonl`",
        "(10^3–10^5 bodies) and of `python3 benchmarks/measure_dynamics_chain.py one dynamic --bodies 1000001",
        "--steps 20` (10^6, alone). One fresh process per measurement, one after the other: sparsekin's",
        "kinematic step of the twin chain (`four_bar_chain`, one driver), its dynamic step of",
        "`n_four_bar` under gravity (generalized-α, fixed 1 ms steps, one output sample per step) and",
        "Exudyn 1.13.6's (generalized-α, modified Newton, its sparse LU; benchmarks/peers/). Time per",
        "step: the mean over the timed steps after two; peak: the process's resident set (185 MB of it",
        "the process itself, a 3-body chain's dynamic run: interpreter, numpy, scipy, numba and its runtime,",
        "sparsekin's kernels; 172 MB for the kinematic run, 44 MB with Exudyn). B0 error: against the",
        "exact answer (every crank moves as one four-bar), largest over the steps taken.",
        "",
        *markdown(rows).splitlines(),
        *tolerance_section(given),
        *before,
    ]


def tolerance_section(rows: list[dict]) -> list[str]:
    """`results_section`'s part for the lines of another tolerance (`tolerance_markdown`)."""
    text = tolerance_markdown(rows)
    if not text:
        return []
    return [
        "", "At a looser Newton and projection tolerance (`table --tolerance T ...`, given to both",
        "sparsekin steppers; Exudyn at its own settings): per size and tolerance, the medians of its lines. ‖Φ‖ and",
        "‖Φq q̇ + Φt‖: the largest over the run's steps, weighted as energy.csv (lengths over the model",
        "size, `length_scale_m` in the lines); a step may leave a velocity drift of tolerance · h.", "",
        *text.splitlines(),
    ]  # fmt: skip


#: The lines `table --out` wrote for RESULTS.md.
DYNAMICS_CHAIN = Path(__file__).resolve().with_name("dynamics_chain.jsonl")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    one = commands.add_parser("one", help="one sparsekin measurement in this process")
    one.add_argument("analysis", choices=("kinematic", "dynamic"))
    one.add_argument("--bodies", type=int, default=1001, help="2N + 1")
    one.add_argument("--steps", type=int, default=20)
    one.add_argument("--step", type=float, default=STEP, help="seconds (dynamic; default %(default)s)")
    one.add_argument("--tolerance", type=float, help="Newton and projection tolerance (default: the stepper's)")
    run_table = commands.add_parser("table", help="every size, each measurement in a fresh process")
    run_table.add_argument("--accuracy", action="store_true", help=f"and {ACCURACY_STEPS} steps at the largest size")
    run_table.add_argument("--out", type=Path, help="also write the JSON lines here")
    run_table.add_argument("--tolerance", type=_tolerance, nargs="+", default=[None],
                           help="tolerances of both steppers, in turn ('default': the steppers' own)")
    compare = commands.add_parser("against", help="the dynamic run of this tree and another, alternately")
    compare.add_argument("tree", type=Path, help="the other checkout (e.g. an export of main)")
    compare.add_argument("--bodies", type=int, nargs="+", default=[10001, 100001])
    compare.add_argument("--steps", type=int, default=20)
    compare.add_argument("--rounds", type=int, default=3)
    compare.add_argument("--append", type=Path, help="append the JSON lines to this file")
    compare.add_argument("--tolerance", type=float, help="of both trees' dynamic runs (default: the stepper's)")
    by_window = commands.add_parser("windows", help="a long dynamic run's cost per window of steps, this process")
    by_window.add_argument("--bodies", type=int, default=100001, help="2N + 1")
    by_window.add_argument("--steps", type=int, default=1000)
    by_window.add_argument("--tolerance", type=float, help="Newton and projection tolerance (default: the stepper's)")
    arguments = parser.parse_args(argv)
    if arguments.command == "windows":
        for row in windows(arguments.bodies, arguments.steps, arguments.tolerance):
            print(json.dumps(row))
        return
    if arguments.command == "against":
        rows = [row for bodies in arguments.bodies
                for row in against(arguments.tree.resolve(), bodies, arguments.steps, arguments.rounds,
                                   arguments.tolerance)]  # fmt: skip
        if arguments.append:
            with arguments.append.open("a") as out:
                out.write("".join(json.dumps(row) + "\n" for row in rows))
        print(against_markdown(rows))
        return
    if arguments.command == "one":
        print(json.dumps(measure_sparsekin(arguments.analysis, arguments.bodies, arguments.steps, arguments.step,
                                           arguments.tolerance)))  # fmt: skip
        return
    rows = table(arguments.accuracy, tolerances=arguments.tolerance)
    if arguments.out:
        arguments.out.write_text("".join(json.dumps(row) + "\n" for row in rows))
    print(markdown(rows) if None in arguments.tolerance else "")
    print(tolerance_markdown(rows))


def _tolerance(text: str) -> float | None:
    return None if text == "default" else float(text)


if __name__ == "__main__":
    main()
