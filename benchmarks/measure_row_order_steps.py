"""Time per step of an overconstrained model with the tall LU's rows offered in the model's
order (issue 26) against the minimum-degree order of main before it, in one process.

Usage: ``python3 benchmarks/measure_row_order_steps.py [N] [STEPS]`` (rotating squares N×N,
default 100, and 40 steps of 0.01 s).  Two steppers of the same model, one analysed in each
order (the reduced system's refactorization takes the tall LU's pivot order), advanced
alternately, step by step, so that the load of a shared machine falls on both alike; prints
the medians, their ratio, the median of the paired ratios and the factors' entries.
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

sys.path[:0] = [str(Path(__file__).resolve().parent.parent)]  # sparsekin when not installed

from sparsekin import RedundantConstraintWarning, testset  # noqa: E402
from sparsekin.analysis import tall_lu  # noqa: E402
from sparsekin.solve.stepper import KinematicStepper  # noqa: E402


def minimum_degree_row_order(matrix, preference, fill_reducing=False):
    """Main's `row_order` (e7f00d6): SuperLU's multiple minimum degree on A A^T + c I."""
    pattern = sparse.csr_array((np.ones(matrix.nnz), matrix.indices, matrix.indptr), shape=matrix.shape)
    graph = sparse.csc_array(pattern @ pattern.T)
    shifted = graph + sparse.diags_array(np.full(matrix.shape[0], 1.0 + float(graph.sum(axis=0).max())))
    factor = splu(sparse.csc_array(shifted), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options={"SymmetricMode": True})  # fmt: skip
    order = np.argsort(factor.perm_c)
    group = np.digitize(preference[order], (1.0, 2.0))
    return order[np.argsort(group, kind="stable")].astype(np.int64)


def main(n: int = 100, steps: int = 40) -> None:
    warnings.simplefilter("ignore", RedundantConstraintWarning)
    mechanism = testset.rotating_squares(n)
    model_order = KinematicStepper(mechanism)
    model_order.start(0.0)
    own = tall_lu.row_order
    tall_lu.row_order = minimum_degree_row_order
    try:
        minimum_degree = KinematicStepper(mechanism)
        minimum_degree.start(0.0)
    finally:
        tall_lu.row_order = own
    times = {model_order: [], minimum_degree: []}
    for k in range(1, steps + 1):
        pair = (model_order, minimum_degree) if k % 2 else (minimum_degree, model_order)
        for stepper in pair:
            start = time.perf_counter()
            stepper.advance(0.01 * k)
            times[stepper].append(time.perf_counter() - start)
    a, b = np.array(times[model_order]), np.array(times[minimum_degree])
    print(f"rotating squares {n}×{n}, {steps} steps: model's order {1e3 * np.median(a):.2f} ms "
          f"({model_order.linear_solver.nnz_factors} factor entries), minimum degree {1e3 * np.median(b):.2f} ms "
          f"({minimum_degree.linear_solver.nnz_factors}); ratio of medians {np.median(a) / np.median(b):.2f}, "
          f"median of paired ratios {np.median(a / b):.2f}")  # fmt: skip


if __name__ == "__main__":
    main(*map(int, sys.argv[1:]))
