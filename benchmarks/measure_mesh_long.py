"""A long lattice run's step against issue 29's per-step figure, for comparing two checkouts in
alternating fresh processes (issue 29: the step once the pose has moved far from the drawing).

Usage: ``OPENBLAS_NUM_THREADS=1 PYTHONPATH=TREE python3 benchmarks/measure_mesh_long.py TREE
BODIES STEPS [--run=LABEL]``, with TREE a checkout (its harness and its sparsekin are used; this
file may come from another).  Runs `harness.Stepper` on path ``sparsekin`` (``"auto"``'s plan:
on a mesh `DissectionSolver` held by `ReusingSolver`) on the lattice of about BODIES bodies for
STEPS steps of `families.STEP` from t = 0 (the rows' drivers have period π s: in 150 steps each
row's first bar turns up to 0.3–0.6 rad from the vertical, depending on its phase), timing every
step, then times issue 29's reference in the same process: one SuperLU factorization (COLAMD,
`SuperLUSolver`, what ``linear_solver="superlu"`` factors) of the Jacobian at t = 0.  Prints one
JSON object: the steps' median, mean (the refactorizations amortized), 90th percentile and
largest; the mean against the reference (issue 29: at most 0.07); counted on the factorizing
solver inside `ReusingSolver` (so the same for every tree): the factorizations (the sample time,
their time, the entries of their factors, and their kind: fresh, numeric on a held pattern, or
a numeric one the guard rejected followed by a fresh one), the solves with the held factors and
their mean time per factorization, the GMRES iterations and how many GMRES solves took each
count; the peak resident memory before and after the reference.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

#: Lines printed by this script (kept by hand; `make_results.py` writes their table).
MESH_LONG = Path(__file__).resolve().parent / "mesh_long.jsonl"


class _Counted:
    """Forwards to `target`; counts and times its ``factor`` and ``solve``, per held factorization."""

    def __init__(self, target, clock) -> None:
        self._target = target
        self._clock = clock  # the run's time, read at each factorization
        self.factorizations = []  # per factorization: sample time, seconds, entries of L + U
        self.epochs = [[0, 0.0]]  # per held factorization (t = 0's first): its solves and their seconds

    def __getattr__(self, name):
        return getattr(self._target, name)

    def factor(self, *args, **kwargs):
        before = self._kinds()
        result, seconds = _timed(self._target.factor, args, kwargs)
        numeric, fallback = (after - b for after, b in zip(self._kinds(), before))
        kind = "fallback" if fallback else "numeric" if numeric else "fresh"
        entries = getattr(self._target, "nnz_factors", None)
        self.factorizations.append([round(self._clock(), 6), seconds, entries, kind])
        self.epochs.append([0, 0.0])
        return result

    def _kinds(self):
        """The target's numeric refactorizations and rejected ones, so far."""
        return getattr(self._target, "n_refactorizations", 0), getattr(self._target, "n_fallbacks", 0)

    def solve(self, *args, **kwargs):
        result, seconds = _timed(self._target.solve, args, kwargs)
        self.epochs[-1][0] += 1
        self.epochs[-1][1] += seconds
        return result


def _timed(method, args, kwargs):
    """``method(*args, **kwargs)`` and the seconds it took."""
    start = time.perf_counter()
    result = method(*args, **kwargs)
    return result, time.perf_counter() - start


def _peak_rss_gb() -> float:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 2**20
    return 0.0


def _superlu_at_drawing(mechanism) -> float:
    """Seconds of one SuperLU (COLAMD) factorization of `mechanism`'s Jacobian at t = 0."""
    from sparsekin.engine.assembly import Assembler
    from sparsekin.engine.discretization import Discretization
    from sparsekin.engine.linalg import SuperLUSolver
    from sparsekin.engine.pattern import build_pattern

    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    solver = SuperLUSolver()
    start = time.perf_counter()
    solver.factor(assembler.jacobian)
    return time.perf_counter() - start


def _warm_mesh_kernels() -> None:
    """`auto`'s mesh path on a small lattice, at the drawing and three perturbed poses, the
    last two refactored: its kernels loaded (or compiled) outside the timings (the 100-body
    warm-up run takes the dense path)."""
    from families import build

    from sparsekin.engine.assembly import Assembler
    from sparsekin.engine.discretization import Discretization
    from sparsekin.engine.dissection import DissectionSolver
    from sparsekin.engine.krylov import ReusingSolver
    from sparsekin.engine.pattern import build_pattern

    mechanism = build("lattice", 200)
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    q = pattern.initial_coordinates
    solver = ReusingSolver(DissectionSolver(q.reshape(-1, 3)[:, :2].copy()), refactor_iterations=0)
    rng = np.random.default_rng(0)
    # the last two refactored (numerically if the tree can)
    moved = [q + 0.01 * rng.standard_normal(q.size) for _ in range(3)]
    for pose in (q, *moved):
        assembler.fill_residual_jacobian(pose)
        solver.factor(assembler.jacobian)
        b = np.ones(q.size)
        solver.solve(b)
        solver.solve(b, transposed=True)
        solver.solve_held(b)


