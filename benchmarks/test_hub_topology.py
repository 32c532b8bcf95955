"""Many legs on one crankshaft body (a hub, a star) against the same legs in a chain (issue 27).

`jansen.jansen_machine` (tests/jansen.py): `count` Jansen legs whose cranks are welded to one crankshaft
body, or each to the previous one; the same bodies and equations.  Per step: the median of
`ROUNDS` rounds of `STEPS` full steps of `KinematicStepper` (what `solve_kinematics` runs at
this size: refactorization, chord Newton), from the same solved first sample, both
topologies in the same run; the ratio hub / chain is in ``extra_info`` (target ≤ 1.5).
The hub's coordinates are eliminated last (`sparsekin.engine.ordering.hub_last_ordering`);
before, SuperLU's order made the hub 30–50× slower.

The test suite runs it once at the smoke size (10 legs); ``--sizes=full`` at 1000.
"""

from __future__ import annotations

import time

import numpy as np
from jansen import jansen_machine, jansen_points

from sparsekin.engine.pattern import build_point_map
from sparsekin.model.geometry import to_global
from sparsekin.solve.stepper import KinematicStepper

#: Legs per ``--sizes``.
LEGS = {"smoke": 10, "full": 1000}
#: Time steps per round, and rounds.
STEPS, ROUNDS = 20, 5
#: Time step, s (a crank at 1 rad/s).
DT = 0.01


def _per_step(mechanism) -> tuple[float, KinematicStepper]:
    """Median time of a step over `ROUNDS` rounds of `STEPS` steps from the first sample."""
    stepper = KinematicStepper(mechanism)
    stepper.start(0.0)
    first = (stepper.coordinates.copy(), stepper.velocities.copy(), stepper.accelerations.copy())
    rounds = []
    for _ in range(ROUNDS):
        stepper.start_from(0.0, *first, first=(0.0, first[0]))
        start = time.perf_counter()
        for k in range(1, STEPS + 1):
            stepper.advance(k * DT)
        rounds.append((time.perf_counter() - start) / STEPS)
    return float(np.median(rounds)), stepper


def test_hub_against_chain(benchmark, request):
    count = LEGS[request.config.getoption("--sizes")]

    def measure():
        measured = {}
        for topology in ("chain", "hub"):
            mechanism = jansen_machine(count, topology)
            seconds, stepper = _per_step(mechanism)
            body, local = build_point_map(mechanism).locate(f"u{count - 1}.G")  # the last leg's foot
            foot = to_global(stepper.coordinates.reshape(-1, 3)[body : body + 1], local[None])[0]
            measured[topology] = {"seconds_per_step": seconds, "bodies": mechanism.n_bodies,
                                  "linear_solver": stepper.linear_solver.name, "foot": foot}  # fmt: skip
        return measured

    measured = benchmark.pedantic(measure, rounds=1, iterations=1)
    hub, chain = measured["hub"], measured["chain"]
    exact = jansen_points(0.3 + STEPS * DT)["G"][0]  # circle intersections
    for topology in (hub, chain):
        np.testing.assert_allclose(topology.pop("foot"), exact, rtol=0.0, atol=1e-9)
    benchmark.extra_info.update({"legs": count, "hub": hub, "chain": chain,
                                 "ratio": hub["seconds_per_step"] / chain["seconds_per_step"]})  # fmt: skip
