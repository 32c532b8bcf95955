"""Time per step of chains and overconstrained families on ``"auto"``'s path, for comparing two
checkouts in alternating fresh processes (issue 29: they must not change).

Usage: ``PYTHONPATH=TREE python3 benchmarks/measure_against_tree.py TREE [MODEL ...]``, with TREE
a checkout (its benchmarks' harness and its sparsekin are used), run alternately for the two
trees (default: the models below 10^6 bodies).  Prints per model the harness's first sample and the median of five rounds of ten
steps of `families.STEP` (`harness.Stepper`, path ``sparsekin``), one JSON object a line.
"""

from __future__ import annotations

import json
import sys
import time
import warnings

import numpy as np

#: The models, by name, made from the tree's `families.build` and `sparsekin.testset`.
MODELS = {
    "task5_chain_1e4": lambda build, testset: build("task5_chain", 10_000),
    "four_bar_chain_1e4": lambda build, testset: build("four_bar_chain", 10_000),
    "task5_chain_1e6": lambda build, testset: build("task5_chain", 1_000_000),
    "four_bar_chain_1e6": lambda build, testset: build("four_bar_chain", 1_000_000),
    "rotating_squares_60": lambda build, testset: testset.rotating_squares(60),
    "parallel_bar_chain_1e3": lambda build, testset: testset.parallel_bar_chain(1000),
}
ROUNDS, STEPS_PER_ROUND = 5, 10


def main(tree: str, names: list[str]) -> None:
    sys.path[:0] = [tree + "/benchmarks", tree]  # the tree's harness and sparsekin (read at run time, not at import)
    from families import STEP, build
    from harness import Stepper

    from sparsekin import testset

    warnings.simplefilter("ignore")  # the overconstrained models' redundancy warnings
    Stepper(build("task5_chain", 100), "sparsekin", STEP).run(1)  # compile outside the timings
    for name in names:
        mechanism = MODELS[name](build, testset)
        start = time.perf_counter()
        stepper = Stepper(mechanism, "sparsekin", STEP)
        first = time.perf_counter() - start
        rounds = []
        for _ in range(ROUNDS):
            stepper.reset()
            start = time.perf_counter()
            stepper.run(STEPS_PER_ROUND)
            rounds.append((time.perf_counter() - start) / STEPS_PER_ROUND)
        print(json.dumps({"tree": tree, "model": name, "path": stepper.path, "first_s": first,
                          "per_step_s": float(np.median(rounds))}), flush=True)  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:] or [name for name in MODELS if not name.endswith("1e6")])
