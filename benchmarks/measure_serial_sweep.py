"""The serial baseline of `test_sweep_speed.py`: a Python loop over `solve_kinematics`.

Usage: ``python measure_serial_sweep.py N_VARIANTS N_SAMPLES``.  Runs Task 5 with both
actuators' amplitude set to each of ``linspace(0.03, 0.07, N_VARIANTS)`` over 0 … 10 s
(N_SAMPLES samples), recording point K as the sweep does, after one warm-up run; prints
JSON: the loop's seconds and the variants that locked up.  `test_sweep_speed.py` starts
it with the environment Dask gives its worker processes (one BLAS thread), so that the
baseline and the workers run the same code the same way.
"""

import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

import sparsekin as sk

TASK5 = Path(__file__).resolve().parent.parent / "examples" / "task5.toml"


def main(n_variants: int, n_samples: int) -> dict:
    task5 = sk.load_model(TASK5)
    times = np.linspace(0.0, 10.0, n_samples)
    variants = [
        dataclasses.replace(
            task5,
            drivers=tuple(
                dataclasses.replace(d, law=dataclasses.replace(d.law, amplitude=a)) for d in task5.drivers
            ),
        )  # fmt: skip
        for a in np.linspace(0.03, 0.07, n_variants)
    ]
    sk.solve_kinematics(variants[0], times[:50], coordinates=False, points=["K"])  # warm-up (numba's cache)
    locked = 0
    start = time.perf_counter()
    for variant in variants:
        try:
            sk.solve_kinematics(variant, times, coordinates=False, points=["K"])
        except sk.ConvergenceError:
            locked += 1
    return {"seconds": time.perf_counter() - start, "variants": n_variants, "locked": locked}


if __name__ == "__main__":
    print(json.dumps(main(int(sys.argv[1]), int(sys.argv[2]))))
