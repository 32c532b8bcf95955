"""Forward dynamics on the large path (issue 25, speed): the pieces that make a step of a long
chain cheap, each against an independent computation.

* `saddle_pattern` (the saddle matrix's CSR pattern in linear time) against ``np.unique`` of
  the (row, column) keys, with the ground's and left-out equations' triplets discarded;
* `DynamicSystem.product` (S x without assembling S) and `residuals` ([0; d] − S x for two
  columns in one pass) against the assembled S; `RefactorSolver.solve_pair` (two solves in
  one pass) against `solve`, bit for bit;
* the paired projections (`_project_together`) against exact ones (a fresh sparse solve);
* `RoundingFloor`'s rules (measured, only downwards from a held matrix, forgotten; the
  projections' refinement skipped on a measured contraction grown as the age squared; the
  predictor's extrapolation used while it pays);
* the N-four-bar chain on the refactorization path against its exact answer (every crank
  moves as one four-bar: tests/dynamics_reference.py), with the dense path's motion and no
  drift at any sample, and through five singular (flat) crossings.
"""

from __future__ import annotations

import numpy as np
import pytest
from dynamics_reference import n_four_bar_b0, n_four_bar_motion

from sparsekin import Body, Mechanism, Revolute
from sparsekin.engine import _dynamics_kernels
from sparsekin.engine.discretization import discretize
from sparsekin.engine.saddle import DynamicSystem
from sparsekin.solve.dynamics import run_dynamics
from sparsekin.solve.options import DynamicsOptions, Request, SolveOptions
from sparsekin.solve.policy import Thresholds
from sparsekin.solve.rounding_floor import (COLD_MARGIN, EXTRAPOLATION_GAIN, FLOOR_STEPS, GROWTH_STEPS,
                                            PROJECTION_NOISE, RATE_STEPS, REFINEMENT_MARGIN, RoundingFloor)
from sparsekin.testset import n_four_bar


