"""`KinematicsResult`'s repr is a summary (like xarray's), not a dump of its arrays."""

from __future__ import annotations

import numpy as np
from examples_loader import EXAMPLES

from sparsekin import load_model, solve_kinematics


def test_a_long_run_prints_as_a_few_lines_naming_what_was_recorded():
    mechanism = load_model(EXAMPLES / "task5_dynamics.toml")
    n_times = 2001
    result = solve_kinematics(mechanism, np.linspace(0.0, 2.0, n_times), points=["K"], joints=[0, 1])
    text = repr(result)
    assert str(result) == text
    lines = text.splitlines()
    assert len(lines) <= 10  # whatever the number of samples: no array is printed
    assert lines[0] == f"<KinematicsResult 'task5_dynamics': {n_times} samples, t = 0 … 2 s, complete>"
    assert "10 bodies, 14 joints, 2 drivers" in lines[1]
    assert lines[2].startswith(f"  path:         {result.linear_solver}: {result.n_factorizations} factorizations")
    recorded = {line.split()[0]: line for line in lines[4:]}
    assert f"({n_times}, 30)" in recorded["coordinates"]
    assert f"({n_times}, 1, 6)" in recorded["points"] and "K × (x, y, vx, vy, ax, ay)" in recorded["points"]
    joint_names = [mechanism.joints[k].name or f"joints[{k}]" for k in (0, 1)]
    assert f"({n_times}, 2, 3)" in recorded["joints"] and ", ".join(joint_names) in recorded["joints"]
    n_forces = len(result.force_labels)
    assert f"({n_times}, {n_forces})" in recorded["forces"] and f"… ({n_forces})" in recorded["forces"]


def test_a_run_that_kept_nothing_says_so():
    mechanism = load_model(EXAMPLES / "four_bar.toml")
    result = solve_kinematics(mechanism, np.linspace(0.0, 1.0, 5), coordinates=False)
    assert "3 bodies, 4 joints, 1 driver\n" in repr(result)
    assert repr(result).endswith("recorded: nothing but the times")
