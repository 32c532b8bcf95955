"""A long lattice run's step against issue 29's per-step figure, for comparing two checkouts in
alternating fresh processes (issue 29: the step once the pose has moved far from the drawing).

Usage: ``OPENBLAS_NUM_THREADS=1 PYTHONPATH=TREE python3 benchmarks/measure_mesh_long.py TREE
BODIES STEPS [--run=LABEL]``, with TREE a checkout (its harness and its sparsekin are used; this
file may come from another).  Runs `harness.Stepper` on path ``sparsekin`` (``"auto"``'s plan:
on a mesh `DissectionSolver` held by `ReusingSolver`) on the lattice of about BODIES bodies for
STEPS steps of `families.STEP` from t = 0 (the rows' drivers have period π s: 150 steps take
every row's first bar 0.3–0.6 rad off the vertical), timing every step, then times issue 29's
reference in the same process: one SuperLU factorization (COLAMD, `SuperLUSolver`, what
``linear_solver="superlu"`` factors) of the Jacobian at t = 0.  Prints one JSON object: the
steps' median, mean (the refactorizations amortized), 90th percentile and largest; the mean
against the reference (issue 29: at most 0.07); counted on the factorizing solver inside
`ReusingSolver` (so the same for every tree): the factorizations (the sample time, their
time, the entries of their factors, and their kind: fresh, numeric on a held pattern, or a
numeric one the guard rejected followed by a fresh one), the solves with the held factors and their mean time per
factorization, the GMRES iterations and how many GMRES solves took each count; the peak
resident memory before and after the reference.
"""

from __future__ import annotations

import json
import os
import sys
import time

import numpy as np


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


def main(tree: str, bodies: int, steps: int, run: str | None) -> None:
    sys.path[:0] = [tree + "/benchmarks", tree]  # the tree's harness and sparsekin
    from families import STEP, build
    from harness import Stepper

    from sparsekin.engine import krylov
    from sparsekin.engine.krylov import ReusingSolver

    histogram, gmres = {}, krylov.fgmres

    def counted_fgmres(*args):  # GMRES's iteration counts, -1 when it gave up
        iterations = gmres(*args)
        histogram[iterations] = histogram.get(iterations, 0) + 1
        return iterations

    krylov.fgmres = counted_fgmres
    Stepper(build("lattice", 100), "sparsekin", STEP).run(3)  # compile, and load GMRES's kernels, outside the timings
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


if __name__ == "__main__":
    arguments = [a for a in sys.argv[1:] if not a.startswith("--run=")]
    labels = [a[len("--run="):] for a in sys.argv[1:] if a.startswith("--run=")]
    main(arguments[0], int(arguments[1]), int(arguments[2]), labels[0] if labels else None)