def test_saddle_pattern_is_the_sorted_unique_entries():
    rng = np.random.default_rng(5)
    n, size, count = 30, 50, 4000
    # coordinates 0..n-1, the ground n..n+2, kept equations from n+3 on, left out: negative
    rows = rng.integers(-3, n + 3 + size - n, count).astype(np.int32)  # the dtypes DynamicSystem uses
    cols = rng.integers(-3, n + 3 + size - n, count).astype(np.int32)
    cols[:200] = 7  # a long row of a hub's coordinate (sorted by argsort, not insertion)
    rows[:200] = 7
    cols[:200] = rng.integers(n + 3, n + 3 + size - n, 200)
    indptr, slots = np.zeros(size + 1, dtype=np.int64), np.empty(count, dtype=np.int32)
    indices = _dynamics_kernels.saddle_pattern(rows, cols, n, indptr, slots)

    def saddle_index(index):
        return np.where(index < n, index, np.where(index < n + 3, -1, index - 3))

    r, c = saddle_index(rows), saddle_index(cols)
    valid = (r >= 0) & (c >= 0)
    keys, inverse = np.unique(r[valid] * size + c[valid], return_inverse=True)
    np.testing.assert_array_equal(indices, keys % size)
    np.testing.assert_array_equal(indptr, np.searchsorted(keys // size, np.arange(size + 1)))
    np.testing.assert_array_equal(slots[valid], inverse)
    assert np.all(slots[~valid] == keys.size)  # the discard slot


@pytest.mark.parametrize("name", ["chain", "chain, rows left out", "task5 with masses", "lattice with masses"])
def test_derived_slots_fill_the_same_matrix_bit_for_bit(name):
    """Where Φq's slots and the diagonal's are derived from the row pointers (not held), S
    is the same, bit for bit, as every triplet scattered at the slot the pattern gave it,
    and `triplet_slots` gives the pattern's slots back (what the compiled loop reads)."""
    from sparsekin.testset import lattice, task5, with_masses

    built = {"task5 with masses": lambda: with_masses(task5(), 1.0, 0.1),
             "lattice with masses": lambda: with_masses(lattice(3, 4), 1.0, 0.1)}  # fmt: skip
    mechanism = built.get(name, lambda: n_four_bar(12))()
    discretization = discretize(mechanism)
    pattern, m = discretization.constraints, discretization.constraints.n_equations
    system = DynamicSystem(discretization, np.setdiff1d(np.arange(m), [3, 8] if "left out" in name else []))
    rng = np.random.default_rng(4)
    q = pattern.initial_coordinates + 0.05 * rng.standard_normal(system.n)
    n = system.n
    state = (q, rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(m), 1.0, 0.3, 0.2)
    system.fill_constraints(q)
    matrix = system.fill_matrix(*state, regularization=1e-9).copy()
    # every triplet again, as the pattern was made (`_fill_triplets`), scattered at the slots
    # of a pattern made from them
    block, kept = system._rows.size, system.kept_rows.size
    count = block + 2 * pattern.nnz + kept
    rows, cols = np.zeros(count, dtype=system._rows.dtype), np.zeros(count, dtype=system._cols.dtype)
    system._rows, system._cols, system._vals = rows, cols, np.zeros(count)
    system._fill_triplets(*state)
    system._vals[count - kept :] = -1e-9
    indptr, slots = np.zeros(system.size + 1, dtype=np.int64), np.empty(count, dtype=np.int32)
    indices = _dynamics_kernels.saddle_pattern(rows, cols, system.n, indptr, slots)
    np.testing.assert_array_equal(indices, matrix.indices)
    data = np.zeros(indices.size + 1)
    _dynamics_kernels.scatter_add(system._vals, slots, data)
    np.testing.assert_array_equal(matrix.data, data[:-1])
    np.testing.assert_array_equal(system.triplet_slots(), slots)
    if name.startswith("chain"):
        assert system.saddle.slots is None  # derived, not held


def test_saddle_pattern_from_parts_is_the_pattern_of_every_triplet():
    """The kernels that make S's pattern from the block's triplets and the Jacobian's rows
    (`_saddle_pattern_kernels`) against `saddle_pattern` of every triplet (block, Φq, Φqᵀ,
    diagonal): random block triplets with repeats, the ground's and negative indices and a
    hub's long row; a random Jacobian with ground columns and rows left out."""
    from scipy.sparse import random as sparse_random

    from sparsekin.engine import _saddle_pattern_kernels as parts

    rng = np.random.default_rng(11)
    n, m, count = 40, 25, 3000
    rows = rng.integers(-2, n + 3, count).astype(np.int32)
    cols = rng.integers(-2, n + 3, count).astype(np.int32)
    rows[:100], cols[:100] = 7, rng.integers(0, n, 100)  # a hub: sorted by np.sort, not insertion
    jacobian = sparse_random(m, n + 3, density=0.15, random_state=3, format="csr")
    jacobian.sort_indices()
    indptr, indices = jacobian.indptr.astype(np.int32), jacobian.indices.astype(np.int32)
    kept_row = np.full(m, -1, dtype=np.int64)
    kept = np.setdiff1d(np.arange(m), [2, 9, 17])
    kept_row[kept] = np.arange(kept.size)
    size = n + kept.size
    # every triplet, as `DynamicSystem._fill_triplets` writes them
    every_rows, every_cols = [rows], [cols]
    for r in range(m):
        row = n + 3 + kept_row[r] if kept_row[r] >= 0 else -1
        for s in range(indptr[r], indptr[r + 1]):
            every_rows.append(np.array([row, indices[s]], dtype=np.int32))
            every_cols.append(np.array([indices[s], row], dtype=np.int32))
    every_rows.append((n + 3 + np.arange(kept.size)).astype(np.int32))
    every_cols.append(every_rows[-1])
    every_rows, every_cols = np.concatenate(every_rows), np.concatenate(every_cols)
    expected_indptr, slots = np.zeros(size + 1, dtype=np.int64), np.empty(every_rows.size, dtype=np.int64)
    expected = _dynamics_kernels.saddle_pattern(every_rows, every_cols, n, expected_indptr, slots)

    ok, block_start, block_columns = parts.coordinate_block_rows(rows, cols, count, n)
    saddle_indptr = np.zeros(size + 1, dtype=np.int64)
    assert ok and parts.saddle_rows(block_start, indptr, indices, kept_row, n, saddle_indptr)
    saddle_indices = np.empty(saddle_indptr[-1], dtype=np.int32)
    block_slots, transposed_slots = np.empty(count, dtype=np.int64), np.empty(indices.size, dtype=np.int64)
    parts.fill_saddle_pattern((rows, cols), block_start, block_columns, (indptr, indices, kept_row), n, saddle_indptr,
                              saddle_indices, block_slots, transposed_slots)  # fmt: skip
    np.testing.assert_array_equal(saddle_indptr, expected_indptr)
    np.testing.assert_array_equal(saddle_indices, expected)
    np.testing.assert_array_equal(block_slots, slots[:count])
    np.testing.assert_array_equal(transposed_slots, slots[count + 1 : count + 2 * indices.size : 2])
    # out of order: an equation's index among the triplets, a Jacobian row unsorted, kept rows reversed
    assert not parts.coordinate_block_rows(rows, np.append(cols[:-1], n + 3).astype(np.int32), count, n)[0]
    unsorted = indices.copy()
    first = next(r for r in range(m) if indptr[r + 1] - indptr[r] >= 2)
    unsorted[indptr[first]], unsorted[indptr[first] + 1] = unsorted[indptr[first] + 1], unsorted[indptr[first]]
    assert not parts.saddle_rows(block_start, indptr, unsorted, kept_row, n, saddle_indptr)
    reversed_row = np.where(kept_row >= 0, kept.size - 1 - kept_row, -1)
    assert not parts.saddle_rows(block_start, indptr, indices, reversed_row, n, saddle_indptr)


def _saddle_models():
    from pathlib import Path

    import sparsekin as sk
    from helpers import actuator_round_trip
    from sparsekin.testset import lattice, task5, with_masses

    examples = Path(__file__).resolve().parents[1] / "examples"
    return {"chain": lambda: n_four_bar(12), "task5 with masses": lambda: with_masses(task5(), 1.0, 0.1),
            "lattice with masses": lambda: with_masses(lattice(3, 4), 1.0, 0.1),
            "andrews (a spring)": lambda: sk.load_model(examples / "dynamics" / "andrews.toml"),
            "struck lattice (rotational springs)": lambda: sk.load_model(examples / "dynamics" / "struck_lattice.toml"),
            "task5 on actuators": lambda: actuator_round_trip(0.1, 0.05)[0]}  # fmt: skip


@pytest.mark.parametrize("name", list(_saddle_models()))
@pytest.mark.parametrize("left_out", [(), (0, 3, -1)])
def test_pattern_from_its_parts_is_the_sorted_triplets(name, left_out, monkeypatch):
    """S's pattern made from the block's triplets and the Jacobian's rows (`_pattern_from_parts`:
    no Φq triplets, no sort of them) is the pattern of every triplet sorted
    (`SaddlePattern.from_triplets`), entry for entry and dtype for dtype, with the same slots
    and the same matrix bit for bit; kept equations out of order take the sort."""
    discretization = discretize(_saddle_models()[name]())
    m = discretization.constraints.n_equations
    kept = np.setdiff1d(np.arange(m), np.array(left_out, dtype=np.int64) % m)
    made = DynamicSystem(discretization, kept)
    assert made.saddle.slots is None and made._slots[2] is None  # from the parts: Φq's slots derived
    monkeypatch.setattr(DynamicSystem, "_pattern_from_parts", lambda self, block, dtype: False)
    sorted_ = DynamicSystem(discretization, kept)
    for mine, theirs in [(made.saddle.indptr, sorted_.saddle.indptr), (made.saddle.indices, sorted_.saddle.indices),
                         (made._slots[0], sorted_._slots[0]), (made._slots[1], sorted_._slots[1]),
                         (made._rows, sorted_._rows), (made._cols, sorted_._cols), (made._vals, sorted_._vals)]:  # fmt: skip
        assert mine.dtype == theirs.dtype
        np.testing.assert_array_equal(mine, theirs)
    np.testing.assert_array_equal(made.triplet_slots(), sorted_.triplet_slots())
    rng = np.random.default_rng(6)
    n = made.n
    q = discretization.constraints.initial_coordinates + 0.05 * rng.standard_normal(n)
    state = (q, rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(m), 1.0, 0.3, 0.2)
    for system in (made, sorted_):
        system.set_time(0.01)
        system.fill_constraints(q)
    np.testing.assert_array_equal(made.fill_matrix(*state, regularization=1e-9).data,
                                  sorted_.fill_matrix(*state, regularization=1e-9).data)  # fmt: skip
    monkeypatch.undo()
    shuffled = DynamicSystem(discretization, kept[::-1].copy())  # rows of S in another order: sorted
    assert shuffled.saddle.nnz == made.saddle.nnz
    shuffled.set_time(0.01)
    shuffled.fill_constraints(q)
    np.testing.assert_array_equal(np.sort(shuffled.fill_matrix(*state).data), np.sort(made.fill_matrix(*state).data))


def test_product_is_the_assembled_matrix_times_x():
    discretization = discretize(n_four_bar(12))
    m = discretization.constraints.n_equations
    system = DynamicSystem(discretization, np.setdiff1d(np.arange(m), [3, 8]))  # two rows left out
    rng = np.random.default_rng(3)
    q = discretization.constraints.initial_coordinates + 0.05 * rng.standard_normal(system.n)
    state = (q, rng.standard_normal(system.n), rng.standard_normal(system.n), rng.standard_normal(m), 1.0, 0.3, 0.2)
    system.fill_constraints(q)
    x = rng.standard_normal(system.size)
    expected = system.fill_matrix(*state) @ x
    product = system.product(*state, x, np.empty(system.size))
    np.testing.assert_allclose(product, expected, rtol=0.0, atol=1e-13 * np.abs(expected).max())


def test_rounding_floor_rules():
    floor = RoundingFloor(True)
    assert floor.noise(1e-12) == 1e-12  # nothing measured: the held matrix's own allowance
    floor.measured(4e-10, fresh=False)
    assert floor.level == 4e-10  # the first stall, held or fresh, sets it
    floor.measured(6e-10, fresh=False)
    assert floor.level == 4e-10  # a held matrix cannot raise it
    floor.measured(3e-10, fresh=False)
    assert floor.level == 3e-10
    floor.measured(5e-10, fresh=True)
    assert floor.level == 5e-10  # a fresh factorization measures it
    for _ in range(FLOOR_STEPS + 1):
        floor.step()
    assert floor.level == 0.0  # forgotten: measured again
    off = RoundingFloor(False)
    off.measured(4e-10, fresh=True)
    assert off.level == 0.0 and off.noise(1e-12) == 1e-12  # the dense path never has one


def test_refinement_skipped_only_on_a_measured_contraction_grown_with_age():
    floor, noise = RoundingFloor(True), 1e-7
    floor.step_begins()
    assert not floor.skips_refinement("velocity", 1e-9, noise)  # nothing measured
    floor.refined("velocity", 1e-4)  # at age 1
    for _ in range(3):  # age 4: the contraction predicted 16 times larger
        floor.step_begins()
    limit = REFINEMENT_MARGIN * noise / (1e-4 * 16)
    assert floor.skips_refinement("velocity", 0.99 * limit, noise)
    assert not floor.skips_refinement("velocity", 1.01 * limit, noise)
    assert not floor.skips_refinement("acceleration", 1e-12, noise)  # measured per projection
    for _ in range(RATE_STEPS - 3):
        floor.step_begins()
    assert not floor.skips_refinement("velocity", 1e-12, noise)  # too old: measured again
    floor.refined("velocity", 1e-4)
    floor.refactored()
    assert not floor.skips_refinement("velocity", 1e-12, noise)  # a new factorization
    floor.refined("velocity", 1e-12)  # at age 0 (the factorization of this step): no growth law from it
    floor.step_begins()
    assert not floor.skips_refinement("velocity", 1e-12, noise)
    dense = RoundingFloor(False)
    dense.step_begins()
    dense.refined("velocity", 1e-12)
    assert dense.projection_noise(1e3) == 0.0 and not dense.skips_refinement("velocity", 1e-12, noise)
    floor.measured(4e-10, fresh=True)
    assert floor.projection_noise(2e3) == pytest.approx(PROJECTION_NOISE * 2e3 * 4e-10)


def test_projection_starts_cold_where_two_solves_from_zero_are_predicted_to_do():
    """`RoundingFloor.starts_cold`: from zero on a factorization of this step, when no second
    increment from zero was measured in `GROWTH_STEPS` steps, or when the contraction measured,
    per step of age and grown with the age now, predicts one within `COLD_MARGIN` · noise."""
    floor, noise = RoundingFloor(True), 1e-7
    floor.step_begins()
    assert floor.starts_cold("velocity", 1.0, noise)  # nothing measured: from zero, to measure it
    floor.contracted("velocity", 2e-3)  # at age 1
    floor.step()
    floor.refactored()
    floor.step_begins()
    floor.step_begins()  # a new factorization, age 2: the growth per step of age still holds
    limit = COLD_MARGIN * noise / (2e-3 * 2)
    assert floor.starts_cold("velocity", 0.99 * limit, noise)
    assert not floor.starts_cold("velocity", 1.01 * limit, noise)  # warm: from the last change
    assert floor.starts_cold("acceleration", 1.01 * limit, noise)  # measured per projection
    floor.refactored()
    assert floor.starts_cold("velocity", 1.0, noise)  # a factorization of this step (age 0)
    for _ in range(GROWTH_STEPS):
        floor.step_begins()
        floor.step()
    assert floor.starts_cold("velocity", 1.0, noise)  # measured too long ago: measured again
    dense = RoundingFloor(False)
    dense.step_begins()
    dense.contracted("velocity", 1e-12)
    assert dense.starts_cold("velocity", 1.0, noise)  # (the dense path projects from zero, `_project`)


def test_predictor_extrapolates_while_it_pays():
    floor = RoundingFloor(True)
    floor.refactored()  # the first step's factorization
    for _ in range(RATE_STEPS - 1):
        floor.predicted(False, 3e-9)
        floor.step()
    assert not floor.extrapolates()  # a factorization RATE_STEPS - 1 steps ago
    floor.predicted(False, 3e-9)
    floor.step()
    assert floor.extrapolates()  # tried once no factorization was made for RATE_STEPS steps
    floor.predicted(True, 0.99 * EXTRAPOLATION_GAIN * 3e-9)
    assert floor.extrapolates()  # it paid: kept
    floor.predicted(True, 1.01 * EXTRAPOLATION_GAIN * 3e-9)
    assert not floor.extrapolates()  # it did not: off until tried again
    for _ in range(RATE_STEPS - 1):
        floor.predicted(False, 3e-9)
        floor.step()
    assert not floor.extrapolates()
    floor.predicted(False, 3e-9)
    floor.refactored()
    floor.step()
    assert not floor.extrapolates()  # RATE_STEPS since the trial, but a factorization just now
    floor.failed()
    floor._paid = True
    assert not floor.extrapolates()  # never while regularized (after a failed step) ...
    assert not RoundingFloor(False).extrapolates()  # ... nor on the dense path


def test_long_chain_extrapolating_predictor_starts_newton_closer(monkeypatch):
    """10^4 bodies, 40 steps of 1 ms: the extrapolating predictor (`RoundingFloor.extrapolates`)
    leaves B0 nearer the exact answer than the last accelerations alone, the drifts at the
    tolerance at every sample.  While the residuals rounded at the far coordinates' ulp it
    also saved a correction (312 solves against 328); with them summed exactly, Newton
    corrects down to the rounding of q either way and the extrapolation costs solves
    instead (268 against 241 here; at 10^5 bodies over 100 steps 3.04 against 2.68
    corrections a step, the same time a step) for its accuracy: B0 3.54e-8 against
    3.68e-8 m here, 9.46e-8 against 1.07e-7 m at 10^5 bodies."""
    from sparsekin.solve import rounding_floor

    loops, times = 5000, np.linspace(0.0, 0.04, 41)
    exact, _ = n_four_bar_b0(times, n_loops=loops)
    results = {}
    for gain in (EXTRAPOLATION_GAIN, -1.0):  # the rule, and an extrapolation that never pays
        monkeypatch.setattr(rounding_floor, "EXTRAPOLATION_GAIN", gain)
        options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
        results[gain] = run_dynamics(discretize(n_four_bar(loops)), times, options, DynamicsOptions(1e-3),
                                     Request(coordinates=False, points=["B0"], energy=True))  # fmt: skip
    extrapolating, constant = results[EXTRAPOLATION_GAIN], results[-1.0]
    errors = [np.abs(result.point("B0").position - exact).max() for result in (extrapolating, constant)]
    assert errors[0] < 1e-7 and errors[0] < errors[1]
    assert extrapolating.energy.drift_position.max() <= 1e-10 and extrapolating.energy.drift_velocity.max() <= 1e-10


@pytest.mark.parametrize("rtol", [None, 1e-4])
def test_a_halved_step_holds_no_state_of_a_failed_attempt_or_of_the_sample_before(rtol, monkeypatch):
    """A step that fails is halved; its second substep holds two states (the one it steps from
    and the one it makes), not the sample's first state (`advance` held it through every
    substep: 140 MB at 10^6 bodies) nor the failed attempt's arrays (the error-controlled
    loop held its exception, whose traceback held them).  Nothing but the stepper holds
    their arrays there (dead, spare in its pool `StateArrays`, or written again as the first
    substep's), the collector disabled, and the second substep makes no new array; the
    motion is closer to the exact answer than in 1 ms steps."""
    import gc
    import sys
    import weakref

    from sparsekin.engine.linalg import SingularMatrix
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper

    options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
    dynamics = DynamicsOptions(1e-3, rtol=rtol)
    stepper = GeneralizedAlphaStepper(n_four_bar(60), options=options, dynamics=dynamics)
    stepper.start(0.0)
    stepper.advance(1e-3)
    sample = weakref.ref(stepper.state.coordinates)
    solve, step, predict = stepper.solver.solve, stepper._step, _dynamics_kernels.predict
    solves, attempts, alive, made = [], [], [], []

    def failing_once(*args, **kwargs):
        solves.append(None)
        if len(solves) == 2:  # the first attempt's second Newton correction
            raise SingularMatrix("forced")
        return solve(*args, **kwargs)

    def recording_predict(*args):
        attempts.append(weakref.ref(args[9]))  # the attempt's new coordinates
        return predict(*args)

    def held_elsewhere(reference) -> bool:  # alive, and held by more than the stepper
        array, pool = reference(), stepper._arrays
        if array is None:
            return False
        holders = (*pool._spare.values(), pool._lent, stepper._state, stepper._previous)
        held = sum(item is array for items in holders for item in items)
        return sys.getrefcount(array) - held > 2  # this local and the call's argument

    def checked_step(state, h, t_next):
        if len(attempts) == 2:  # the second substep: the failed attempt and the sample's state
            alive.extend(held_elsewhere(reference) for reference in (attempts[0], sample))
            made.append(stepper._arrays.n_made)
        return step(state, h, t_next)

    monkeypatch.setattr(stepper.solver, "solve", failing_once)
    monkeypatch.setattr(_dynamics_kernels, "predict", recording_predict)
    monkeypatch.setattr(stepper, "_step", checked_step)
    gc.disable()
    try:
        stepper.advance(2e-3)
    finally:
        gc.enable()
    assert stepper.n_subdivisions == 1 and len(attempts) == 3
    assert alive == [False, False] and made == [stepper._arrays.n_made]
    unhalved = GeneralizedAlphaStepper(n_four_bar(60), options=options, dynamics=dynamics)
    unhalved.start(0.0)
    unhalved.advance(1e-3)
    unhalved.advance(2e-3)
    exact, _ = n_four_bar_b0(np.array([2e-3]), n_loops=60)
    errors = [np.abs(np.array([q[0] + np.cos(q[2]), q[1] + np.sin(q[2])]) - exact[0]).max()
              for q in (stepper.state.coordinates, unhalved.state.coordinates)]  # fmt: skip
    assert errors[0] < errors[1] < 1e-8  # the second millisecond in two steps: closer (1.1e-9, 1.8e-9 m)


@pytest.mark.parametrize("dense_max_size", [0, 10**6])  # the refactorization path, the dense one
def test_states_a_caller_holds_are_never_written_again(dense_max_size):
    """A step writes its state into the arrays of states the stepper let go of (`StateArrays`),
    never into a state, an array or a view of one that a caller holds.  Three steppers on one
    chain, a step of each failing once (halved): the caller of the first keeps every state
    (each step's arrays are then new: the reference), of the second a view of every state's
    q and its linearization (as `SampleSteps`' blocks do), of the third nothing.  Every
    step's state is the same in the three bit for bit, the held states and views are what
    they were when they were current, and the third stepper makes no array after its second
    step."""
    from sparsekin.engine.linalg import SingularMatrix
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper

    options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=dense_max_size))

    def arrays(state):
        return [None if array is None else array.copy() for array in (*state[1:6], *state[9:])]

    def kept(stepper, keep):  # what the caller keeps, with copies of its values
        state = stepper.state
        if keep == "states":
            return state, arrays(state)
        lin = stepper.linearization()
        views = (state.coordinates[1:], lin.velocities[None], lin.accelerations[None], lin.multipliers[:])
        return views, [view.copy() for view in views]

    def run(keep):
        stepper = GeneralizedAlphaStepper(n_four_bar(30), options=options, dynamics=DynamicsOptions(1e-3))
        solve, armed = stepper.start(0.0) or stepper.solver.solve, []

        def failing_once(*args, **kwargs):
            if armed:  # the sixth step's first solve: Newton's first correction
                armed.clear()
                raise SingularMatrix("forced")
            return solve(*args, **kwargs)

        stepper.solver.solve = failing_once
        states, held, made = [arrays(stepper.state)], [], None
        for k in range(1, 31):
            armed[:] = [True] if k == 6 else []
            stepper.advance(k * 1e-3)
            if keep != "nothing":  # (no local keeps a state through the next step)
                held.append(kept(stepper, keep))
            states.append(arrays(stepper.state))
            made = stepper._arrays.n_made if k == 2 else made
        assert stepper.n_subdivisions == 1
        for holding, copies in held:
            values = arrays(holding) if keep == "states" else holding
            assert all(a is None and b is None or a.tobytes() == b.tobytes() for a, b in zip(values, copies))
        return states, made, stepper._arrays.n_made

    (reference, *_), (viewed, *_), (free, made, last) = run("states"), run("views"), run("nothing")
    for states in (viewed, free):
        assert all(a is None and b is None or a.tobytes() == b.tobytes()
                   for state, expected in zip(states, reference, strict=True) for a, b in zip(state, expected))
    assert made == last


