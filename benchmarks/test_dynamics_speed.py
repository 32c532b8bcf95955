"""Forward dynamics per step: the N-four-bar chain (dynamic against kinematic, same run), Task 5.

* `test_chain_step` — the IFToMM N-four-bar (`sparsekin.testset.n_four_bar`, masses, gravity,
  released) stepped by `GeneralizedAlphaStepper` at 1 ms, and its kinematic twin
  (`four_bar_chain`, one driver, same bodies and joints) stepped by `KinematicStepper` at
  1 ms, in the same run: the ratio is the cost of a dynamic step in kinematic steps.
* `test_task5_step` — Task 5 with masses, its drivers replaced by actuators pushing with
  constant forces (a student's linkage under forces), per step at 1 ms.

Smoke sizes in the test suite (one round); the full sizes with ``--sizes=full``:
``python3 -m pytest benchmarks/test_dynamics_speed.py --benchmark-enable --benchmark-only
--sizes=full --benchmark-json=benchmarks/dynamics.json``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import sparsekin as sk
from sparsekin.solve.dynamics import GeneralizedAlphaStepper
from sparsekin.solve.stepper import KinematicStepper
from sparsekin.testset import four_bar_chain, n_four_bar

STEP = 1e-3
#: Windows of the chain (2 n + 1 bodies): smoke, and the full sizes 10^3 to 10^5 bodies.
CHAIN_LOOPS = {"smoke": [20], "full": [500, 5_000, 50_000]}
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def pytest_generate_tests(metafunc):
    if "loops" in metafunc.fixturenames:
        loops = CHAIN_LOOPS[metafunc.config.getoption("--sizes")]
        metafunc.parametrize("loops", loops, ids=[f"{2 * n + 1}bodies" for n in loops])


class _Dynamic:
    def __init__(self, mechanism) -> None:
        self.stepper = GeneralizedAlphaStepper(mechanism, STEP)
        self.stepper.start(0.0)
        self.stepper.advance(2 * STEP)  # the first factorization and the chord matrix

    def steps(self, n: int) -> None:
        stepper = self.stepper
        stepper.advance(stepper.state.time + n * STEP)


class _Kinematic:
    def __init__(self, mechanism) -> None:
        self.stepper = KinematicStepper(mechanism)
        self.stepper.start(0.0)
        self.stepper.advance(STEP)

    def steps(self, n: int) -> None:
        stepper = self.stepper
        for _ in range(n):
            stepper.advance(stepper.time + STEP)


_RUNS: dict[tuple[str, int], object] = {}


@pytest.mark.parametrize("analysis", ["dynamic", "kinematic"])
def test_chain_step(benchmark, loops, analysis):
    key = (analysis, loops)
    if key not in _RUNS:
        _RUNS.clear()  # one large model in memory at a time
        _RUNS[key] = _Dynamic(n_four_bar(loops)) if analysis == "dynamic" else _Kinematic(four_bar_chain(loops, 1.5))
    run = _RUNS[key]
    steps = int(min(50, max(2, 100_000 // loops)))
    benchmark.pedantic(run.steps, args=(steps,), rounds=3, iterations=1)
    benchmark.extra_info.update(family="n_four_bar", bodies=2 * loops + 1, analysis=analysis, steps_per_round=steps)


def test_task5_step(benchmark):
    mechanism = sk.load_model(EXAMPLES / "task5_dynamics.toml")
    pushed = dataclasses.replace(mechanism, drivers=[], loads=[*mechanism.loads, sk.Actuator("actuator1", 400.0),
                                                               sk.Actuator("actuator2", 300.0)])  # fmt: skip
    run = _Dynamic(pushed)
    benchmark.pedantic(run.steps, args=(100,), rounds=5, iterations=1)
    benchmark.extra_info.update(family="task5_dynamics", bodies=10, steps_per_round=100)
