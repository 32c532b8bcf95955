"""What the forces cost on top of the kinematics, each ratio measured in the same run.

* ``test_task5_run``: examples/task5_dynamics.toml over 10 s at 1 ms (the compiled loop),
  without forces and with the forces of every driver and joint;
* ``test_chain_step``: ``task5_chain`` with the masses of examples/task5_dynamics.toml on
  every copy, under gravity: one time step of the refactorization path (positions,
  velocities, accelerations), then the same step and the forces of its drivers only, or
  of every driver and joint (`sparsekin.solve.observers.InverseDynamics` on the stepper's
  `linearization`: one transposed solve, the applied and inertial forces, the reactions).

Issue 11's target: forces cost at most 30 % of the kinematic step, on Task 5 and at 10^6
bodies.  ``--sizes=full`` runs the chain at 10^4 and 10^6 bodies; the smoke size at 100.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sparsekin import load_model, solve_kinematics, testset
from sparsekin.results.recording import Selection
from sparsekin.solve.observers import InverseDynamics
from sparsekin.solve.stepper import KinematicStepper

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "task5_dynamics.toml"
TIMES = np.linspace(0.0, 10.0, 10_001)
STEP = 0.01
CHAIN_SIZES = {"smoke": (100,), "full": (10_000, 1_000_000)}
#: What a step records: nothing, the drivers' forces, every driver's and joint's.
FORCES = {"kinematics": None, "drivers": "drivers", "all": "all"}


@pytest.fixture(scope="module")
def task5_dynamics():
    return load_model(EXAMPLE)


@pytest.mark.parametrize("forces", [None, "all"], ids=["kinematics", "forces"])
def test_task5_run(benchmark, task5_dynamics, forces):
    solve_kinematics(task5_dynamics, TIMES[:3], forces=forces)  # compile outside the timing
    result = benchmark.pedantic(solve_kinematics, args=(task5_dynamics, TIMES), kwargs={"forces": forces},
                                rounds=5, iterations=1)  # fmt: skip
    assert result.complete and result.linear_solver == "compiled"
    benchmark.extra_info.update(family="task5_dynamics", bodies=10, forces=forces or "none", samples=result.n_times,
                                force_columns=len(result.force_labels))  # fmt: skip


def loaded_chain(copies: int):
    """``task5_chain(copies)`` with examples/task5_dynamics.toml's masses on every copy, and its gravity."""
    example = load_model(EXAMPLE)
    masses = {body.name: body for body in example.bodies}
    chain = testset.task5_chain(copies)
    repeat = chain.repeats[0]
    bodies = tuple(replace(body, mass=masses[body.name].mass, inertia=masses[body.name].inertia)
                   for body in repeat.unit.bodies)  # fmt: skip
    return replace(chain, repeats=(replace(repeat, unit=replace(repeat.unit, bodies=bodies)),), gravity=example.gravity)


class _Chain:
    """A stepper on a loaded chain after its first sample, and force solvers for it."""

    def __init__(self, bodies: int) -> None:
        self.mechanism = mechanism = loaded_chain(max(1, bodies // 10))
        self.stepper = stepper = KinematicStepper(mechanism, linear_solver="refactor", forces=True)
        stepper.start(0.0)
        model = stepper.discretization
        drivers = Selection(stepper.discretization, coordinates=False,
                            forces=[f"drivers[{d}]" for d in range(mechanism.n_drivers)])  # fmt: skip
        every = Selection(stepper.discretization, coordinates=False, forces="all")
        self.solvers = {"drivers": InverseDynamics(model, drivers.forces), "all": InverseDynamics(model, every.forces)}
        for solver in self.solvers.values():
            solver(stepper.linearization())  # compile outside the timing

    def steps(self, n: int, forces: str | None) -> None:
        solver = None if forces is None else self.solvers[forces]
        for _ in range(n):
            self.stepper.advance(self.stepper.time + STEP)
            if solver is not None:
                solver(self.stepper.linearization())


_CHAINS: dict[int, _Chain] = {}


def pytest_generate_tests(metafunc):
    if "bodies" in metafunc.fixturenames:
        sizes = CHAIN_SIZES[metafunc.config.getoption("--sizes")]
        metafunc.parametrize("bodies", sizes, ids=[f"{b}bodies" for b in sizes])


@pytest.mark.parametrize("forces", list(FORCES))
def test_chain_step(benchmark, bodies, forces):
    chain = _CHAINS.get(bodies)
    if chain is None:
        _CHAINS.clear()  # one large model in memory at a time
        chain = _CHAINS[bodies] = _Chain(bodies)
    steps = int(min(50, max(2, 200_000 // bodies)))
    benchmark.pedantic(chain.steps, args=(steps, FORCES[forces]), rounds=3, iterations=1)
    benchmark.extra_info.update(family="task5_chain", bodies=chain.mechanism.n_bodies, forces=forces,
                                steps_per_round=steps)  # fmt: skip