def test_a_refinement_restart_leaves_velocities_that_needed_no_projection(monkeypatch):
    """The paired projections restart on a fresh matrix when a refinement stops contracting;
    the velocity column's change made so far is then taken back from q̇ — only if that column
    started this step: otherwise its array holds an earlier step's change (always, with warm
    starts), which the restart added to q̇.  Forced here: the velocities on their constraint
    (the column never starts), stale values in its array, and an acceleration column that
    cannot stop (bound and noise 1e-300) on a refinement whose every second increment counts as
    not contracting (`REFINEMENT_CONTRACTION` 0): one restart, q̇ left as it was (the old test,
    ``not moves.done``, moved it by the stale values)."""
    from sparsekin.solve import projections
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper

    options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
    stepper = GeneralizedAlphaStepper(n_four_bar(60), 1e-3, options=options)
    stepper.start(0.0)
    for k in (1, 2, 3):
        stepper.advance(k * 1e-3)
    project, factor, calls, factored = stepper._project_together, stepper._factor, [], []

    def forced(q, v, a, lam, coefficients, velocity, acceleration):
        velocity[0][:] = 0.0  # the velocities' drift: within any bound
        stepper._projection_work[0][:] = 1.0  # the velocity column's array: an earlier step's change
        before, count = v.copy(), len(factored)
        try:
            return project(q, v, a, lam, coefficients, velocity, (acceleration[0], 1e-300, 1e-300))
        finally:
            calls.append((np.array_equal(v, before), len(factored) - count))

    monkeypatch.setattr(projections, "REFINEMENT_CONTRACTION", 0.0)
    monkeypatch.setattr(stepper, "_project_together", forced)
    monkeypatch.setattr(stepper, "_factor", lambda *args: (factored.append(None), factor(*args))[1])
    stepper.advance(4e-3)
    assert calls == [(True, 1)]


