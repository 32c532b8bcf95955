"""Check, set up and step one overconstrained test-set model in a fresh process.

Usage: ``python3 benchmarks/measure_redundancy.py FAMILY SIZE [STEPS]`` with FAMILY one of
`REDUNDANCY_FAMILIES`.  Prints one JSON object: the seconds of building the model, of
`check_model` (rank analysis, Maxwell–Calladine counts, redundant equations named), of the
first sample (`KinematicStepper.start`: the redundant equations found and left out, the
first factorization), the median seconds per step over STEPS steps of 0.01 s, the largest
error of the positions against the closed form, and the peak resident memory of the
process (with the peak before the model was built).
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

_HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(_HERE), str(_HERE.parent)]  # sparsekin when not installed

from sparsekin import check_model, testset  # noqa: E402
from sparsekin.errors import RedundantConstraintWarning  # noqa: E402
from sparsekin.solve.stepper import KinematicStepper  # noqa: E402

#: Family → builder from its size parameter (squares per side, or cells).
REDUNDANCY_FAMILIES = {
    "rotating_squares": testset.rotating_squares,
    "lattice_like_squares": lambda n: testset.lattice(n, max(1, (n - 1) // 2)),  # about n² bodies, no redundancy
    "parallel_bar_chain_3": lambda n: testset.parallel_bar_chain(n, bars=3),
    "parallel_bar_chain_2": lambda n: testset.parallel_bar_chain(n, bars=2),
}
STEP = 0.01


def _peak_rss_bytes() -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmHWM in /proc/self/status")


def _squares_error(coordinates: np.ndarray, n: int, t: float) -> float:
    """Largest position error (m) of the rotating squares against the closed form."""
    exact = testset.rotating_lattice_motion(n, n, [t])[0][0]  # [i, j] = (x, y, angle)
    q = coordinates.reshape(n, n, 3).transpose(1, 0, 2)  # bodies row by row: [j, i]
    return float(np.abs(q[..., :2] - exact[..., :2]).max())


def main(family: str, size: int, steps: int = 5) -> dict:
    with warnings.catch_warnings():  # load the compiled kernels first (the tall LU's from 300 coordinates)
        warnings.simplefilter("ignore", RedundantConstraintWarning)
        small = REDUNDANCY_FAMILIES[family](12 if family.endswith("squares") else 30)
        check_model(small)
        KinematicStepper(small).start(0.0)
    baseline = _peak_rss_bytes()
    start = time.perf_counter()
    mechanism = REDUNDANCY_FAMILIES[family](size)
    built = time.perf_counter()
    report = check_model(mechanism)
    checked = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RedundantConstraintWarning)
        stepper = KinematicStepper(mechanism)
        stepper.start(0.0)
    first = time.perf_counter()
    per_step = []
    for k in range(1, steps + 1):
        begin = time.perf_counter()
        stepper.advance(k * STEP)
        per_step.append(time.perf_counter() - begin)
    error = _squares_error(stepper.coordinates, size, steps * STEP) if family == "rotating_squares" else float("nan")
    return {
        "family": family,
        "size": size,
        "bodies": mechanism.n_bodies,
        "coordinates": report.n_coordinates,
        "equations": report.n_equations,
        "rank": report.rank,
        "redundant": len(report.redundant),
        "left_out": int(stepper.redundant_rows.size),
        "path": stepper.path,
        "build_seconds": built - start,
        "check_seconds": checked - built,
        "first_sample_seconds": first - checked,
        "step_seconds": float(np.median(per_step)),
        "closed_form_error": error,
        "peak_rss_bytes": _peak_rss_bytes(),
        "baseline_rss_bytes": baseline,
    }


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1], int(sys.argv[2]), *map(int, sys.argv[3:]))))
