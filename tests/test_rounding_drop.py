"""Factorizations without the Jacobian's rounding-level entries (issue 29, long mesh runs).

Along a lattice's motion its horizontal bars stay horizontal, but Newton leaves their angles
at rounding (1e-21 to 1e-14) instead of 0: the sin φ entries the drawing had exactly zero
come back as tiny nonzeros, and SuperLU gives them as much fill as real entries.
`ReusingSolver` has `DissectionSolver` leave them out (`ROUNDING_DROP`): its factors are
then a preconditioner of GMRES, not the Jacobian's own.  Checked: the factors without them
are smaller (1.28 times at 20 x 20 cells, 2.5 times measured along a run at 10^4 bodies) and flagged
inexact; the reusing solver's solutions still reach its backward error and agree with
SuperLU's on the Jacobian itself, plain and transposed, at the refactored sample and at
later ones; nothing is dropped without rounding-level entries or with a tolerance of 0; a
preconditioner too poor for GMRES falls back to a factorization with every entry.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_array
from scipy.sparse.linalg import splu

from sparsekin import testset
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.discretization import Discretization
from sparsekin.engine.dissection import DissectionSolver
from sparsekin.engine.krylov import KRYLOV_TOLERANCE, ROUNDING_DROP, ReusingSolver
from sparsekin.engine.linalg import SuperLUSolver
from sparsekin.engine.pattern import build_pattern


def _backward_error(matrix, x, b) -> float:
    """``||b - A x||_2 / (||b||_2 + ||A||_1 ||x||_2)``, the measure `ReusingSolver` accepts by."""
    scale = max(abs(matrix).sum(axis=0).max(), abs(matrix).sum(axis=1).max())
    return float(np.linalg.norm(b - matrix @ x) / (np.linalg.norm(b) + scale * np.linalg.norm(x)))


def _moved_lattice(rows: int, cols: int, turn: float, rng):
    """The lattice's Jacobian with its vertical bars turned by `turn` (rad) and its
    horizontal bars' angles at rounding (1e-16 times standard normal numbers), as along a
    motion; the places of its bodies."""
    mechanism = testset.lattice(rows, cols)
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    q = pattern.initial_coordinates.copy().reshape(-1, 3)
    horizontal = q[:, 2] == 0.0
    q[~horizontal, 2] += turn
    q[horizontal, 2] = 1e-16 * rng.standard_normal(int(horizontal.sum()))
    assembler.fill_residual_jacobian(q.ravel())
    return assembler.jacobian.copy(), q[:, :2].copy()


def test_the_factors_without_rounding_are_smaller_and_flagged(rng):
    jacobian, places = _moved_lattice(20, 20, 0.3, rng)
    tiny = np.abs(jacobian.data) <= ROUNDING_DROP
    assert np.count_nonzero(tiny & (jacobian.data != 0.0)) >= 20 * 20  # a sin φ of each horizontal bar
    exact, dropping = DissectionSolver(places), DissectionSolver(places, drop_tolerance=ROUNDING_DROP)
    exact.factor(jacobian)
    dropping.factor(jacobian)
    assert exact.factors_exact and not dropping.factors_exact
    assert 1.2 * dropping.nnz_factors < exact.nnz_factors  # 1.28 measured here
    # the factors are those of the Jacobian without its tiny entries
    without = jacobian.copy()
    without.data[tiny] = 0.0
    b = rng.standard_normal(jacobian.shape[0])
    expected = splu(without.tocsc()).solve(b)
    np.testing.assert_allclose(dropping.solve(b), expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    dropping.factor(jacobian, drop_tolerance=0.0)  # asked per factorization: every entry, afresh
    assert dropping.factors_exact and dropping.nnz_factors == exact.nnz_factors
    assert (dropping.n_factorizations, dropping.n_refactorizations) == (2, 0)


def test_a_moved_pose_is_refactored_on_the_held_pattern(rng):
    """The same kept entries at the next pose: a numeric refactorization with the held
    pivots, its solutions SuperLU's on the kept entries, both systems, its factors no
    larger than SuperLU's and flagged inexact; a pose whose pivots fail the guard is
    factored afresh; other entries kept, the held pivots on their pattern."""
    jacobian, places = _moved_lattice(16, 16, 0.3, rng)
    solver = DissectionSolver(places, drop_tolerance=ROUNDING_DROP)
    solver.factor(jacobian)
    fresh_entries = solver.nnz_factors
    for turn in (0.31, 0.45, -0.2):
        jacobian, _ = _moved_lattice(16, 16, turn, rng)
        solver.factor(jacobian)
        # its exact zeros left out: about SuperLU's count
        assert not solver.factors_exact and solver.nnz_factors <= 1.05 * fresh_entries
        kept = jacobian.copy()
        kept.data[np.abs(kept.data) <= ROUNDING_DROP] = 0.0
        rhs = rng.standard_normal((jacobian.shape[0], 2))
        for transposed, operator in ((False, kept), (True, kept.T)):
            expected = splu(operator.tocsc()).solve(rhs)
            np.testing.assert_allclose(solver.solve(rhs, transposed=transposed), expected, rtol=0,
                                       atol=1e-10 * np.abs(expected).max())  # fmt: skip
    assert (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks) == (1, 3, 0)
    # The held pivot order made bad: the guard rejects the refactorization, SuperLU pivots anew.
    bad = jacobian.copy()
    bad.data *= 1.0 + 1e-3 * rng.standard_normal(bad.nnz)
    held = solver._held
    held.perm_r = held.perm_r[::-1].copy()  # pivots no longer SuperLU's
    held._analysis = None
    solver.factor(bad)
    assert (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks) == (2, 4, 1)
    assert solver.factors_exact is False  # still without the rounding entries, but SuperLU's own pivots
    b = rng.standard_normal(bad.shape[0])
    kept = bad.copy()
    kept.data[np.abs(kept.data) <= ROUNDING_DROP * np.abs(bad.data).max()] = 0.0
    expected = splu(kept.tocsc()).solve(b)
    np.testing.assert_allclose(solver.solve(b), expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    # An entry beyond the rounding where the held pattern has none: the held pivots on the
    # new pattern (analysed anew), SuperLU's solution on it.
    grown = bad.copy()
    grown.data[np.flatnonzero(np.abs(grown.data) <= 1e-13)[0]] = 0.3
    solver.factor(grown)
    assert (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks) == (2, 5, 1)
    kept = grown.copy()
    kept.data[np.abs(kept.data) <= ROUNDING_DROP * np.abs(grown.data).max()] = 0.0
    expected = splu(kept.tocsc()).solve(b)
    np.testing.assert_allclose(solver.solve(b), expected, rtol=0, atol=1e-10 * np.abs(expected).max())


def test_the_drawings_pivots_serve_a_moved_pose(rng):
    """The drawing factored without a drop tolerance (the first sample), a moved pose with
    it: refactored with the drawing's pivots on the moved pose's kept entries."""
    mechanism = testset.lattice(16, 16)
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    drawing = assembler.jacobian.copy()
    solver = DissectionSolver(pattern.initial_coordinates.reshape(-1, 3)[:, :2])
    solver.factor(drawing)
    moved, _ = _moved_lattice(16, 16, 0.3, rng)
    solver.factor(moved, drop_tolerance=ROUNDING_DROP)
    assert (solver.n_factorizations, solver.n_refactorizations, solver.n_fallbacks) == (1, 1, 0)
    kept = moved.copy()
    kept.data[np.abs(kept.data) <= ROUNDING_DROP] = 0.0
    b = rng.standard_normal(moved.shape[0])
    expected = splu(kept.tocsc()).solve(b)
    np.testing.assert_allclose(solver.solve(b), expected, rtol=0, atol=1e-10 * np.abs(expected).max())


def test_reusing_solves_reach_the_backward_error_on_dropped_factors(rng):
    """The reuse path at a moved pose: refactored there without the tiny entries, then the
    next poses; solutions against SuperLU's on the Jacobian itself, both systems."""
    _, places = _moved_lattice(12, 12, 0.0, rng)
    solver = ReusingSolver(DissectionSolver(places))
    for step, turn in enumerate((0.25, 0.26, 0.27)):
        jacobian, _ = _moved_lattice(12, 12, turn, rng)
        solver.factor(jacobian)
        if step == 0:  # stale on purpose: refactored at this pose (numerically, on the kept pattern)
            solver._stale = True
            solver.factor(jacobian)
            assert not solver.inner.factors_exact
        rhs = rng.standard_normal((jacobian.shape[0], 2))
        for transposed, operator in ((False, jacobian), (True, jacobian.T)):
            x = solver.solve(rhs, transposed=transposed)
            expected = splu(operator.tocsc()).solve(rhs)
            for c in range(2):
                assert _backward_error(operator, x[:, c], rhs[:, c]) <= KRYLOV_TOLERANCE
            np.testing.assert_allclose(x, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    assert solver.n_krylov_iterations >= 8  # every solve by GMRES, the refactored pose's too
    assert (solver.n_factorizations, solver.n_refactorizations) == (1, 1)


def test_nothing_dropped_when_told_not_to(rng):
    jacobian, places = _moved_lattice(8, 8, 0.3, rng)
    solver = ReusingSolver(DissectionSolver(places), drop_tolerance=0.0)
    solver.factor(jacobian)
    assert solver.inner.factors_exact
    b = rng.standard_normal(jacobian.shape[0])
    x = solver.solve(b)  # direct: the factors are the Jacobian's
    assert solver.n_krylov_iterations == 0 and _backward_error(jacobian, x, b) <= KRYLOV_TOLERANCE


class _DroppingSuperLU(SuperLUSolver):
    """SuperLU that leaves out every entry within `drop_tolerance` of the largest: a
    preconditioner as poor as asked."""

    drop_tolerance = 0.0
    factors_exact = True

    def factor(self, jacobian, *, drop_tolerance=None):
        drop = self.drop_tolerance if drop_tolerance is None else drop_tolerance
        kept = jacobian.copy()
        small = np.abs(kept.data) <= drop * np.abs(kept.data).max()
        self.factors_exact = not np.any(small & (kept.data != 0.0))
        kept.data[small] = 0.0
        kept.eliminate_zeros()
        super().factor(kept)


def test_a_preconditioner_too_poor_falls_back_to_every_entry(rng):
    n = 200
    off = csr_array(rng.uniform(-1.0, 1.0, (n, n)) * (rng.random((n, n)) < 0.03))
    matrix = csr_array(off + csr_array(np.diag(np.full(n, 4.0))))
    # the diagonal alone as preconditioner
    solver = ReusingSolver(_DroppingSuperLU(), drop_tolerance=0.3, max_iterations=1)
    solver.factor(matrix)
    assert not solver.inner.factors_exact
    b = rng.standard_normal(n)
    x = solver.solve(b)  # GMRES fails on the diagonal, again after refactoring: every entry, directly
    assert solver.inner.factors_exact and solver.n_factorizations == 3
    assert _backward_error(matrix, x, b) <= KRYLOV_TOLERANCE
    np.testing.assert_allclose(x, np.linalg.solve(matrix.toarray(), b), rtol=0, atol=1e-12 * np.abs(x).max())


def test_bad_drop_tolerances_are_refused():
    with pytest.raises(ValueError, match=r"`drop_tolerance` must be in \[0, 1\), got -1"):
        DissectionSolver(np.zeros((2, 2)), drop_tolerance=-1.0)
    with pytest.raises(ValueError, match=r"`drop_tolerance` must be in \[0, 1\), got 1.0"):
        ReusingSolver(SuperLUSolver(), drop_tolerance=1.0)


def test_a_factorization_singular_without_the_dropped_entries_is_made_with_every_entry(rng):
    """An entry within the drop tolerance that the matrix needs (a small inertia beside the
    largest entry): the dropped factorization is singular, so every entry is kept."""
    n = 50
    diagonal = np.full(n, 4.0)
    diagonal[-1] = 0.1  # alone in its row and column: left out, the matrix is singular
    off = csr_array(rng.uniform(-1.0, 1.0, (n, n)) * (rng.random((n, n)) < 0.05))
    off = csr_array(off.toarray() * (np.arange(n)[:, None] < n - 1) * (np.arange(n)[None, :] < n - 1))
    matrix = csr_array(off + csr_array(np.diag(diagonal)))
    solver = ReusingSolver(_DroppingSuperLU(), drop_tolerance=0.3)
    solver.factor(matrix)
    assert solver.inner.factors_exact
    b = rng.standard_normal(n)
    x = solver.solve(b)
    assert _backward_error(matrix, x, b) <= KRYLOV_TOLERANCE