def test_regularization_only_after_a_failed_step_on_the_large_path():
    large, dense = RoundingFloor(True), RoundingFloor(False)
    assert large.regularization(1e-10) == 0.0 and dense.regularization(1e-10) == 1e-10
    large.failed()
    assert large.regularization(1e-10) == 1e-10
    large.recovered()
    assert large.regularization(1e-10) == 0.0
    dense.recovered()
    assert dense.regularization(1e-10) == 1e-10


def test_chain_on_the_refactor_path_is_exact_and_does_not_drift():
    loops = 60  # 121 bodies
    times = np.linspace(0.0, 0.1, 11)
    results = {}
    for size in (0, 10**6):  # the refactorization path, and the dense one
        options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=size))
        results[size] = run_dynamics(discretize(n_four_bar(loops)), times, options, DynamicsOptions(1e-3),
                                     Request(points=["B0"], energy=True))  # fmt: skip
    sparse, dense = results[0], results[10**6]
    assert (sparse.linear_solver, dense.linear_solver) == ("refactor", "dense")
    exact, _ = n_four_bar_b0(times, n_loops=loops)
    # the bound; the integrator's own error at 1 ms is 1.2e-7 m after 0.1 s
    assert np.abs(sparse.point("B0").position - exact).max() < 1e-6
    np.testing.assert_allclose(sparse.coordinates, dense.coordinates, rtol=0.0, atol=1e-10 * 2 * loops)
    assert sparse.energy.drift_position.max() <= 1e-10 and sparse.energy.drift_velocity.max() <= 1e-10


