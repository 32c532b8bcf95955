"""The guard's fallback on the N-four-bar chain's saddle: new pivots against SuperLU afresh.

Issue 25: when the guard of `RefactorSolver` rejects the held pivots (the chain's flat
crossing), the solver chooses new rows on the held column order by threshold partial
pivoting (`_pivoting_kernels.partial_pivoting_rows`); before, it ran SuperLU afresh, whose
factors came on top of the run's arrays (the 10^6 run's peak).  This script runs the
forward dynamics of the chain for 5 steps, forces one fallback on the last step's
iteration matrix in the way MODE says, then runs 3 more steps:

* ``new`` — `RefactorSolver._new_pivots` (what the guard does now);
* ``superlu`` — `RefactorSolver._fresh_factor` (what it did before).

It prints one JSON line: CPU seconds of the fallback, the process's peak (ru_maxrss) and
resident memory before and after it and 3 steps later, the factors' entries, and the
backward error of a solve with the new factors.  Run each mode in its own process (the peak is the process's)::

    python3 benchmarks/measure_new_pivots.py --bodies 100001 --mode new
    python3 benchmarks/measure_new_pivots.py --bodies 100001 --mode superlu

(10^6 bodies take ~3 GB: under the team's lock.)
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time

import numpy as np


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def resident_mb() -> float:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def measure(bodies: int, mode: str) -> dict:
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper
    from sparsekin.testset import n_four_bar

    stepper = GeneralizedAlphaStepper(n_four_bar((bodies - 1) // 2), 1e-3)
    stepper.start(0.0)
    solver, matrices = stepper.solver, []
    factor = solver.factor
    solver.factor = lambda matrix: (matrices.append(matrix), factor(matrix))[1]
    for k in range(1, 6):
        stepper.advance(k * 1e-3)
    matrix = matrices[-1]
    before = {"peak_mb": peak_mb(), "resident_mb": resident_mb(), "factor_entries": solver.nnz_factors}
    start = time.process_time()
    if mode == "new":
        solver._new_pivots(matrix.data, False)
    else:
        solver._fresh_factor(matrix.T)
    cpu = time.process_time() - start
    after = {"peak_mb": peak_mb(), "resident_mb": resident_mb(), "factor_entries": solver.nnz_factors}
    rhs = np.random.default_rng(0).standard_normal(matrix.shape[0])
    x = solver.solve(rhs)
    residual = matrix @ x - rhs
    norm = max(abs(matrix[start : start + 65536]).sum(axis=1).max() for start in range(0, matrix.shape[0], 65536))
    backward = float(np.abs(residual).max() / (norm * np.abs(x).max() + np.abs(rhs).max()))
    for k in range(6, 9):
        stepper.advance(k * 1e-3)
    three_steps_later = peak_mb()
    return {"bodies": bodies, "mode": mode, "fallback_cpu_seconds": cpu, "before": before, "after": after,
            "peak_after_3_steps_mb": three_steps_later, "backward_error": backward, "load": os.getloadavg()[0]}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", type=int, default=100001)
    parser.add_argument("--mode", choices=("new", "superlu"), default="new")
    arguments = parser.parse_args()
    print(json.dumps(measure(arguments.bodies, arguments.mode)))


if __name__ == "__main__":
    main()
