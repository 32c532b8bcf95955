"""Build, set up and step one test-set model in a fresh process; print what it cost.

Usage: ``python3 benchmarks/measure_setup.py FAMILY BODIES``.  Prints one JSON object:
the seconds spent building the model, computing its pattern and solving the first sample
(model to pattern to first factorization), and the process's peak resident memory after
two time steps (Linux), with the peak of the same process before the model was built (the
interpreter, numpy, scipy, numba and the compiled kernels), so that their difference is
what the model costs.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(_HERE), str(_HERE.parent)]  # the harness, and sparsekin when not installed

from families import STEP, build  # noqa: E402
from harness import Stepper  # noqa: E402

from sparsekin import testset  # noqa: E402
from sparsekin.engine.pattern import build_pattern  # noqa: E402


def _peak_rss_bytes() -> int:
    """Peak resident memory of this process (VmHWM).

    Not ``getrusage``'s ``ru_maxrss``: Linux carries that over from the parent across
    fork and exec, so a child of a large pytest process would report the parent's size.
    """
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024  # kB
    raise RuntimeError("no VmHWM in /proc/self/status")


def main(family: str, bodies: int) -> dict:
    Stepper(testset.task5(), "sparsekin", STEP).run(1)  # load the compiled kernels
    baseline = _peak_rss_bytes()
    start = time.perf_counter()
    mechanism = build(family, bodies)
    built = time.perf_counter()
    build_pattern(mechanism)
    patterned = time.perf_counter()
    stepper = Stepper(mechanism, "sparsekin", STEP)
    ready = time.perf_counter()
    stepper.run(2)
    return {
        "family": family,
        "bodies": mechanism.n_bodies,
        "build_seconds": built - start,
        "pattern_seconds": patterned - built,
        "first_sample_seconds": ready - patterned,
        "peak_rss_bytes": _peak_rss_bytes(),
        "baseline_rss_bytes": baseline,
    }


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1], int(sys.argv[2]))))