def test_chain_on_the_refactor_path_passes_its_singular_crossings():
    """N = 4 over 5 s (five flat crossings, where Φq loses rank), as tests/test_dynamics.py
    checks it on the dense path: every crank on the exact angle within 1e-3 rad."""
    times = np.linspace(0.0, 5.0, 101)
    options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
    result = run_dynamics(discretize(n_four_bar(4)), times, options, DynamicsOptions(1e-3), Request(energy=True))
    assert result.linear_solver == "refactor"
    cranks = np.concatenate([result.coordinates[:, 2:3], result.coordinates[:, 5::6]], axis=1)
    assert np.abs(cranks - n_four_bar_motion(times, 4).angle[:, None]).max() < 1e-3
    assert np.ptp(cranks, axis=1).max() < 1e-9
    assert result.energy.drift_position.max() <= 1e-10 and result.energy.drift_velocity.max() <= 1e-10


def test_long_chain_skips_refinements_and_stays_exact(monkeypatch):
    """10^5 bodies, 20 steps of 1 ms, the projections started from zero: they stop after one
    solve where the held factorization's measured contraction allows it
    (`RoundingFloor.skips_refinement`), with fewer solves than without the rule, B0 on the
    exact answer as before, and the drifts at the tolerance at every sample."""
    from sparsekin.solve import projections, rounding_floor

    monkeypatch.setattr(projections, "WARM_START", False)  # (a column started warm never stops at one solve)
    loops, times = 50000, np.linspace(0.0, 0.02, 21)
    exact, _ = n_four_bar_b0(times, n_loops=loops)
    results = {}
    for margin in (REFINEMENT_MARGIN, -1.0):  # the rule, and never skipping
        monkeypatch.setattr(rounding_floor, "REFINEMENT_MARGIN", margin)
        options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
        results[margin] = run_dynamics(discretize(n_four_bar(loops)), times, options, DynamicsOptions(1e-3),
                                       Request(coordinates=False, points=["B0"], energy=True))  # fmt: skip
    skipping, refining = results[REFINEMENT_MARGIN], results[-1.0]
    assert skipping.stats.n_solves < refining.stats.n_solves
    errors = [np.abs(result.point("B0").position - exact).max() for result in (skipping, refining)]
    assert errors[0] < 1e-7 and errors[0] <= 1.01 * errors[1]  # the integrator's own error, ~1e-8 m here
    assert skipping.energy.drift_position.max() <= 1e-10 and skipping.energy.drift_velocity.max() <= 1e-10


