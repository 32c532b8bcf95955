"""Time per full step of the test-set families, sparsekin against two baselines.

For every family and size (`families.SIZES`) and every linear solver of
`harness.LINEAR_SOLVERS`, `test_time_step` times `harness.Stepper.run` over
`families.steps_per_round` steps of `families.STEP` s from the same solved first sample,
and records the split into assembly, factorization and solves and the Newton iterations
per step.  `test_setup_and_memory` builds, sets up and steps each sparsekin model in a
fresh process and records the build and pattern times and the peak memory.

Full run (documented in benchmarks/README.md, 8 minutes):
``python3 -m pytest benchmarks --benchmark-enable --benchmark-only --sizes=full
--benchmark-json=benchmarks/results.json`` then
``python3 benchmarks/make_results.py benchmarks/results.json``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from families import (
    DENSE_MAX_BODIES,
    MESH_BASELINE_MAX_BODIES,
    MESHES,
    SIZES,
    SMOKE_MAX_BODIES,
    STEP,
    build,
    steps_per_round,
)
from harness import LINEAR_SOLVERS, PHASES, Stepper

#: SuperLU in METIS's order and "auto" before `DissectionSolver` (issue 29) run on meshes
#: from here, where "sparsekin" takes `DissectionSolver` (`MIN_DISSECTION_COORDINATES`).
MIN_MESH_COMPARISON_BODIES = 10_000
#: Timed rounds per benchmark, fewer for the slow ones.
ROUNDS_BELOW_1E5, ROUNDS_FROM_1E5 = 5, 3


def _cases(config, solver_names):
    full = config.getoption("--sizes") == "full"
    for family, sizes in SIZES.items():
        for bodies in sizes:
            if not full and bodies > SMOKE_MAX_BODIES:
                continue
            for solver in solver_names:
                if solver == "dense" and bodies > DENSE_MAX_BODIES:
                    continue
                if solver != "sparsekin" and family in MESHES and bodies > MESH_BASELINE_MAX_BODIES:
                    continue
                if solver in ("superlu-metis", "sparsekin-refactor", "supernodal") and (
                    family not in MESHES or bodies < MIN_MESH_COMPARISON_BODIES
                ):
                    continue  # meshes only, where "sparsekin" takes the mesh solver
                yield pytest.param(family, bodies, solver, id=f"{family}-{bodies}-{solver}")


def pytest_generate_tests(metafunc):
    if metafunc.function is test_time_step:
        metafunc.parametrize("family, bodies, solver", list(_cases(metafunc.config, LINEAR_SOLVERS)))
    elif metafunc.function is test_setup_and_memory:
        cases = [(case.values[0], case.values[1]) for case in _cases(metafunc.config, ["sparsekin"])]
        metafunc.parametrize("family, bodies", cases, ids=[f"{f}-{b}" for f, b in cases])


_models: dict[tuple[str, int], object] = {}


def _model(family: str, bodies: int):
    """One model per family and size for the whole session (the largest take seconds)."""
    key = (family, bodies)
    if key not in _models:
        _models.clear()  # keep one at a time: a 10^6-body model takes a few GB
        _models[key] = build(family, bodies)
    return _models[key]


def test_time_step(benchmark, family, bodies, solver):
    mechanism = _model(family, bodies)
    stepper = Stepper(mechanism, solver, STEP)
    n_steps = steps_per_round(mechanism.n_bodies, solver)
    rounds = ROUNDS_BELOW_1E5 if mechanism.n_bodies < 100_000 else ROUNDS_FROM_1E5
    stepper.run(1)  # warm up: the first Newton step after the start, caches
    benchmark.pedantic(stepper.run, args=(n_steps,), setup=stepper.reset, rounds=rounds, iterations=1)
    # The split and the counts are those of the last round.
    assert np.all(np.isfinite(stepper.coordinates))
    benchmark.extra_info.update(
        family=family,
        bodies=mechanism.n_bodies,
        coordinates=stepper.pattern.n_coordinates,
        solver=solver,
        path=stepper.path,
        steps_per_round=n_steps,
        newton_iterations_per_step=stepper.newton_iterations / n_steps,
        **{f"{phase}_seconds_per_step": stepper.seconds[phase] / n_steps for phase in PHASES},
    )


def test_setup_and_memory(benchmark, family, bodies):
    _models.clear()  # the child's figures are its own, but a smaller parent forks faster
    script = Path(__file__).resolve().parent / "measure_setup.py"

    def measure():
        output = subprocess.run(
            [sys.executable, str(script), family, str(bodies)], check=True, capture_output=True, text=True
        )
        return json.loads(output.stdout)

    measured = benchmark.pedantic(measure, rounds=1, iterations=1)
    assert measured["peak_rss_bytes"] >= measured["baseline_rss_bytes"]
    benchmark.extra_info.update(measured)
