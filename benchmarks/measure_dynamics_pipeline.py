"""Speed of `solve_dynamics` on the run pipeline: medians of five runs per case, one process.

Forward dynamics moved from its own recording loop onto the generic run driver (a
`Stepper` under `SampleSteps`, forces by `ForceOutputs.fill`, energy and drift as schema
rows).  Two cases, each after a warm-up run in the same process:

* ``n_four_bar(2)`` (5 bars), 1001 output samples at 1 ms, ``max_step`` 1 ms: one
  integration step per sample, so the per-sample cost of the pipeline shows most;
* ``n_four_bar(300)`` (601 bars, the refactorization path), 51 samples.

Interleave two trees in fresh processes from a shell, e.g. (an export of the tree before,
then this one)::

    for r in 1 2 3; do for tree in /tmp/before /tmp/after; do
        (cd $tree && PYTHONPATH=$PWD python3 benchmarks/measure_dynamics_pipeline.py); done; done

prints ``case: median seconds`` per line.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

import sparsekin as sk
from sparsekin.testset import n_four_bar

CASES = ((2, 1001), (300, 51))


def main() -> None:
    warnings.simplefilter("ignore")
    for loops, samples in CASES:
        model = n_four_bar(loops)
        times = np.linspace(0.0, 1e-3 * (samples - 1), samples)
        sk.solve_dynamics(model, times[:3], max_step=1e-3)  # compile and warm
        walls = []
        for _ in range(5):
            start = time.perf_counter()
            result = sk.solve_dynamics(model, times, max_step=1e-3)
            walls.append(time.perf_counter() - start)
        print(f"n_four_bar({loops}) {samples} samples {result.linear_solver}: {np.median(walls):.4f}")


if __name__ == "__main__":
    main()