def test_long_chain_projections_start_from_the_last_change(monkeypatch):
    """10^4 bodies, 300 steps of 1 ms: the projections started from their changes of the
    step before (`projections.WARM_START`) take fewer solves than from zero (measured 1858
    against 2119), B0 on the exact answer as from zero, the drifts at the tolerance."""
    from sparsekin.solve import projections

    loops, times = 5000, np.linspace(0.0, 0.3, 31)
    exact, _ = n_four_bar_b0(times, n_loops=loops)
    results = {}
    for warm in (True, False):
        monkeypatch.setattr(projections, "WARM_START", warm)
        options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
        results[warm] = run_dynamics(discretize(n_four_bar(loops)), times, options, DynamicsOptions(1e-3),
                                     Request(coordinates=False, points=["B0"], energy=True))  # fmt: skip
    assert results[True].stats.n_solves < 0.92 * results[False].stats.n_solves
    errors = {warm: np.abs(result.point("B0").position - exact).max() for warm, result in results.items()}
    assert errors[True] < 1e-6 and errors[True] <= 1.01 * errors[False]  # the integrator's own error, 3.3e-7 m here
    assert results[True].energy.drift_position.max() <= 1e-10 and results[True].energy.drift_velocity.max() <= 1e-10



def _n_four_bar_at(loops: int, x0: float) -> Mechanism:
    """`n_four_bar(loops)` drawn `x0` m along x from the origin (the same motion, shifted)."""
    points = {f"{name}{i}": (x0 + i, y) for i in range(loops + 1) for name, y in (("A", 0.0), ("B", 1.0))}
    bar = {"mass": 1.0, "inertia": 1 / 12}
    bodies = [Body(f"crank{i}", origin=f"A{i}", angle=np.pi / 2, points=(f"A{i}", f"B{i}"), com=(x0 + i, 0.5),
                   velocity=(0.0, 0.0, -1.0), **bar) for i in range(loops + 1)]  # fmt: skip
    bodies += [Body(f"coupler{i}", origin=f"B{i - 1}", points=(f"B{i - 1}", f"B{i}"), com=(x0 + i - 0.5, 1.0),
                    velocity=(1.0, 0.0, 0.0), **bar) for i in range(1, loops + 1)]  # fmt: skip
    joints = [Revolute((f"crank{i}", "ground"), at=f"A{i}") for i in range(loops + 1)]
    for i in range(1, loops + 1):
        joints += [Revolute((f"crank{i}", f"coupler{i}"), at=f"B{i}"),
                   Revolute((f"coupler{i}", f"crank{i - 1}"), at=f"B{i - 1}")]  # fmt: skip
    return Mechanism(points=points, bodies=bodies, joints=joints, gravity=(0.0, -9.81))


def test_a_long_chain_far_from_the_origin_stays_on_the_exact_motion():
    """400 four-bars drawn 10^7 m from the origin (coordinates' ulp 1.9e-9 m) through their
    first flat crossing (0.72 s).  Summed left to right, each revolute's residual rounded at
    that ulp, and Newton's corrections carried it along Φq's vanishing singular values
    (σ_min ≈ (π/2) θ / N): B0 ended 8.1e-4 m off the exact answer at 0.8 s (the integrator's
    own error is 2.7e-6 m, the same chain at the origin).  With the residuals' differences of
    far terms formed exactly (`sparsekin.engine._kernels._gap`): 4.5e-6 m (2.1e-6 of it
    before the crossing, where the coordinates' own ulp is 1e4 times the chain's at the
    origin).  (Newton settling within 4× its measured stall level instead of the rounding
    of q gave 1.9e-5 m here.)"""
    loops, x0 = 400, 1e7
    times = np.linspace(0.0, 0.8, 801)
    result = run_dynamics(discretize(_n_four_bar_at(loops, x0)), times, SolveOptions(1e-10), DynamicsOptions(1e-3),
                          Request(points=["B0"]))  # fmt: skip
    exact, _ = n_four_bar_b0(times, n_loops=loops)
    assert np.abs(result.point("B0").position - (x0, 0.0) - exact).max() < 1e-5


