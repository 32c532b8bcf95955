"""Where a long mesh run's step time goes under factorization reuse, for comparing two checkouts
in alternating fresh processes (issue 29: `ReusingSolver`'s refactorization rule).

Usage: ``OPENBLAS_NUM_THREADS=1 PYTHONPATH=TREE python3 benchmarks/measure_mesh_reuse.py TREE
FAMILY BODIES STEPS``, with TREE a checkout (its harness and its sparsekin are used; this file
may come from another).  Runs `harness.Stepper` on path ``sparsekin`` (``"auto"``'s plan: on a
mesh `DissectionSolver` held by `ReusingSolver`) for STEPS steps of `families.STEP` from t = 0,
and prints one JSON object: the mean step and its phases (harness timers), and, counted on the
factorizing solver inside `ReusingSolver` (so the same for every tree), the factorizations and
their seconds, the solves with the held factors and their seconds, the GMRES iterations and the
solves per step, how many GMRES solves took each iteration count, and per held factorization
(the first: t = 0's, made before the run) its solves and their mean time.
"""

from __future__ import annotations

import json
import os
import sys
import time


class _Counted:
    """Forwards to `target`; counts and times its ``factor`` and ``solve``."""

    def __init__(self, target) -> None:
        self._target = target
        self.factor_calls = self.solve_calls = 0
        self.factor_s = self.solve_s = 0.0
        self.epochs = [[0, 0.0]]  # per held factorization: its solves and their seconds

    def __getattr__(self, name):
        return getattr(self._target, name)

    def factor(self, *args, **kwargs):
        result, seconds = _timed(self._target.factor, args, kwargs)
        self.factor_calls += 1
        self.factor_s += seconds
        self.epochs.append([0, 0.0])
        return result

    def solve(self, *args, **kwargs):
        result, seconds = _timed(self._target.solve, args, kwargs)
        self.solve_calls += 1
        self.solve_s += seconds
        self.epochs[-1][0] += 1
        self.epochs[-1][1] += seconds
        return result


def _timed(method, args, kwargs):
    """``method(*args, **kwargs)`` and the seconds it took."""
    start = time.perf_counter()
    result = method(*args, **kwargs)
    return result, time.perf_counter() - start


def _warm_gmres(reusing_solver) -> None:
    """One GMRES solve on a small system: its kernels loaded (or compiled) outside the timings."""
    import numpy as np
    from scipy.sparse import csr_array

    from sparsekin.engine.linalg import RefactorSolver

    matrix = csr_array(np.array([[4.0, 1.0, 0.0], [1.0, 4.0, 1.0], [0.0, 1.0, 4.0]]))
    solver = reusing_solver(RefactorSolver())
    solver.factor(matrix)
    matrix.data[0] = 3.0  # a later Jacobian: solved by GMRES on the held factorization
    solver.factor(matrix)
    solver.solve(np.ones(3))


def main(tree: str, family: str, bodies: int, steps: int) -> None:
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

    Stepper(build(family, 100), "sparsekin", STEP).run(1)  # compile outside the timings
    _warm_gmres(ReusingSolver)
    stepper = Stepper(build(family, bodies), "sparsekin", STEP)
    reusing = stepper.stepper.linear_solver._target
    if not isinstance(reusing, ReusingSolver):
        raise SystemExit(f"path {stepper.path!r}: no ReusingSolver to measure")
    counted = reusing.inner = _Counted(reusing.inner)
    iterations, solves = reusing.n_krylov_iterations, reusing.n_solves
    start = time.perf_counter()
    stepper.run(steps)
    seconds = time.perf_counter() - start
    print(json.dumps({
        "tree": tree, "family": family, "bodies": bodies, "steps": steps, "path": stepper.path,
        "mean_step_s": seconds / steps, "split_s": {phase: s / steps for phase, s in stepper.seconds.items()},
        "factorizations": counted.factor_calls, "factorization_s": counted.factor_s,
        "held_solves": counted.solve_calls, "held_solve_s": counted.solve_s,
        "solves_per_step": (reusing.n_solves - solves) / steps,
        "gmres_iterations": reusing.n_krylov_iterations - iterations,
        "gmres_solves_by_iterations": dict(sorted(histogram.items())),
        "held_solves_by_factorization": [[n, s / max(n, 1)] for n, s in counted.epochs],
        "load": os.getloadavg()[0],
    }), flush=True)  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