def main(tree: str, bodies: int, steps: int, run: str | None) -> None:
    sys.path[:0] = [tree + "/benchmarks", tree]  # the tree's harness and sparsekin
    from families import STEP, build
    from harness import Stepper

    from sparsekin.engine import krylov
    from sparsekin.engine.krylov import ReusingSolver

    histogram, gmres = {}, krylov.fgmres

    def counted_fgmres(*args, **kwargs):  # GMRES's iteration counts, -1 when it gave up
        iterations = gmres(*args, **kwargs)
        histogram[iterations] = histogram.get(iterations, 0) + 1
        return iterations

    krylov.fgmres = counted_fgmres
    # compile, and load GMRES's kernels, outside the timings
    Stepper(build("lattice", 100), "sparsekin", STEP).run(3)
    _warm_mesh_kernels()
    histogram.clear()
    mechanism = build("lattice", bodies)
    stepper = Stepper(mechanism, "sparsekin", STEP)
    reusing = stepper.stepper.linear_solver._target
    if not isinstance(reusing, ReusingSolver):
        raise SystemExit(f"path {stepper.path!r}: no ReusingSolver to measure")
    counted = reusing.inner = _Counted(reusing.inner, lambda: stepper.time)
    iterations, solves = reusing.n_krylov_iterations, reusing.n_solves
    seconds = []
    for _ in range(steps):
        start = time.perf_counter()
        stepper.run(1)
        seconds.append(time.perf_counter() - start)
    peak_run = _peak_rss_gb()
    load_run = os.getloadavg()[0]
    superlu_s = _superlu_at_drawing(mechanism)
    seconds = np.array(seconds)
    print(json.dumps({
        "run": f"{run}, load {load_run:.2f}" if run else None, "tree": tree, "family": "lattice",
        "bodies": mechanism.n_bodies, "steps": steps, "t_end": round(stepper.time, 6), "path": stepper.path,
        "median_step_s": float(np.median(seconds)), "mean_step_s": float(seconds.mean()),
        "p90_step_s": float(np.percentile(seconds, 90)), "max_step_s": float(seconds.max()),
        "superlu_t0_s": superlu_s, "mean_over_superlu": float(seconds.mean()) / superlu_s,
        "split_s": {phase: s / steps for phase, s in stepper.seconds.items()},
        "factorizations": counted.factorizations,
        "held_solves": sum(n for n, _ in counted.epochs),
        "held_solves_by_factorization": [[n, s / max(n, 1)] for n, s in counted.epochs],
        "solves_per_step": (reusing.n_solves - solves) / steps,
        "gmres_iterations": reusing.n_krylov_iterations - iterations,
        "gmres_solves_by_iterations": dict(sorted(histogram.items())),
        "peak_gb_run": peak_run, "peak_gb": _peak_rss_gb(), "load_end": os.getloadavg()[0],
    }), flush=True)  # fmt: skip


def _seconds(value: float) -> str:
    """A duration with a unit that keeps three significant digits."""
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6)):
        if value >= scale:
            return f"{value / scale:.3g} {unit}"
    return f"{value / 1e-9:.3g} ns"


_KIND_LETTERS = {"fresh": "f", "numeric": "n", "fallback": "b"}


def results_section(records: list[dict]) -> list[str]:
    """`MESH_LONG`'s table for benchmarks/RESULTS.md."""
    lines = [
        "### Long lattice runs against issue 29's per-step figure (`measure_mesh_long.py`)",
        "",
        "`benchmarks/mesh_long.jsonl` holds the lines printed by `OPENBLAS_NUM_THREADS=1 PYTHONPATH=TREE python3",
        "benchmarks/measure_mesh_long.py TREE BODIES STEPS --run=LABEL`, the trees alternating in fresh processes",
        "(\"run\": the label and the load average at the run's end; \"tree\": main's checkout or this branch's).",
        "STEPS steps of `families.STEP` from t = 0 on `auto`'s path (`DissectionSolver` held by `ReusingSolver`),",
        "every step timed: median and mean (the refactorizations at moved poses amortized); \"/ SuperLU\": the",
        "mean over one SuperLU (COLAMD) factorization of the Jacobian at t = 0 timed in the same process after",
        "the run (issue 29 asks at most 0.07 at 10^6 bodies); factorizations after t = 0's: sample time, kind",
        "(fresh SuperLU, numeric on the held pattern), time and entries of L + U; held solves: per held",
        "factorization from t = 0's on, solves × mean time; GMRES: iteration count × solves (−1 gave up);",
        "peak: resident memory after the run (and after the reference).",
        "",
        "| run | tree | bodies | steps | median step | mean step | / SuperLU | factorizations | held solves "
        "| solves per step | GMRES | peak |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in records:
        factorizations = "; ".join(
            f"{f[0]:g} s {_KIND_LETTERS[f[3]]} {_seconds(f[1])} {f[2] / 1e6:.2f} M" for f in r["factorizations"]
        ) or "—"  # fmt: skip
        held = ", ".join(f"{n} × {_seconds(s)}" for n, s in r["held_solves_by_factorization"])
        gmres = ", ".join(f"{k}×{v}" for k, v in r["gmres_solves_by_iterations"].items())
        cells = [r["run"] or "—", r.get("tree_label", r["tree"]), f"{r['bodies']:,}", str(r["steps"]),
                 _seconds(r["median_step_s"]), _seconds(r["mean_step_s"]),
                 f"{r['mean_over_superlu']:.3f} (of {_seconds(r['superlu_t0_s'])})", factorizations, held,
                 f"{r['solves_per_step']:.2f}", gmres, f"{r['peak_gb_run']:.2f} GB ({r['peak_gb']:.2f} GB with the reference)"]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "Kinds: f fresh SuperLU; n numeric on the held pattern; b a numeric one the guard rejected, "
              "then SuperLU."]
    return lines


if __name__ == "__main__":
    arguments = [a for a in sys.argv[1:] if not a.startswith("--run=")]
    labels = [a[len("--run="):] for a in sys.argv[1:] if a.startswith("--run=")]
    main(arguments[0], int(arguments[1]), int(arguments[2]), labels[0] if labels else None)
