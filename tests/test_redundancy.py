"""Overconstrained mechanisms at scale (issue 18): the tall LU's redundancy analysis, the
rotating squares and the parallel-bar chain against their closed forms, inconsistent
redundant sets, the Maxwell–Calladine counts and the minimum-norm reactions beyond
`MAX_MIN_NORM_EQUATIONS` redundant equations.

* rotating squares (Grima & Evans): square (i, j) centred at (i·p(θ), j·p(θ)), turned by
  (−1)^(i+j)·θ, p = cos θ + sin θ, θ = 0.3 + 0.2 sin t; (n − 2)² redundant equations;
* parallel-bar chain: plate k = plate k−1 + (cos θ_k, sin θ_k), the bars turned to θ_k;
  one redundant equation per cell with three bars, none with two and a welded one;
* the analysis by the tall LU against the dense analysis (same count, dependencies in the
  left null space, the kept block of full rank), both paths;
* forces: an energy balance under gravity on a chain with more than 64 redundant
  equations, and the augmented-system multipliers against numpy's least squares.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
from scipy import sparse

from helpers import solve_with

import sparsekin as sk
from sparsekin.engine.discretization import Discretization
from sparsekin import testset
from sparsekin.analysis.describe import row_preference
from sparsekin.analysis.rank import analyse_jacobian
from sparsekin.analysis.rigidity import counts_line
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.multipliers import MAX_MIN_NORM_EQUATIONS, augmented_minimum_norm, minimum_norm_multipliers
from sparsekin.engine.linalg import SuperLUSolver
from sparsekin.engine.pattern import build_pattern
from sparsekin.solve.policy import Thresholds

G = 9.81
#: Agreement with a closed form, relative to the largest value of each quantity (x, y in m
#: and angles in rad together): what a correct double-precision solver meets (issue 26).
POSITION_RTOL, RATE_RTOL = 1e-11, 1e-10


def jacobian_at_drawing(mechanism):
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    return sparse.csr_array(assembler.jacobian, copy=True), row_preference(mechanism, pattern), pattern


def assert_closed_form(result, exact, columns=slice(None)):
    for label, solved, expected, rtol in zip(
        ("positions", "velocities", "accelerations"),
        (result.coordinates, result.velocities, result.accelerations), exact,
        (POSITION_RTOL, RATE_RTOL, RATE_RTOL),
    ):  # fmt: skip
        error = np.abs(solved[:, columns] - expected).max() / np.abs(expected).max()
        assert error <= rtol, f"{label}: {error:.2e} of the largest value"


@pytest.fixture(params=["dense", "tall LU"])
def path(request):
    """Both analyses: the tall LU from 1 coordinate on, or never (the coordinates from which
    the tall LU analyses a Jacobian)."""
    return 1 if request.param == "tall LU" else 10**9


def solve(mechanism, times, tall_lu_from):
    """`solve_kinematics`, its redundant equations found by the tall LU from `tall_lu_from` coordinates on."""
    return solve_with(mechanism, times, thresholds=Thresholds(smallest_tall_lu=tall_lu_from))


def squares_closed_form(n, t):
    theta, rate, accel = 0.3 + 0.2 * np.sin(t), 0.2 * np.cos(t), -0.2 * np.sin(t)
    pitch = np.cos(theta) + np.sin(theta)
    pitch_rate = (np.cos(theta) - np.sin(theta)) * rate
    pitch_accel = -(np.cos(theta) + np.sin(theta)) * rate**2 + (np.cos(theta) - np.sin(theta)) * accel
    j, i = np.divmod(np.arange(n * n), n)  # bodies row by row
    sign = (-1.0) ** (i + j)
    q = np.stack([i * pitch[:, None], j * pitch[:, None], sign * theta[:, None]], axis=-1)
    qd = np.stack([i * pitch_rate[:, None], j * pitch_rate[:, None], sign * rate[:, None]], axis=-1)
    qdd = np.stack([i * pitch_accel[:, None], j * pitch_accel[:, None], sign * accel[:, None]], axis=-1)
    return (array.reshape(t.size, -1) for array in (q, qd, qdd))


@pytest.mark.parametrize("n", [3, 6])
def test_rotating_squares_follow_the_closed_form_with_the_exact_redundant_count(n, path):
    mechanism = testset.rotating_squares(n)
    assert mechanism.n_bodies == n * n
    assert len(mechanism.joints) == 2 * n * (n - 1) + 2
    times = np.linspace(0.0, 3.0, 7)
    with pytest.warns(sk.RedundantConstraintWarning, match=rf"{(n - 2) ** 2} redundant equations? left out"):
        result = solve(mechanism, times, path)
    assert len(result.redundant_equations) == (n - 2) ** 2
    assert_closed_form(result, squares_closed_form(n, times))


@pytest.mark.parametrize("n", [4, 12])
def test_counts_of_the_rotating_squares(n, path):
    mechanism = testset.rotating_squares(n)
    report = sk.check_model(mechanism, tall_lu_from=path)
    assert (report.n_coordinates, report.n_equations, report.rank) == (3 * n * n, 4 * n * n - 4 * n + 4, 3 * n * n)
    assert len(report.redundant) == (n - 2) ** 2
    assert report.dof_by_rank == (1, 0)  # one flex without the driver: Poisson's ratio −1
    assert counts_line(report.n_coordinates, report.n_equations, report.rank) in str(report)
    assert f"0 degrees of freedom, {(n - 2) ** 2} states of self-stress (redundant equations)" in str(report)
    # the ground pin, the slot and the driver are never named redundant
    assert not any("ground" in equation.label or "driver" in equation.label for equation in report.redundant)


def chain_closed_form(n, bars, t):
    phases = 2 * np.pi * (np.arange(n) % testset.BAR_CHAIN_PHASES) / testset.BAR_CHAIN_PHASES
    a, w = testset.BAR_CHAIN_AMPLITUDE, testset.BAR_CHAIN_OMEGA
    arg = w * t[:, None] + phases
    theta = np.pi / 2 + a * (np.sin(arg) - np.sin(phases))
    rate, accel = a * w * np.cos(arg), -a * w * w * np.sin(arg)
    out = []
    for angle, derivative in ((theta, None), (rate, 1), (accel, 2)):
        if derivative is None:
            step = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
        elif derivative == 1:
            step = rate[..., None] * np.stack([-np.sin(theta), np.cos(theta)], axis=-1)
        else:
            step = (accel[..., None] * np.stack([-np.sin(theta), np.cos(theta)], axis=-1)
                    - rate[..., None] ** 2 * np.stack([np.cos(theta), np.sin(theta)], axis=-1))  # fmt: skip
        plates = np.cumsum(step, axis=1)  # plate k's origin (its derivatives)
        below = np.concatenate([np.zeros_like(plates[:, :1]), plates[:, :-1]], axis=1)
        zero = np.zeros_like(angle)
        bodies = np.zeros((t.size, n, 4, 3))
        for index, shift in enumerate((0.0, 0.5, 1.0)):
            bodies[:, :, index, :2] = below + (np.array([shift, 0.0]) if derivative is None else 0.0)
            bodies[:, :, index, 2] = angle
        if bars == 2:  # b welded to plate k: it translates with it
            bodies[:, :, 1, :2] = plates + (np.array([0.5, -1.0]) if derivative is None else 0.0)
            bodies[:, :, 1, 2] = np.pi / 2 if derivative is None else zero
        bodies[:, :, 3, :2] = plates
        bodies[:, :, 3, 2] = zero
        out.append(bodies.reshape(t.size, -1))
    return out


@pytest.mark.parametrize("bars", [2, 3])
def test_parallel_bar_chain_follows_the_closed_form(bars, path):
    n = 30
    mechanism = testset.parallel_bar_chain(n, bars=bars)
    assert mechanism.n_bodies == 4 * n
    times = np.linspace(0.0, 2.0, 9)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = solve(mechanism, times, path)
    redundant = [w for w in caught if issubclass(w.category, sk.RedundantConstraintWarning)]
    assert len(redundant) == (bars == 3)
    assert len(result.redundant_equations) == (n if bars == 3 else 0)
    if bars == 3:  # one equation of each cell's three-bar loop
        cells = sorted(int(label.split("–")[0].split("(revolute ")[1].lstrip("abcp")) for label in result.redundant_equations)
        assert cells == list(range(n))
    assert_closed_form(result, chain_closed_form(n, bars, times))


def bar_of_wrong_length(n, cell, error=1e-3):
    """The chain with the middle bar of `cell` 1 mm too long: its top node raised (the
    next cell's middle bar 1 mm too short).  The drawing holds; the bars contradict each
    other as soon as the cells shear."""
    mechanism = testset.parallel_bar_chain(n, bars=3)
    points = dict(mechanism.points)
    x, y = points[f"M{cell + 1}"]
    points[f"M{cell + 1}"] = (x, y + error)
    return replace(mechanism, points=points)


def test_an_inconsistent_redundant_set_is_named_as_such(path):
    n, cell = 20, 7
    assert sk.check_model(bar_of_wrong_length(n, cell), tall_lu_from=path).problems == (f"{n} redundant equations",)
    report = sk.check_model(bar_of_wrong_length(n, cell), time=0.5, tall_lu_from=path)  # sheared: the bars disagree
    assert len(report.redundant) == n
    bad = [equation for equation in report.redundant if not equation.consistent]
    assert len(bad) == 2 and any("not satisfied" in problem for problem in report.problems)
    for equation in bad:  # in the two cells whose middle bar changed length
        assert any(f"{name}{k}" in equation.label for name in "abcp" for k in (cell, cell + 1))
        assert equation.residual > 1e-6
    assert "NOT satisfied" in str(report)
    with pytest.raises(sk.ConvergenceError, match="contradict"), warnings.catch_warnings():
        warnings.simplefilter("ignore", sk.RedundantConstraintWarning)
        solve(bar_of_wrong_length(n, cell), np.linspace(0.0, 1.0, 3), path)


def test_a_tall_lu_whose_kept_rows_overflow_is_not_certified(monkeypatch):
    """Rotating squares of 10^6 bodies in their own order keep a block B singular to working
    precision: its inverse iteration overflowed and the certificate's SVD raised ("SVD did
    not converge", the run's one line).  Now an overflow fails the certificate, and the
    next order (or the dense analysis) decides: here the same answer as the dense one."""
    from sparsekin.analysis.tall_lu import TallLU

    jacobian, preference, _ = jacobian_at_drawing(testset.rotating_squares(9))
    dense = analyse_jacobian(jacobian, row_preference=preference)
    monkeypatch.setattr(TallLU, "solve", lambda self, rhs: np.full(self.shape[1], np.inf))
    fallen_back = analyse_jacobian(jacobian, row_preference=preference, tall_lu_from=1)
    assert type(fallen_back.dependency_source).__name__ != "TallLU"
    assert (fallen_back.rank, fallen_back.redundant_rows.tolist()) == (dense.rank, dense.redundant_rows.tolist())


def test_more_null_vectors_than_the_dense_analysis_finds_is_one_error(monkeypatch):
    """A tall Jacobian the sparse LU cannot certify, with more redundant equations than the
    dense analysis draws (`MAX_NULLITY`): its blocks of (m + n) × MAX_NULLITY numbers took
    more than 7.5 GB at 5·10^5 squares and could not have named them all; now one
    `ModelError` before they are allocated."""
    from sparsekin.analysis import rank

    jacobian, preference, _ = jacobian_at_drawing(testset.rotating_squares(9))
    m, n = jacobian.shape
    monkeypatch.setattr(rank, "MAX_NULLITY", m - n - 1)
    with pytest.raises(rank.RankUndetermined, match=rf"^the rank of the {m} × {n} constraint Jacobian cannot be told: "
                       rf"at least {m - n} redundant equations, more than the dense analysis finds \({m - n - 1};"):  # fmt: skip
        analyse_jacobian(jacobian, row_preference=preference, tall_lu_from=10**9)
    assert issubclass(rank.RankUndetermined, sk.ModelError)  # one line on the command line, exit 2


@pytest.mark.parametrize("builder", [lambda: testset.rotating_squares(9), lambda: testset.parallel_bar_chain(40)])
def test_tall_lu_agrees_with_the_dense_analysis(builder):
    jacobian, preference, pattern = jacobian_at_drawing(builder())
    dense = analyse_jacobian(jacobian, row_preference=preference)
    tall = analyse_jacobian(jacobian, row_preference=preference, tall_lu_from=1)
    assert type(tall.dependency_source).__name__ == "TallLU"
    assert (tall.rank, tall.n_redundant, tall.n_free) == (dense.rank, dense.n_redundant, 0)
    scaled = tall.row_scale[:, None] * jacobian.toarray() * tall.column_scale
    kept = np.setdiff1d(np.arange(jacobian.shape[0]), tall.redundant_rows)
    assert np.linalg.matrix_rank(scaled[kept]) == jacobian.shape[1]  # the chosen rows are independent
    dependencies = tall.dependencies
    np.testing.assert_allclose(dependencies[tall.redundant_rows], np.eye(tall.n_redundant), atol=0)
    assert np.abs(dependencies.T @ scaled).max() <= 1e-10 * np.abs(dependencies).max()
    drivers = np.arange(int(pattern.element_first_row[len(builder().joints)]), pattern.n_equations)
    np.testing.assert_allclose(tall.rows_in_dependencies(drivers).toarray(), dependencies[drivers], atol=1e-12)


def test_a_driver_in_a_redundancy_is_named(path):
    """A second driver on a parallel bar prescribes what the first one and the bars fix."""
    chain = testset.parallel_bar_chain(30, bars=3)
    twin = sk.RotationalDriver(("c12", "p11"), law=chain.drivers[12].law, name="twin")
    mechanism = replace(chain, drivers=(*chain.drivers, twin))
    report = sk.check_model(mechanism, tall_lu_from=path)
    assert len(report.redundant) == 31
    assert sum(equation.involves_drivers for equation in report.redundant) >= 1
    assert report.dof_by_rank == (30, 0)  # one shear per cell without the drivers
    with pytest.raises(sk.ModelError, match="drivers take part in a redundancy"):
        solve(mechanism, np.linspace(0.0, 1.0, 3), path)


def test_minimum_norm_multipliers_match_least_squares(rng):
    square = sparse.random_array((25, 25), density=0.15, random_state=rng) + 3.0 * sparse.eye_array(25)
    redundant = sparse.csr_array(sparse.random_array((10, 25), density=0.3, random_state=rng) @ square)
    jacobian = sparse.csr_array(sparse.vstack([square, redundant]))  # 10 rows combinations of the others
    rhs = rng.standard_normal(25)
    solver = SuperLUSolver()
    solver.factor(sparse.csr_array(square))
    kept, left_out = minimum_norm_multipliers(solver, redundant, solver.solve(rhs, transposed=True))
    expected = np.linalg.lstsq(jacobian.toarray().T, rhs, rcond=None)[0]
    np.testing.assert_allclose(np.concatenate([kept, left_out]), expected, rtol=0, atol=1e-10)
    np.testing.assert_allclose(augmented_minimum_norm(jacobian, rhs), expected, rtol=0, atol=1e-10)


@pytest.mark.parametrize("method", ["conjugate gradients", "augmented LU"])
def test_energy_balance_with_more_than_64_redundant_equations(method):
    """Drivers' power = d/dt (kinetic + potential energy) on a chain with masses under gravity."""
    # the augmented LU: what runs when conjugate gradients converge too slowly
    thresholds = Thresholds(min_norm_iterations=0) if method == "augmented LU" else Thresholds()
    n = MAX_MIN_NORM_EQUATIONS + 6
    chain = testset.parallel_bar_chain(n, bars=3)
    bodies = [replace(body, mass=1.0 + 0.5 * (k % 4), inertia=0.1) for k, body in enumerate(chain.bodies)]
    mechanism = replace(chain, bodies=bodies, gravity=(0.0, -G))
    h = 1e-3
    times = np.arange(0.0, 0.2 + h / 2, h)
    with pytest.warns(sk.RedundantConstraintWarning, match="minimum-norm"):
        result = solve_with(mechanism, times, thresholds=thresholds)
    mass = np.array([body.mass for body in bodies])
    inertia = np.array([body.inertia for body in bodies])
    velocity = result.velocities.reshape(times.size, -1, 3)
    kinetic = 0.5 * (mass * (velocity[..., 0] ** 2 + velocity[..., 1] ** 2) + inertia * velocity[..., 2] ** 2).sum(1)
    potential = G * (mass * result.coordinates.reshape(times.size, -1, 3)[..., 1]).sum(1)
    energy = kinetic + potential
    rate = (energy[:-4] - 8 * energy[1:-3] + 8 * energy[3:-1] - energy[4:]) / (12 * h)
    power = sum(result.driver_force(k).power for k in range(n))
    assert np.abs(power).max() > 10.0
    assert np.abs(power[2:-2] - rate).max() <= 1e-6 * np.abs(power).max()
    # the bars carry forces: the minimum-norm split, not the left-out rows at zero
    assert np.all(np.isfinite(result.force_tracks))


@pytest.mark.parametrize("offset, certified, redundant", [(None, True, 0), (1e-6, True, 0), (1e-12, False, 0),
                                                       (1e-13, False, 1), (0.0, False, 1)])  # fmt: skip
def test_the_dense_independence_certificate_never_contradicts_the_analysis(offset, certified, redundant):
    """`independent_rows` (the start of a small dynamics model skips the iterative analysis
    with it) certifies rows independent only where `analyse_jacobian` names no redundant
    row: 12 random sparse rows in 15 coordinates, the last replaced by the sum of two
    others moved by `offset` in one coordinate (None: left alone).  Moved by 1e-12, the
    smallest singular value of the scaled Jacobian is 1.3e-13 of the largest: independent
    to the analysis (its tolerance is 100 ε ≈ 2.2e-14) but within the certificate's margin
    of 100 times that, so deferred; by 1e-13 (1.3e-14) the analysis names it redundant.
    A tall Jacobian is always deferred."""
    from sparsekin.analysis.rank import independent_rows

    rng = np.random.default_rng(7)
    dense = rng.standard_normal((12, 15)) * (rng.random((12, 15)) < 0.4) + np.eye(12, 15)
    if offset is not None:
        dense[-1] = dense[0] + dense[3]
        dense[-1, 14] += offset
    jacobian = sparse.csr_array(dense)
    assert independent_rows(jacobian) is certified
    assert analyse_jacobian(jacobian).redundant_rows.size == redundant
    assert not independent_rows(sparse.csr_array(np.vstack([dense, dense[:2]])))
