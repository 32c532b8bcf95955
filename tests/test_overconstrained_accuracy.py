"""Overconstrained models on the tall LU's path (from `SMALLEST_TALL_LU` = 300 coordinates)
against their closed forms, on every linear-solver path (issue 26).

The redundant equations left out must not cost accuracy: the kept block is as well
conditioned as the model allows, so positions agree with the closed form to 1e-11 and
velocities and accelerations to 1e-10 of their largest value, as on the small models the
dense analysis handles.  Families: rotating squares and rectangles
(`testset.rotating_lattice_motion`), square and rectangular grids, the rectangles written as
a grid file of 2 × 2 motifs and the same model written flat, and the parallel-bar chain.
All sizes 3×3 … 100×100 are in ``benchmarks/measure_overconstrained_accuracy.py``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from test_redundancy import assert_closed_form, chain_closed_form, jacobian_at_drawing

from sparsekin import RedundantConstraintWarning, load_model, save_model, solve_kinematics, testset
from sparsekin.analysis import rank as rank_module
from sparsekin.analysis.rank import analyse_jacobian

#: One period of the drivers' sine (θ = 0.3 + 0.2 sin t), 7 samples.
TIMES = np.linspace(0.0, 2 * np.pi, 7)
RECTANGLE = (1.0, 0.6)


def solved(mechanism, linear_solver, times=TIMES):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RedundantConstraintWarning)
        return solve_kinematics(mechanism, times, linear_solver=linear_solver)


def lattice_columns(mechanism, ni, nj, name):
    """The coordinate columns (x, y, angle) of rectangle (i, j), shape (ni, nj, 3)."""
    bodies = np.array([[mechanism.body_index(name(i, j)) for j in range(nj)] for i in range(ni)])
    return 3 * bodies[..., None] + np.arange(3)


def motif_name(i, j):
    return f"m{i // 2}_{j // 2}." + "abcd"[i % 2 + 2 * (j % 2)]


def motif_file(n, tmp_path):
    path = tmp_path / "motif.toml"
    save_model(testset.rotating_rectangles_motif(n // 2, n // 2, *RECTANGLE), path)
    return load_model(path)


#: (label, builder of the mechanism (tmp_path), ni, nj, width, height, name of body (i, j), paths)
LATTICES = [
    ("squares 10×10", lambda _: testset.rotating_squares(10), 10, 10, 1.0, 1.0, lambda i, j: f"s{i}_{j}.sq",
     ("auto", "refactor", "superlu", "dense")),
    ("squares 17×17", lambda _: testset.rotating_squares(17), 17, 17, 1.0, 1.0, lambda i, j: f"s{i}_{j}.sq",
     ("auto", "refactor", "superlu", "dense")),
    ("squares 40×40", lambda _: testset.rotating_squares(40), 40, 40, 1.0, 1.0, lambda i, j: f"s{i}_{j}.sq",
     ("auto", "superlu")),
    ("rectangles 20×20", lambda _: testset.rotating_rectangles(20, 20, *RECTANGLE), 20, 20, *RECTANGLE,
     lambda i, j: f"r{i}_{j}.rect", ("refactor", "superlu")),
    ("rectangles 31×12", lambda _: testset.rotating_rectangles(31, 12, *RECTANGLE), 31, 12, *RECTANGLE,
     lambda i, j: f"r{i}_{j}.rect", ("auto", "superlu")),
    ("motif file 20×20", lambda tmp: motif_file(20, tmp), 20, 20, *RECTANGLE, motif_name, ("auto", "superlu", "dense")),
    ("motif flat 20×20", lambda tmp: motif_file(20, tmp).expanded(), 20, 20, *RECTANGLE, motif_name,
     ("auto", "superlu")),
]  # fmt: skip


@pytest.mark.parametrize(
    "case, linear_solver",
    [(case, path) for case in LATTICES for path in case[-1]],
    ids=[f"{case[0]}-{path}" for case in LATTICES for path in case[-1]],
)
def test_rotating_lattices_on_the_tall_path_follow_their_closed_form(case, linear_solver, tmp_path):
    _, build, ni, nj, width, height, name, _ = case
    mechanism = build(tmp_path)
    assert mechanism.n_coordinates >= rank_module.SMALLEST_TALL_LU  # the tall LU's analysis
    result = solved(mechanism, linear_solver)
    assert len(result.redundant_equations) == (ni - 2) * (nj - 2)
    exact = testset.rotating_lattice_motion(ni, nj, TIMES, width, height)
    assert_closed_form(result, exact, lattice_columns(mechanism, ni, nj, name))


@pytest.mark.parametrize("linear_solver", ["auto", "superlu", "dense"])
def test_the_parallel_bar_chain_on_the_tall_path_follows_its_closed_form(linear_solver):
    n = 100  # 1200 coordinates, 100 redundant equations
    times = np.linspace(0.0, 2.0, 9)
    result = solved(testset.parallel_bar_chain(n, bars=3), linear_solver, times)
    assert len(result.redundant_equations) == n
    assert_closed_form(result, chain_closed_form(n, 3, times))


@pytest.mark.parametrize("build", [lambda: testset.parallel_bar_chain(30, bars=3), lambda: testset.rotating_squares(12),
                                   lambda: testset.rotating_rectangles_motif(5, 5, *RECTANGLE)])  # fmt: skip
def test_the_tall_path_names_the_latest_joint_equation_of_each_dependency(build):
    """Rows offered in the model's order: each redundant equation is the one that completes
    its dependency, the latest joint equation in it (later joints first)."""
    jacobian, preference, _ = jacobian_at_drawing(build())
    analysis = analyse_jacobian(jacobian, row_preference=preference)
    assert type(analysis.dependency_source).__name__ == "TallLU"
    joints = preference >= 1.0  # the drivers are offered first
    for k, row in enumerate(analysis.redundant_rows.tolist()):
        dependency = analysis.dependency(k)
        assert np.flatnonzero(joints & (np.abs(dependency) > 1e-12)).max() == row


def test_joints_listed_in_a_scattered_order_take_the_fill_reducing_order_and_the_closed_form(monkeypatch):
    """The model's order fills in too much (`NATURAL_FILL_LIMIT`): the tall LU starts again
    in a nested-dissection order, and the motion is as accurate."""
    from dataclasses import replace

    from sparsekin.analysis import tall_lu

    n = 14
    squares = testset.rotating_squares(n).expanded()
    order = np.random.default_rng(0).permutation(len(squares.joints))
    mechanism = replace(squares, joints=tuple(squares.joints[k] for k in order))
    made = []
    monkeypatch.setattr(rank_module, "TallLU", lambda *args: made.append(tall_lu.TallLU(*args)) or made[-1])
    result = solved(mechanism, "auto")
    assert [(factor.over_budget, factor.complete) for factor in made] == [(True, False), (False, True)]
    assert len(result.redundant_equations) == (n - 2) ** 2
    exact = testset.rotating_lattice_motion(n, n, TIMES)
    assert_closed_form(result, exact, lattice_columns(mechanism, n, n, lambda i, j: f"s{i}_{j}.sq"))
