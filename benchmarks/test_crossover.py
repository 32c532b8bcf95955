"""Where the compiled dense loop stops paying: `solve_kinematics` with ``"dense"`` and
``"refactor"`` on small members of the test set, 400 steps of 5 ms.

``linear_solver="auto"`` switches from the first to the second at
`sparsekin.solve.policy.COMPILED_MAX_COORDINATES` coordinates, from these figures.
"""

from __future__ import annotations

import numpy as np
import pytest

from sparsekin import solve_kinematics, testset

TIMES = np.linspace(0.0, 2.0, 401)
MODELS = {
    "four_bar_chain(5)": lambda: testset.four_bar_chain(5),
    "four_bar_chain(20)": lambda: testset.four_bar_chain(20),
    "four_bar_chain(35)": lambda: testset.four_bar_chain(35),
    "task5_chain(3)": lambda: testset.task5_chain(3),
    "task5_chain(5)": lambda: testset.task5_chain(5),
    "task5_chain(7)": lambda: testset.task5_chain(7),
}


@pytest.mark.parametrize("linear_solver", ["dense", "refactor"])
@pytest.mark.parametrize("model", list(MODELS))
def test_crossover(benchmark, model, linear_solver):
    mechanism = MODELS[model]()
    solve_kinematics(mechanism, TIMES[:3], linear_solver=linear_solver)  # compile outside the timing
    result = benchmark.pedantic(
        solve_kinematics,
        args=(mechanism, TIMES),
        kwargs={"linear_solver": linear_solver},
        rounds=5,
        iterations=1,
    )
    assert result.complete
    benchmark.extra_info.update(
        coordinates=3 * mechanism.n_bodies, path=result.linear_solver, samples=result.n_times
    )
