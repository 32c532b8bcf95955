"""The first sample and the time per step of a model on several paths, beside one SuperLU
factorization of its Jacobian, in one fresh process.

Usage: ``python3 benchmarks/measure_mesh_steps.py FAMILY BODIES [PATH ...]`` with paths of
`harness.LINEAR_SOLVERS` or of `FIRST_SAMPLES` (default: ``auto``, ``refactor-start``,
``sparsekin``, ``sparsekin-refactor``).  `FIRST_SAMPLES`: the first sample as
`solve_kinematics` makes it (pattern, stepper, `start` at t = 0) with ``"auto"``'s solver,
``"auto"``'s before issue 29, ``"superlu"``, or SuperLU in METIS's order.  Every other path: the harness's first sample
(`harness.Stepper`, which solves it twice on the reuse path: once more after the switch)
and the median over three rounds of four steps of `families.STEP`, with the split of the
last round.  The reference of issue 29, one SuperLU factorization (COLAMD, what
``linear_solver="superlu"`` does at every Newton iteration) of the Jacobian at the first
sample, is timed after the first samples and again at the end; ``--rounds=R`` repeats the
first samples and the reference R times, interleaved (a loaded machine's times move 2×
from one minute to the next); ``--long=N`` adds to each path's line one run of N steps from
t = 0 (mean step, split, factorizations: the refactorizations at moved poses included).
Prints one JSON object per line, with the peak resident memory so far.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

_HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(_HERE), str(_HERE.parent)]  # the harness, and sparsekin when not installed

from families import STEP, build  # noqa: E402
from harness import BEFORE_DISSECTION, Stepper  # noqa: E402
from measure_mesh_lu import _peak_rss_bytes, jacobian_at_drawing  # noqa: E402

from sparsekin.engine.linalg import SuperLUSolver  # noqa: E402
from sparsekin.solve.options import SolveOptions  # noqa: E402
from sparsekin.solve.stepper import KinematicStepper  # noqa: E402

ROUNDS, STEPS_PER_ROUND = 3, 4


#: First samples as `solve_kinematics` makes them (pattern, stepper, `start` at t = 0): with
#: ``"auto"``; with ``"auto"`` as it was before `DissectionSolver` (``refactor-start``: the
#: METIS-ordered refactorization); with ``linear_solver="superlu"`` (``superlu-start``); and
#: with the linear solver ``superlu-metis`` holds (one factorization; the switch to
#: `ReusingSolver` after it costs nothing).
FIRST_SAMPLES = {
    "auto": lambda: ("auto", None),
    "refactor-start": lambda: ("auto", SolveOptions(thresholds=BEFORE_DISSECTION)),
    "superlu-start": lambda: ("superlu", None),
    "superlu-metis-start": lambda: (SuperLUSolver(ordering="metis"), None),
}


def first_sample(mechanism, name: str) -> dict:
    start = time.perf_counter()
    linear_solver, options = FIRST_SAMPLES[name]()
    stepper = KinematicStepper(mechanism, linear_solver=linear_solver, options=options)
    stepper.start(0.0)
    seconds = time.perf_counter() - start
    return {"path": f"{name}, first sample", "taken": stepper.path, "first_sample_s": seconds,
            "factorizations": stepper.n_factorizations, "solves": stepper.n_solves}  # fmt: skip


def reference_factorization(jacobian, family: str, bodies: int, round_: int) -> dict:
    """Issue 29's reference: one SuperLU factorization (COLAMD) of the Jacobian at t = 0."""
    start = time.perf_counter()
    SuperLUSolver().factor(jacobian)
    return {"family": family, "bodies": bodies, "path": "one SuperLU factorization", "round": round_,
            "factorization_s": time.perf_counter() - start, "peak_rss_bytes": _peak_rss_bytes()}  # fmt: skip


def main(family: str, bodies: int, paths: list[str], rounds: int = 1, long_steps: int = 0) -> None:
    Stepper(build(family, 100), "sparsekin", STEP).run(1)  # compile outside the timings
    mechanism = build(family, bodies)
    jacobian, _, _ = jacobian_at_drawing(family, bodies)
    for round_ in range(rounds):  # the first samples and the reference, interleaved
        for name in [path for path in paths if path in FIRST_SAMPLES]:
            row = first_sample(mechanism, name)
            print(json.dumps(dict(row, family=family, bodies=mechanism.n_bodies, round=round_,
                                  peak_rss_bytes=_peak_rss_bytes())), flush=True)  # fmt: skip
        print(json.dumps(reference_factorization(jacobian, family, mechanism.n_bodies, round_)), flush=True)
    for path in [path for path in paths if path not in FIRST_SAMPLES]:
        start = time.perf_counter()
        stepper = Stepper(mechanism, path, STEP)
        first = time.perf_counter() - start
        rounds_s = []
        for _ in range(ROUNDS):
            stepper.reset()
            start = time.perf_counter()
            stepper.run(STEPS_PER_ROUND)
            rounds_s.append((time.perf_counter() - start) / STEPS_PER_ROUND)
        split = {phase: seconds / STEPS_PER_ROUND for phase, seconds in stepper.seconds.items()}
        row = {"family": family, "bodies": mechanism.n_bodies, "path": path, "taken": stepper.path,
               "first_sample_s": first, "per_step_s": float(np.median(rounds_s)), "split_s": split,
               "step_rounds_s": rounds_s}  # fmt: skip
        if long_steps:  # one run of that many steps from t = 0: the refactorizations at moved poses with it
            stepper.reset()
            counted = stepper.stepper
            factorizations = counted.n_factorizations + counted.n_refactorizations
            start = time.perf_counter()
            stepper.run(long_steps)
            row.update(long_steps=long_steps, long_mean_step_s=(time.perf_counter() - start) / long_steps,
                       long_split_s={phase: seconds / long_steps for phase, seconds in stepper.seconds.items()},
                       long_factorizations=counted.n_factorizations + counted.n_refactorizations - factorizations)  # fmt: skip
        print(json.dumps(dict(row, peak_rss_bytes=_peak_rss_bytes())), flush=True)
        del stepper
    print(json.dumps(reference_factorization(jacobian, family, mechanism.n_bodies, rounds)), flush=True)


if __name__ == "__main__":
    arguments = [argument for argument in sys.argv[3:] if not argument.startswith("--")]
    rounds = [int(argument.split("=")[1]) for argument in sys.argv[3:] if argument.startswith("--rounds=")]
    long_steps = [int(argument.split("=")[1]) for argument in sys.argv[3:] if argument.startswith("--long=")]
    main(sys.argv[1], int(sys.argv[2]), arguments or ["auto", "refactor-start", "sparsekin", "sparsekin-refactor"],
         rounds[-1] if rounds else 1, long_steps[-1] if long_steps else 0)  # fmt: skip