@pytest.mark.parametrize("path", ["refactor", "dense", "compiled"])
def test_chain_far_from_the_origin_passes_its_flat_crossing(path):
    """The 10^5-body chain's stop at its first flat crossing, in small: coordinates far from
    the origin carry a rounding (10^4 m: 1.8e-12 m) that Φq's vanishing singular values
    amplify past Newton's stall allowance ``STALL √n`` times the rounding of q (then in the
    residuals too; now only in q itself, see the test above).  N = 4 drawn
    10^4 m from the origin, one sample a step, stopped at t = 0.717 s ("Newton does not
    contract (3.2e-10 after 2.9e-10)") on all three paths.  It must cross on the exact
    motion: B0 within the integrator's own error at 1 ms and on the track of the same chain
    drawn at the origin (measured: 1.3e-5 m off the exact answer at 1 s, 6e-8 m apart),
    every crank at the same angle, no drift at any sample."""
    loops, x0 = 4, 1e4
    times = np.linspace(0.0, 1.0, 1001)
    size, compiled = {"refactor": (0, 0), "dense": (10**6, 0), "compiled": (10**6, 10**6)}[path]
    thresholds = Thresholds(saddle_dense_max_size=size, compiled_saddle_max_size=compiled)
    options = SolveOptions(1e-10, thresholds=thresholds)
    tracks = {}
    for shift in (0.0, x0):
        result = run_dynamics(discretize(_n_four_bar_at(loops, shift)), times, options, DynamicsOptions(1e-3),
                              Request(points=["B0"], energy=True))  # fmt: skip
        tracks[shift] = result.point("B0").position - (shift, 0.0)
    assert result.linear_solver == ("refactor" if path == "refactor" else "dense")
    # the step halved at the crossing grows back though every sample is one step (good steps
    # counted across samples; before: 1282 steps, the rest of the run at 0.5 ms)
    assert result.n_steps <= 1010
    exact, _ = n_four_bar_b0(times, n_loops=loops)
    assert np.abs(tracks[x0] - exact).max() < 2e-5  # h = 1 ms: 1.3e-5 m at 1 s
    assert np.abs(tracks[x0] - tracks[0.0]).max() < 1e-6
    cranks = result.coordinates[:, 2 : 3 * (loops + 1) : 3]
    assert np.ptp(cranks, axis=1).max() < 1e-7
    assert result.energy.drift_position.max() <= 1e-10 and result.energy.drift_velocity.max() <= 1e-10


def _saddle_state(loops: int, left_out=()):
    """A DynamicSystem of `n_four_bar(loops)` at a perturbed state, Φq filled there, and that state."""
    discretization = discretize(n_four_bar(loops))
    m = discretization.constraints.n_equations
    system = DynamicSystem(discretization, np.setdiff1d(np.arange(m), left_out))
    rng = np.random.default_rng(7)
    q = discretization.constraints.initial_coordinates + 0.05 * rng.standard_normal(system.n)
    state = (q, rng.standard_normal(system.n), rng.standard_normal(system.n), rng.standard_normal(m), 1.0, 0.3, 0.2)
    system.fill_constraints(q)
    return system, state, rng


def test_paired_solves_are_the_single_solves_bit_for_bit():
    """`RefactorSolver.solve_pair`: both right-hand sides in one pass over the factors, each
    solution the one `solve` gives, bit for bit, and S x = rhs (the assembled S)."""
    from sparsekin.engine.linalg import RefactorSolver

    system, state, rng = _saddle_state(12)
    matrix = system.fill_matrix(*state)
    solver = RefactorSolver()
    solver.factor(matrix)
    solver.factor(matrix)  # a numeric refactorization on the analysed pattern, as the stepper's
    rhs = [rng.standard_normal(system.size) for _ in range(2)]
    expected = [solver.solve(b.copy()) for b in rhs]
    count = solver.n_solves
    first, second = rhs[0].copy(), rhs[1].copy()
    solver.solve_pair(first, second)
    assert np.array_equal(first, expected[0]) and np.array_equal(second, expected[1])
    assert solver.n_solves == count + 2
    for x, b in zip((first, second), rhs):
        np.testing.assert_allclose(matrix @ x, b, rtol=0.0, atol=1e-10 * np.abs(b).max())
    with pytest.raises(ValueError):
        solver.solve_pair(first[:-1].copy(), second)


def test_saddle_residuals_are_the_drift_less_the_product():
    """`DynamicSystem.residuals`: ``[0; drift] − S x`` for two columns in one pass, against the
    assembled S (two rows left out), and bit for bit `product`'s numbers for one column."""
    system, state, rng = _saddle_state(12, left_out=[3, 8])
    n, k = system.n, system.size - system.n
    xs = [rng.standard_normal(system.size) for _ in range(2)]
    drifts = [rng.standard_normal(k) for _ in range(2)]
    outs = [np.empty(system.size) for _ in range(2)]
    system.residuals(*state, (xs[0], drifts[0], outs[0]), (xs[1], drifts[1], outs[1]))
    matrix = system.fill_matrix(*state)
    for x, drift, out in zip(xs, drifts, outs):
        expected = np.concatenate([np.zeros(n), drift]) - matrix @ x
        np.testing.assert_allclose(out, expected, rtol=0.0, atol=1e-13 * np.abs(expected).max())
    single = np.empty(system.size)
    system.residuals(*state, (xs[0], drifts[0], single))
    product = system.product(*state, xs[0], np.empty(system.size))
    assert np.array_equal(single, np.concatenate([0.0 - product[:n], drifts[0] - product[n:]]))


def test_refinement_passes_are_the_numpy_passes_bit_for_bit():
    """The projections' fused passes (`sparsekin.engine._projection_kernels`) give the numbers
    of the passes they replace, bit for bit: `residuals` with the bodies' inertia as six values
    each after `product`'s triplets of the same state; the acceleration drift at moved
    velocities and its move (`Assembler.fill_acceleration_drift`)."""
    system, state, rng = _saddle_state(12, left_out=[3, 8])
    n, k = system.n, system.size - system.n
    x, drift = rng.standard_normal(system.size), rng.standard_normal(k)
    product = system.product(*state, x, np.empty(system.size))
    after_product = np.empty(system.size)  # the triplets of `product` are not `residuals`' own: filled again
    system.residuals(*state, (x, drift, after_product), same_state=True)
    assert np.array_equal(after_product, np.concatenate([0.0 - product[:n], drift - product[n:]]))
    assembler, (q, v, a, lam) = system.assembler, state[:4]
    jacobian_qdd, weights = rng.standard_normal(lam.size), assembler.weights
    old = rng.standard_normal(lam.size)
    assembler.fill_acceleration_rhs(q, v)
    expected = jacobian_qdd - assembler.acceleration_rhs
    moved_drift = old.copy()
    moved = assembler.fill_acceleration_drift(q, v, jacobian_qdd, moved_drift, weights)
    assert np.array_equal(moved_drift, expected)
    assert moved == _dynamics_kernels.weighted_norm(expected - old, weights)
    assert assembler.fill_acceleration_drift(q, v, jacobian_qdd, moved_drift) == 0.0
    assert np.array_equal(moved_drift, expected)


