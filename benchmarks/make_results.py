"""Run the full benchmark suite and write benchmarks/RESULTS.md from it.

Usage:

* ``python3 benchmarks/make_results.py`` runs `COMMAND` (the full sizes, 15 minutes on
  this project's machines) and writes benchmarks/results.json and benchmarks/RESULTS.md;
* ``python3 benchmarks/make_results.py results.json [RESULTS.md]`` only writes the tables
  from an earlier run's JSON.

Every figure comes from the JSON: the medians of `test_scaling.py::test_time_step` divided
by the steps per round, the phase split and Newton iterations it recorded, and the build
times and peak memory of `test_scaling.py::test_setup_and_memory`.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from measure_andrews_work_precision import ANDREWS_WORK_PRECISION
from measure_andrews_work_precision import results_section as andrews_section
from measure_compiled_band import COMPILED_BAND
from measure_compiled_band import results_section as compiled_band_section
from measure_dynamics_chain import DYNAMICS_CHAIN
from measure_dynamics_chain import results_section as dynamics_chain_section
from measure_lattice_dynamics import LATTICE_DYNAMICS
from measure_lattice_dynamics import results_section as lattice_dynamics_section
from measure_mesh_long import MESH_LONG
from measure_mesh_long import results_section as mesh_long_section
from measure_small_dynamics import SMALL_DYNAMICS
from measure_small_dynamics import results_section as small_dynamics_section

#: The benchmark run whose JSON this script reads, from the repository root.
COMMAND = (
    "python3 -m pytest benchmarks --benchmark-enable --benchmark-only --sizes=full "
    "--benchmark-json=benchmarks/results.json"
)
_HERE = Path(__file__).resolve().parent
#: Lines printed by `measure_mesh_lu.py` and `measure_mesh_steps.py` (issue 29), kept by hand.
MESH_LU = _HERE / "mesh_lu.jsonl"
#: Lines printed by `measure_mesh_reuse.py` (issue 29: long lattice runs under `ReusingSolver`), kept by hand.
MESH_REUSE = _HERE / "mesh_reuse.jsonl"
#: The table printed by `memory_estimates.py` (issue 28) with its command and load, kept by hand.
MEMORY_ESTIMATES = _HERE / "memory_estimates.md"
#: Hand-measured error-controlled runs of A02 (`measure_dynamics_accuracy.py`), as written.
DYNAMICS_ACCURACY = _HERE / "dynamics_accuracy.md"
#: Sizes over which the scaling exponents are fitted, bodies.
FIT_RANGE = (1_000, 1_000_000)
#: The solver whose time the ratios divide, and the baselines, in column order.
REFERENCE = "sparsekin"
BASELINES = ("superlu", "coo_spsolve", "dense")


def _seconds(value: float) -> str:
    """A duration with a unit that keeps three significant digits."""
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6)):
        if value >= scale:
            return f"{value / scale:.3g} {unit}"
    return f"{value / 1e-9:.3g} ns"


def load(path: Path) -> tuple[dict, dict, dict]:
    """(steps, setups, document): per (family, bodies) the step records, the setup records."""
    document = json.loads(path.read_text())
    steps: dict = defaultdict(dict)
    setups: dict = {}
    others, large, sweeps, forces, startup, overconstrained, hubs = [], [], [], [], [], [], []
    for record in document["benchmarks"]:
        info = record["extra_info"]
        if record["name"].startswith("test_time_step"):
            per_step = record["stats"]["median"] / info["steps_per_round"]
            steps[(info["family"], info["bodies"])][info["solver"]] = dict(info, seconds_per_step=per_step)
        elif record["name"].startswith("test_setup_and_memory"):
            setups[(info["family"], info["bodies"])] = info
        elif record["name"].startswith(("test_large_file", "test_grid_file")):
            large.append(info)
        elif record["name"].startswith("test_task5_amplitude_sweep"):
            sweeps.append(info)
        elif record["name"].startswith(("test_task5_run", "test_chain_step")):
            forces.append(dict(info, median=record["stats"]["median"]))
        elif record["name"].startswith("test_startup"):
            startup.append(info)
        elif record["name"].startswith("test_overconstrained"):
            overconstrained.append(info)
        elif record["name"].startswith("test_hub_against_chain"):
            hubs.append(info)
        else:
            others.append(record)
    document["others"], document["large"], document["sweeps"] = others, large, sweeps
    document["forces"], document["startup"] = forces, startup
    document["overconstrained"], document["hubs"] = overconstrained, hubs
    return steps, setups, document


def scaling_exponent(points: list[tuple[int, float]]) -> float | None:
    """Least-squares slope of log(time per step) against log(bodies) over `FIT_RANGE`."""
    fitted = [(b, t) for b, t in points if FIT_RANGE[0] <= b <= FIT_RANGE[1] * 1.01]
    if len(fitted) < 2:
        return None
    x, y = np.log([b for b, _ in fitted]), np.log([t for _, t in fitted])
    return float(np.polyfit(x, y, 1)[0])


def render(steps: dict, setups: dict, document: dict) -> str:
    machine = document.get("machine_info", {})
    commit = document.get("commit_info", {})
    cpu = machine.get("cpu", {})
    lines = [
        "# Benchmark results",
        "",
        "Generated by `benchmarks/make_results.py` from a pytest-benchmark run; do not edit by hand.",
        "",
        f"- **Date**: {document.get('datetime', '?')}",
        f"- **Machine**: {cpu.get('brand_raw', machine.get('processor', '?'))}, "
        f"{cpu.get('count', '?')} logical CPUs, {machine.get('system', '?')} {machine.get('release', '')}, "
        f"Python {machine.get('python_version', '?')}",
        f"- **Commit**: {commit.get('id', '?')[:12]}{' (with uncommitted changes)' if commit.get('dirty') else ''}",
        "- **Command**: `python3 benchmarks/make_results.py`, which runs",
        f"  `{COMMAND}` and writes this file from the JSON",
        "",
        "Time per step: the median over rounds of the time of a round of full steps (positions by",
        "Newton–Raphson, velocities, accelerations of every body) divided by its steps; time step",
        "0.01 s from the same solved first sample each round. The split (assembly: driver laws,",
        "residual, Jacobian and γ refills; factorization; solves) and the Newton iterations per",
        "step are those of the last round. Ratios are baseline time / sparsekin time in the same",
        "run. `sparsekin`: refactorization on a fixed pattern and chord Newton (what",
        "`solve_kinematics` runs above `COMPILED_MAX_COORDINATES`; where the refactorization's fill-in",
        "exceeds `MAX_REFACTOR_FILL`, its factorization reused across samples by GMRES, marked †);",
        "`superlu`: a SuperLU factorization per",
        "Newton iteration; `coo_spsolve`: Jacobian rebuilt COO → CSR and `spsolve` for every system; `dense`:",
        "dense Jacobian and `numpy.linalg.solve` for every system. Build: making the `Mechanism`;",
        "pattern: `build_pattern`; first sample: pattern, assembler and the first Newton solve;",
        "memory: peak resident set of a fresh process after two steps, less the same process's",
        "peak before the model was built (interpreter, libraries and compiled kernels).",
        "",
    ]
    families = sorted({family for family, _ in steps}, key=["task5_chain", "four_bar_chain", "lattice"].index)
    exponents = {}
    for family in families:
        sizes = sorted(bodies for f, bodies in steps if f == family)
        solvers = sorted({s for b in sizes for s in steps[(family, b)]} - {REFERENCE, *BASELINES})
        lines += [f"## {family}", ""]
        header = ["bodies", "sparsekin / step", "assembly", "factorization", "solves", "Newton it. / step"]
        header += [f"{name} / step" for name in solvers]
        header += [f"{name} / step (ratio)" for name in BASELINES]
        header += ["build", "pattern", "first sample", "peak memory", "per body"]
        lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for bodies in sizes:
            records = steps[(family, bodies)]
            mine = records.get(REFERENCE)
            row = [f"{bodies:,}"]
            if mine:
                row += [
                    _seconds(mine["seconds_per_step"]) + (" †" if mine.get("path") == "reuse" else "")
                ]
                row += [
                    _seconds(mine[f"{phase}_seconds_per_step"])
                    for phase in ("assembly", "factorization", "solves")
                ]
                row += [f"{mine['newton_iterations_per_step']:.2f}"]
            else:
                row += ["—"] * 5
            row += [
                _seconds(records[name]["seconds_per_step"]) if name in records else "—" for name in solvers
            ]
            for name in BASELINES:
                if name in records and mine:
                    ratio = records[name]["seconds_per_step"] / mine["seconds_per_step"]
                    row.append(f"{_seconds(records[name]['seconds_per_step'])} ({ratio:.3g}×)")
                else:
                    row.append("not run")
            setup = setups.get((family, bodies))
            if setup:
                used = setup["peak_rss_bytes"] - setup["baseline_rss_bytes"]
                row += [_seconds(setup["build_seconds"]), _seconds(setup["pattern_seconds"])]
                row += [
                    _seconds(setup["first_sample_seconds"]),
                    f"{used / 2**20:,.0f} MB",
                    f"{used / bodies:,.0f} B",
                ]
            else:
                row += ["—"] * 5
            lines.append("| " + " | ".join(row) + " |")
        for name in (REFERENCE, *BASELINES):
            points = [
                (b, steps[(family, b)][name]["seconds_per_step"]) for b in sizes if name in steps[(family, b)]
            ]
            exponents[(family, name)] = scaling_exponent(points)
        lines.append("")
    lines += [
        "## Scaling",
        "",
        f"Exponent of time per step against bodies, least squares over {FIT_RANGE[0]:,}–{FIT_RANGE[1]:,} bodies:",
        "",
    ]
    for (family, name), exponent in exponents.items():
        if exponent is not None:
            lines.append(f"- {family}, {name}: {exponent:.3f}")
    if document["large"]:
        lines += ["", *_large_files(document["large"])]
    if document["forces"]:
        lines += ["", *_forces(document["forces"])]
    if document["sweeps"]:
        lines += ["", *_sweeps(document["sweeps"])]
    if document["startup"]:
        lines += ["", *_startup(document["startup"][0])]
    if document.get("overconstrained"):
        lines += ["", *_overconstrained(document["overconstrained"])]
    if MESH_LU.exists():
        lines += ["", *mesh_lu_section([json.loads(line) for line in MESH_LU.read_text().splitlines() if line])]
    if MESH_REUSE.exists():
        lines += ["", *mesh_reuse_section([json.loads(line) for line in MESH_REUSE.read_text().splitlines() if line])]
    if MESH_LONG.exists():
        lines += ["", *mesh_long_section([json.loads(line) for line in MESH_LONG.read_text().splitlines() if line])]
    if MEMORY_ESTIMATES.exists():
        lines += ["", *MEMORY_ESTIMATES.read_text(encoding="utf-8").rstrip("\n").splitlines()]
    if SMALL_DYNAMICS.exists():
        lines += ["", *small_dynamics_section([json.loads(line) for line in SMALL_DYNAMICS.read_text().splitlines() if line])]
    if COMPILED_BAND.exists():
        lines += ["", *compiled_band_section([json.loads(line) for line in COMPILED_BAND.read_text().splitlines() if line])]
    if document.get("hubs"):
        lines += ["", *_hubs(document["hubs"])]
    if DYNAMICS_CHAIN.exists():
        lines += ["", *dynamics_chain_section([json.loads(line) for line in DYNAMICS_CHAIN.read_text().splitlines() if line])]
    if LATTICE_DYNAMICS.exists():
        lines += ["", *lattice_dynamics_section([json.loads(line) for line in LATTICE_DYNAMICS.read_text().splitlines()
                                                 if line])]  # fmt: skip
    if ANDREWS_WORK_PRECISION.exists():
        lines += ["", *andrews_section([json.loads(line) for line in ANDREWS_WORK_PRECISION.read_text().splitlines() if line])]
    if DYNAMICS_ACCURACY.exists():
        lines += ["", *DYNAMICS_ACCURACY.read_text(encoding="utf-8").rstrip("\n").splitlines()]
    if document["others"]:
        lines += [
            "",
            "## Whole runs through `solve_kinematics`, and the phases of a Task 5 step",
            "",
            "`test_crossover`: the compiled dense loop against the refactorization path on small models",
            '(`linear_solver="auto"` switches at `COMPILED_MAX_COORDINATES`).',
            "",
            "| benchmark | median | min | rounds | notes |",
            "|---|---|---|---|---|",
        ]
        for record in document["others"]:
            stats = record["stats"]
            if "samples" in record["extra_info"]:  # a whole run: its time per step
                record["extra_info"]["time_per_step"] = _seconds(
                    stats["median"] / (record["extra_info"]["samples"] - 1)
                )
            notes = ", ".join(
                f"{key} {value:.4g}" if isinstance(value, float) else f"{key} {value}"
                for key, value in record["extra_info"].items()
            )
            lines.append(
                f"| `{record['name']}` | {_seconds(stats['median'])} | {_seconds(stats['min'])} | {stats['rounds']} | {notes} |"
            )
    lines += [
        "",
        "Dense baseline: run up to 1,000 bodies only. At 10^4 bodies its matrix (3·10^4 squared) would take",
        "7.2 GB and each `numpy.linalg.solve` about 2/3·(3·10^4)^3 ≈ 1.8·10^13 flops, minutes per solve on this machine.",
        "",
    ]
    return "\n".join(lines)


def _hubs(records: list[dict]) -> list[str]:
    """The table of `test_hub_topology.py`: legs on one crankshaft against the same legs in a chain."""
    lines = [
        "## Many legs on one body against the same legs in a chain (`test_hub_topology.py`)",
        "",
        "Jansen legs whose cranks are welded to one crankshaft body (a hub) or each to the previous",
        "one (a chain): the same bodies and equations. Time per step: the median of 5 rounds of 20",
        "steps of `KinematicStepper`, both in the same run (target: hub / chain ≤ 1.5).",
        "",
        "| legs | bodies | hub / step | chain / step | hub / chain | paths |",
        "|---|---|---|---|---|---|",
    ]
    for info in records:
        hub, chain = info["hub"], info["chain"]
        lines.append(f"| {info['legs']:,} | {hub['bodies']:,} | {_seconds(hub['seconds_per_step'])} | "
                     f"{_seconds(chain['seconds_per_step'])} | {info['ratio']:.2f} | "
                     f"{hub['linear_solver']}, {chain['linear_solver']} |")
    return lines


def _overconstrained(records: list[dict]) -> list[str]:
    """The table of `test_overconstrained.py`, and the exponent of the squares' setup time."""
    lines = [
        "## Overconstrained mechanisms (`test_overconstrained.py`)",
        "",
        "Each row is one fresh process (`benchmarks/measure_redundancy.py`): `check_model`, the first sample",
        "(`KinematicStepper.start`: redundant equations found, named and left out, first factorization), the",
        "median of 10 steps of 0.01 s, the peak resident memory (everything included), the positions against",
        "the closed form. `lattice_like_squares` and `parallel_bar_chain_2` are the non-redundant references.",
        "",
        "| family | bodies | redundant | check | first sample | per step | peak memory | closed-form error |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for info in records:
        error = info["closed_form_error"]
        cells = [info["family"], f"{info['bodies']:,}", f"{info['redundant']:,}", _seconds(info["check_seconds"]),
                 _seconds(info["first_sample_seconds"]), _seconds(info["step_seconds"]),
                 f"{info['peak_rss_bytes'] / 2**30:.2f} GB", "—" if error != error else f"{error:.1e} m"]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    squares = [(info["bodies"], info["check_seconds"] + info["first_sample_seconds"])
               for info in records if info["family"] == "rotating_squares" and info["bodies"] >= 900]  # fmt: skip
    if len(squares) >= 2:
        x, y = np.log([b for b, _ in squares]), np.log([t for _, t in squares])
        lines += ["", f"Exponent of the rotating squares' setup time (check + first sample) against bodies, "
                      f"{squares[0][0]:,} to {squares[-1][0]:,}: {float(np.polyfit(x, y, 1)[0]):.2f}."]  # fmt: skip
    return lines


def _large_files(records: list[dict]) -> list[str]:
    """The table of `test_large_files.py`: ``sparsekin run`` on chains written as small files."""
    lines = [
        "## Large models from small files (`test_large_files.py`, `test_grid_files.py`)",
        "",
        "Each row is one fresh process (`benchmarks/measure_file_run.py`): the example file with another",
        "`count`, read and its pattern built (`setup`), or run through `sparsekin run --quiet` (the time to",
        "the first sample counts from the start of the process, imports included; per sample: after the",
        "first). Peak memory: the process's peak resident set, everything included.",
        "",
        "| case | bodies | file | samples | options | read | pattern | first sample | per sample | peak memory |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for info in records:
        cells = [
            info["case"],
            f"{info['bodies']:,}",
            f"{info['file_bytes'] / 1000:.1f} kB",
            str(info.get("samples", "—")),
            f"`{info['options']}`" if info.get("options") else "",
            _seconds(info["read_seconds"]),
            _seconds(info["pattern_seconds"]) if "pattern_seconds" in info else "—",
            _seconds(info["first_sample_seconds"]) if "first_sample_seconds" in info else "—",
            _seconds(info["seconds_per_sample"]) if "seconds_per_sample" in info else "—",
            f"{info['peak_rss_bytes'] / 2**30:.2f} GB",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _forces(records: list[dict]) -> list[str]:
    """The tables of `test_forces_cost.py`: what the forces cost on top of the kinematics."""
    lines = [
        "## Forces on top of the kinematics (`test_forces_cost.py`)",
        "",
        "Medians over rounds; each ratio divides by the kinematics alone in the same run. Task 5: the whole run",
        "(10 s at 1 ms, compiled loop) of examples/task5_dynamics.toml, without forces and with every driver's",
        "and joint's. `task5_chain` with the same masses on every copy, under gravity: a time step of the",
        "refactorization path, then the same step and the forces of the drivers, or of every driver and joint.",
        "",
        "| model | bodies | forces | time | per step | ratio to kinematics |",
        "|---|---|---|---|---|---|",
    ]
    base = {}
    for info in records:
        steps = info.get("steps_per_round") or (info["samples"] - 1)
        info["per_step"] = info["median"] / steps
        if info["forces"] in ("none", "kinematics"):
            base[(info["family"], info["bodies"])] = info["per_step"]
    for info in records:
        reference = base.get((info["family"], info["bodies"]))
        ratio = f"{info['per_step'] / reference:.2f}×" if reference else "—"
        cells = [info["family"], f"{info['bodies']:,}", info["forces"], _seconds(info["median"]),
                 _seconds(info["per_step"]), ratio]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def mesh_lu_section(records: list[dict]) -> list[str]:
    """`MESH_LU`: every LU option on the lattice's Jacobian, then first sample and step."""
    options = [r for r in records if "option" in r]
    lines = [
        "## Sparse LU on the lattice (issue 29; `measure_mesh_lu.py`, `measure_mesh_steps.py`)",
        "",
        "Not part of the pytest-benchmark run: `benchmarks/mesh_lu.jsonl` holds the lines printed by",
        "`python3 benchmarks/measure_mesh_lu.py lattice BODIES` (one fresh process per size) and",
        "`python3 benchmarks/measure_mesh_steps.py lattice BODIES ...`; the column \"run\" says which session",
        "made the line and the load average then (2 cores shared by six engineers: absolute times move",
        "2× from one minute to the next; compare within one run and size only).",
        "One Jacobian J at t = 0, J x = b solved; pose: the drawing (a third of the lattice's entries exactly",
        "zero), or generic (`--generic`: the drawn coordinates moved by 0.05 × standard normal numbers, no",
        "entry zero, as at a refactorization later in a run). `superlu`: SuperLU with COLAMD on A = Jᵀ,",
        "what `linear_solver=\"superlu\"` does; `dissection`: `DissectionSolver` (what `auto` takes on",
        "meshes), SuperLU on J in a geometric nested dissection of the bodies, numba solves on its",
        "factors; `superlu-metis`: SuperLU on J in METIS's order of the bodies; `refactor-metis`:",
        "`RefactorSolver(ordering=\"metis\")`, what `auto` took on meshes before; `pardiso`: MKL Pardiso",
        "(pypardiso, one thread, a separate install); `supernodal`: `SupernodalSolver`, the multifrontal LU",
        "in numba kernels (BLAS `np.dot` for the fronts' updates, `OPENBLAS_NUM_THREADS=1`) in the same",
        "dissection, its again the numeric factorization on its held analysis. First: everything a",
        "first `factor` does (in",
        "brackets the order alone, timed apart); again: a second `factor` with the same values (a fresh",
        "SuperLU in the held order; `refactor-metis`: the numeric refactorization on its fixed pattern);",
        "solve: median of three; two: one call with two right-hand sides (median of three, runs \"s29kernel\"",
        "on); backward error ‖Jx − b‖∞ / (‖J‖∞‖x‖∞ + ‖b‖∞); L + U: entries held",
        "(SuperLU's count, its supernodes' zeros included; `dissection`: the nonzeros it keeps; the",
        "refactorization's structural pattern; `supernodal`: its dense blocks, zeros included).",
        "",
        "| run | bodies | pose | option | first | again | solve | two | backward error | L + U |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in options:
        again = _seconds(r["refactorization_s"]) if "refactorization_s" in r else "—"
        entries = f"{r['nnz_factors'] / 1e6:.2f} M" if "nnz_factors" in r else "—"
        ordering = f" (order {_seconds(r['ordering_s'])})" if "ordering_s" in r else ""
        two = _seconds(r["solve_two_s"]) if "solve_two_s" in r else "—"
        cells = [r.get("run", "issue 29, first session"), f"{r['bodies']:,}", r.get("pose", "drawing"),
                 f"`{r['option']}`", _seconds(r["first_factorization_s"]) + ordering, again,
                 _seconds(r["solve_s"]), two, f"{r['backward_error']:.1e}", entries]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    steps = [r for r in records if "path" in r]
    if steps:
        lines += [
            "",
            "First sample and time per step (`measure_mesh_steps.py`), one process per size: \"first sample\"",
            "lines as `solve_kinematics` makes it (pattern, stepper, `start` at t = 0) with `auto` (now",
            "`DissectionSolver` on meshes), with `auto` before it (`refactor-start`), with",
            "`linear_solver=\"superlu\"` (`superlu-start`); each round ends with issue 29's reference, one",
            "SuperLU (COLAMD) factorization of the Jacobian at t = 0. Path lines: the harness's stepper",
            "(`sparsekin`: `auto` now; `sparsekin-refactor`: `auto` before; `supernodal`: `SupernodalSolver`,",
            "reused the same way; its first sample solves twice on the reuse path) and the median of three",
            "rounds of four steps; long run (`--long=N`): one run of N steps from t = 0 on the same path, its",
            "refactorizations at moved poses included.",
            "",
            "| run | bodies | what | round | path taken | first sample | per step | solves per step | long run "
            "| peak memory |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in steps:
            first = r.get("first_sample_s", r.get("factorization_s"))
            step = _seconds(r["per_step_s"]) if "per_step_s" in r else "—"
            solves = _seconds(r["split_s"]["solves"]) if "split_s" in r else "—"
            long_run = "—"
            if "long_steps" in r:
                long_run = (f"{r['long_steps']} steps: {_seconds(r['long_mean_step_s'])} a step "
                            f"(solves {_seconds(r['long_split_s']['solves'])}), "
                            f"{r['long_factorizations']} factorizations")  # fmt: skip
            cells = [r.get("run", "issue 29, first session"), f"{r['bodies']:,}", r["path"], str(r.get("round", "—")),
                     r.get("taken", "—"), _seconds(first), step, solves, long_run,
                     f"{r['peak_rss_bytes'] / 2**30:.2f} GB"]  # fmt: skip
            lines.append("| " + " | ".join(cells) + " |")
    return lines


def mesh_reuse_section(records: list[dict]) -> list[str]:
    """`MESH_REUSE`: where a long lattice run's step goes under factorization reuse."""
    lines = [
        "### Long lattice runs under factorization reuse (issue 29; `measure_mesh_reuse.py`)",
        "",
        "`benchmarks/mesh_reuse.jsonl` holds the lines printed by `OPENBLAS_NUM_THREADS=1 PYTHONPATH=TREE",
        "python3 benchmarks/measure_mesh_reuse.py TREE lattice BODIES 150`, the trees alternating in fresh",
        "processes (\"tree\": which checkout's `ReusingSolver`; \"run\": the session, then the load average",
        "at the line's end). 150 steps of `families.STEP` from t = 0 on `auto`'s path (`DissectionSolver`",
        "held by `ReusingSolver`). Factorizations: the inner solver's, at moved poses after the first,",
        "with their mean time; held solves: every solve with the held factors (GMRES's",
        "preconditioner and the direct ones), with their mean time; GMRES: the iteration counts of",
        "the GMRES solves (count × solves; −1 gave up); per factorization held (from t = 0's on): the",
        "solves made with it × their mean time. The trees other than main are main with `ReusingSolver`'s",
        "stale decision replaced (rent or buy, docs/design-notes.md, \"Factorization reuse\"); not kept.",
        "Runs A–D: the first GMRES solve of each process also loaded GMRES's kernels from numba's cache",
        "(0.3–0.7 s, both trees alike: a few ms a step at 10^4, under 1 % at 10^5); from run E on, loaded before.",
        "",
        "| run | tree | bodies | mean step | solves (phase) | factorizations | held solves | solves per step | GMRES "
        "| per factorization held |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in records:
        mean = r["factorization_s"] / max(r["factorizations"], 1)
        held = f"{r['held_solves']} × {_seconds(r['held_solve_s'] / max(r['held_solves'], 1))}"
        gmres = ", ".join(f"{k}×{v}" for k, v in r["gmres_solves_by_iterations"].items())
        epochs = ", ".join(f"{n} × {_seconds(s)}" for n, s in r.get("held_solves_by_factorization", [])) or "—"
        cells = [f"{r['run']}, load {r['load']:.1f}", r["tree_label"], f"{r['bodies']:,}", _seconds(r["mean_step_s"]),
                 _seconds(r["split_s"]["solves"]), f"{r['factorizations']} × {_seconds(mean)}", held,
                 f"{r['solves_per_step']:.2f}", gmres, epochs]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _startup(info: dict) -> list[str]:
    """`test_startup.py`: ``sparsekin run examples/task5.toml`` from the shell, warm and cold."""
    runs = info["runs"]
    lines = [
        "## Start-up (`test_startup.py`)",
        "",
        "`sparsekin run examples/task5.toml` in fresh processes (`benchmarks/measure_startup.py`): medians of",
        f"{len(runs['warm_seconds'])} warm runs (numba's cache filled) and {len(runs['cold_seconds'])} cold runs "
        "(an empty cache: the first run after an install, every kernel compiled).",
        "",
        "| what | median | runs |",
        "|---|---|---|",
        f"| `import sparsekin.cli` | {_seconds(info['import_seconds'])} | "
        + ", ".join(f"{v:.2f}" for v in runs["import_seconds"]) + " |",
        f"| warm run | {_seconds(info['warm_seconds'])} | " + ", ".join(f"{v:.2f}" for v in runs["warm_seconds"]) + " |",
    ]
    if runs["cold_seconds"]:
        lines.append(f"| cold run | {_seconds(info['cold_seconds'])} | "
                     + ", ".join(f"{v:.1f}" for v in runs["cold_seconds"]) + " |")  # fmt: skip
    return lines


def _sweeps(records: list[dict]) -> list[str]:
    """The table of `test_sweep_speed.py`: a Task 5 amplitude sweep, serial and on Dask."""
    serial = next((info for info in records if info["workers"] == 0), None)
    first = records[0]
    lines = [
        "## Design sweeps on Dask (`test_sweep_speed.py`)",
        "",
        f"A Task 5 amplitude sweep: {first['variants']} variants (both amplitudes 0.03 … 0.07 m), each "
        f"{first['samples']} samples over 10 s recording point K. Serial: a Python loop over `solve_kinematics`",
        "in a process with the one BLAS thread Dask gives its workers. Dask: `sparsekin.sweep` on a local cluster",
        "of single-threaded worker processes, started and warmed up before the timing. Parallel efficiency:",
        "serial time / (workers × time).",
        "",
        "| runner | workers | tasks | variants locked up | time | variants/s | parallel efficiency |",
        "|---|---|---|---|---|---|---|",
    ]
    for info in sorted(records, key=lambda info: info["workers"]):
        efficiency = ""
        if serial is not None and info["workers"]:
            efficiency = f"{serial['seconds'] / (info['workers'] * info['seconds']):.0%}"
        cells = [info["runner"], str(info["workers"] or "—"), str(info.get("tasks", "—")), str(info["locked"]),
                 _seconds(info["seconds"]), f"{info['variants_per_second']:.3g}", efficiency]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str]) -> None:
    if argv:
        source = Path(argv[0])
    else:
        subprocess.run(COMMAND.replace("python3", sys.executable, 1).split(), cwd=_HERE.parent, check=True)
        source = _HERE / "results.json"
    target = Path(argv[1]) if len(argv) > 1 else _HERE / "RESULTS.md"
    steps, setups, document = load(source)
    target.write_text(render(steps, setups, document))
    print(f"wrote {target}")


if __name__ == "__main__":
    if len(sys.argv) > 3:
        sys.exit(__doc__)
    main(sys.argv[1:])