def test_sample_drift_and_energies_made_by_the_step_are_the_published_ones():
    """The last step of an `advance` makes the velocities' drift with the projections' drifts
    left, and the energies with the powers (`_publishes`): the recorded sample equals, bit
    for bit, what `_publish` makes afresh at the same state, one step or three per sample."""
    from sparsekin.solve.dynamics import GeneralizedAlphaStepper

    options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
    stepper = GeneralizedAlphaStepper(discretize(n_four_bar(100)), 1e-3, options=options)
    stepper.start(0.0)
    made, t = 0, 0.0
    for steps in (1, 1, 3, 1, 3, 1, 1, 3):
        t += steps * 1e-3
        stepper.advance(t)
        made += stepper._velocity_drift is not None and stepper._step_energies is not None
        recorded = stepper.recorded()
        stepper._publish()  # Φ refilled at q, the drift and energies made again
        for key, values in stepper.recorded().items():
            assert np.array_equal(values, recorded[key]), key
    assert made >= 4  # (the drift needs both projections tested in one pass: most steps)


def test_projections_together_land_on_both_constraints():
    """The large path's paired projections (`_project_together`): from velocities and
    accelerations off their constraints, the velocities on Φq q̇ + Φt = 0 and the
    accelerations on Φq q̈ = γ at the projected velocities, each within its bound, and both
    within the refinement's noise of the exact projections (a fresh sparse solve of the
    saddle at the converged state), as the two projections one after the other do."""
    from scipy.sparse.linalg import spsolve

    from sparsekin.solve.dynamics import GeneralizedAlphaStepper

    options = SolveOptions(1e-10, thresholds=Thresholds(saddle_dense_max_size=0))
    stepper = GeneralizedAlphaStepper(discretize(n_four_bar(100)), 1e-3, options=options)
    stepper.start(0.0)
    stepper.advance(0.012)  # past the first trial of the extrapolation, a floor measured
    state, system, h = stepper.state, stepper.system, 1e-3
    alpha_m, alpha_f, gamma, beta = stepper.integrator.coefficients
    beta_prime, gamma_prime = (1.0 - alpha_m) / (h * h * beta * (1.0 - alpha_f)), gamma / (h * beta)
    coefficients = (1.0, gamma_prime / beta_prime, 1.0 / beta_prime)
    rng = np.random.default_rng(11)
    n, q, lam = system.n, state.coordinates, state.multipliers
    v0 = state.velocities + 1e-6 * rng.standard_normal(n)
    a0 = state.accelerations + 1e-3 * rng.standard_normal(n)
    system.fill_constraints(q)
    weights = stepper._weights

    def drifts(v, a):
        assembler = stepper.assembler
        velocity = _dynamics_kernels.weighted_norm(system.velocity_drift(v), assembler.weights)
        assembler.fill_acceleration_rhs(q, v)
        acceleration = _dynamics_kernels.weighted_norm(system.jacobian_product(a, assembler.acceleration_rhs),
                                                       assembler.weights)  # fmt: skip
        return velocity, acceleration

    v1, a1, lam1 = v0.copy(), a0.copy(), lam.copy()
    velocity = stepper._velocity_target(v1, coefficients, h)
    velocity = (velocity[0].copy(), *velocity[1:])
    acceleration = stepper._acceleration_target(q, v1, a1, coefficients, np.zeros(stepper.pattern.n_equations))
    # the targets as the stepper makes them (both drifts in one pass): the same numbers
    paired = stepper._paired_targets(q, v1, a1, coefficients, h)
    for one, other in zip((velocity, acceleration), paired):
        assert np.array_equal(one[0], other[0]) and one[1:] == other[1:]
    velocity, acceleration = paired
    bounds, noises = (velocity[1], acceleration[1]), (velocity[2], acceleration[2])
    a1, lam1, _ = stepper._apply_acceleration_change(a1, lam1, stepper._project_together(
        q, v1, a1, lam1, coefficients, velocity, acceleration))  # fmt: skip
    v2, a2, lam2 = v0.copy(), a0.copy(), lam.copy()
    stepper._project_velocities(q, v2, lam2, coefficients, h)
    a2, lam2, _ = stepper._apply_acceleration_change(a2, lam2, stepper._project_accelerations(q, v2, a2, lam2,
                                                                                              coefficients))  # fmt: skip
    # the exact projections: the saddle at the converged state, factored afresh
    matrix = system.fill_matrix(q, v0, np.zeros(n), lam, *coefficients).tocsc()
    change = spsolve(matrix, np.concatenate([np.zeros(n), system.velocity_drift(v0)]))
    v_exact = v0 - change[:n]
    stepper.assembler.fill_acceleration_rhs(q, v_exact)
    a_exact = a0 - spsolve(matrix, np.concatenate([np.zeros(n), system.jacobian_product(
        a0, stepper.assembler.acceleration_rhs)]))[:n]  # fmt: skip
    for v, a in ((v1, a1), (v2, a2)):
        velocity_drift, acceleration_drift = drifts(v, a)
        assert velocity_drift <= bounds[0] and acceleration_drift <= bounds[1]
        # (the refinements may stop at their noise; here a hundredth of it holds: measured
        # 3e-4 (velocities), 8e-4 and 2e-3 (accelerations, together and one after the other))
        assert _dynamics_kernels.weighted_norm(v - v_exact, weights) <= 0.01 * noises[0]
        assert _dynamics_kernels.weighted_norm(a - a_exact, weights) <= 0.01 * noises[1]
    assert _dynamics_kernels.weighted_norm(v0 - v_exact, weights) > 1e3 * noises[0]  # a projection was needed
