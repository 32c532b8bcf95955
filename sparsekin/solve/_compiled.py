"""The whole time loop of a small model in one numba call, with a dense LU.

For models of a few dozen coordinates the Python loop of `sparsekin.solve.stepper` spends its
time in call overhead, not in arithmetic.  `solve_compiled` runs the same analysis —
Taylor predictor, Newton on the positions, then velocities and accelerations with the
Jacobian factored at the converged position — inside one compiled function, on a dense
copy of the Jacobian with an LU factorization with partial pivoting.  It calls what the
Python path calls: the kernel wiring of `sparsekin.engine._kernels` on the pattern's packed
`Primitives`, the law kernels of `sparsekin.model.laws` on the drivers' `LawTable`, and the
Newton rules of `sparsekin.engine.newton`; only the linear algebra is its own.

The first sample runs plain Newton from the initial configuration; every later sample
tries chord Newton first and restarts from the predictor with plain Newton if the chord
gives up (or anything else goes wrong), so a sample fails here exactly when it fails in
the Python path.  (Velocities and accelerations could instead reuse the old
factorization with iterative refinement, saving the factorization at the converged
position: measured slower, docs/design-notes.md, "Chord Newton".)

Contract with the caller: the loop stops at the first sample it cannot solve and returns
its index as ``n_solved``; rows ``0 .. n_solved - 1`` of the output arrays are filled and
final, the rest are not meaningful.  ``status`` says why it stopped (`LoopStatus`); the
loop raises nothing and builds no message.  The caller re-runs from sample ``n_solved``
with the Python path, which fails there again and produces the detailed error.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numba import njit

from .._jit import JIT
from ..engine._force_kernels import fill_applied_forces, fill_force_outputs
from ..engine._kernels import acceleration_rhs, fill_body_turns, residual_jacobian
from ..engine._lu_kernels import dense_lu_factor, dense_lu_solve, dense_lu_solve_transposed
from ..engine.discretization import Discretization
from ..engine.force_columns import ForceOutputArrays
from ..engine.newton import (
    CHORD_REJECTED,
    CONVERGED,
    CORRECT,
    NOT_CONVERGED,
    NOT_FINITE,
    SINGULAR,
    STALLED,
    newton_verdict,
    polishes,
)
from ..model.laws import BUILT_IN_LAWS, evaluate_laws
from ..model.loads import LoadArrays
from ..model.mechanism import Mechanism
from ..results.schema import FORCES
from .branch_guard import BranchGuard, guard_values, jumped
from .steppers import SampleBlock, StepperStats

__all__ = ["CompiledOutcome", "CompiledForces", "CompiledKinematicLoop", "LoopStatus", "solve_compiled",
           "supports_compiled"]

#: The status of a sample whose step fails the branch guard (after Newton's verdicts).
BRANCH_SUSPECT = max(CONVERGED, NOT_FINITE, STALLED, NOT_CONVERGED, SINGULAR, CHORD_REJECTED, CORRECT) + 1


class LoopStatus(IntEnum):
    """Why the compiled loop stopped (the verdicts of `sparsekin.engine.newton`)."""

    #: every sample solved
    SOLVED = CONVERGED
    #: the residual at a Newton iterate is NaN or infinite
    RESIDUAL_NOT_FINITE = NOT_FINITE
    #: from the third correction on, a Newton correction left more than half the residual
    STALLED = STALLED
    #: `max_iterations` Newton corrections did not reach the tolerance
    NOT_CONVERGED = NOT_CONVERGED
    #: a zero or non-finite pivot, or a non-finite solution of a linear system
    SINGULAR = SINGULAR
    #: the step to the sample failed the branch guard (`sparsekin.solve.branch_guard`)
    BRANCH_SUSPECT = BRANCH_SUSPECT


class CompiledOutcome(NamedTuple):
    """What `solve_compiled` did.

    Attributes
    ----------
    n_solved : int
        Samples solved; equal to the number of times unless the loop stopped early.
    status : LoopStatus
        `LoopStatus.SOLVED`, or why sample ``n_solved`` failed.
    n_factorizations, n_solves : int
        Dense LU factorizations and triangular solves, counted like the Python path's.
    n_restarts : int
        Samples whose chord Newton was abandoned for plain Newton from the predictor.
    """

    n_solved: int
    status: LoopStatus
    n_factorizations: int
    n_solves: int
    n_restarts: int

    @property
    def complete(self) -> bool:
        return self.status == LoopStatus.SOLVED


class CompiledForces(NamedTuple):
    """The forces the compiled loop records at each sample (`sparsekin.engine.forces`).

    Attributes
    ----------
    loads : LoadArrays
    laws : LawTable
        The loads' laws, all built in.
    n_laws : int
    outputs : ForceOutputArrays
        For Jacobian values in CSR order.
    inertial : bool
        False for quasi-static forces.
    rows : ndarray, shape (n_times, n_columns)
        Filled with the force columns of each sample solved.
    """

    loads: LoadArrays
    laws: object
    n_laws: int
    outputs: ForceOutputArrays
    inertial: bool
    rows: np.ndarray


def supports_compiled(mechanism: Mechanism) -> bool:
    """Whether every law is one the compiled loop evaluates (`sparsekin.model.laws.BUILT_IN_LAWS`).

    Subclasses and other law objects are refused: their `evaluate` may differ.  So are
    actuator loads (`sparsekin.engine.actuators`), which the loop's forces leave out.
    """
    return _unsupported_law(mechanism) is None and not any(load.type_name == "actuator"
                                                           for load in mechanism.declared("loads"))


def _unsupported_law(mechanism: Mechanism):
    """``(kind, element, law)`` of the first driver or load law the compiled loop cannot
    evaluate (a repeated unit's elements looked at once, not once per copy), or None."""
    for kind in ("drivers", "loads"):
        for element in mechanism.declared(kind):
            for law in element.laws():
                if type(law) not in BUILT_IN_LAWS:
                    return kind, element, law
    return None


@njit(inline="always", **JIT)
def _factor(indptr, indices, jac_data, lu, pivots):
    """Scatter the CSR values into the dense `lu` and factor it; False if singular."""
    for r in range(lu.shape[0]):
        for c in range(lu.shape[1]):
            lu[r, c] = 0.0
    for r in range(lu.shape[0]):
        for s in range(indptr[r], indptr[r + 1]):
            lu[r, indices[s]] = jac_data[s]
    return dense_lu_factor(lu, pivots)


@njit(inline="always", **JIT)
def _solved(lu, pivots, b):
    """Solve in place; False if the solution is not finite."""
    dense_lu_solve(lu, pivots, b)
    for value in b:
        if not math.isfinite(value):
            return False
    return True


@njit(inline="always", **JIT)
def _solve_positions(system, q, target, tolerance, max_iterations, chord, work):
    """Newton from q (ground appended), refined in place; returns (corrections, verdict).

    The loop of `sparsekin.engine.newton.solve_positions` with a dense LU; `system` is
    ``(primitives, indptr, indices, residual weights)``, `work` ``(turns, residual,
    jac_data, lu, pivots, counts)``.  On success `lu` holds the factorization of the
    Jacobian at the converged q (before the polishing correction, which moves q by less
    than the tolerance).  ``counts`` accumulates (factorizations, solves).
    """
    primitives, indptr, indices, weights = system
    turns, residual, jac_data, lu, pivots, counts = work
    n = lu.shape[0]
    previous_norm = np.inf
    for iteration in range(max_iterations + 1):
        norm = residual_jacobian(primitives, q, turns, target, weights, residual, jac_data)
        verdict = newton_verdict(iteration, norm, previous_norm, tolerance, max_iterations, chord)
        if verdict == CONVERGED:
            counts[0] += 1
            if not _factor(indptr, indices, jac_data, lu, pivots):
                return iteration, SINGULAR
            if polishes(iteration, norm, tolerance, chord):
                counts[1] += 1
                if not _solved(lu, pivots, residual):
                    return iteration, SINGULAR
                for c in range(n):
                    q[c] -= residual[c]
                return iteration + 1, CONVERGED
            return iteration, CONVERGED
        if verdict != CORRECT:
            return iteration, verdict
        if not chord:
            counts[0] += 1
            if not _factor(indptr, indices, jac_data, lu, pivots):
                return iteration, SINGULAR
        previous_norm = norm
        counts[1] += 1
        if not _solved(lu, pivots, residual):
            return iteration, SINGULAR
        for c in range(n):
            q[c] -= residual[c]
    return max_iterations, NOT_CONVERGED


@njit(**JIT)
def _run_time_loop(model, times, start, settings, out, forces, guard):
    """Samples `start` … in turn (rows before `start` are solved already); returns
    (n_solved, status, n_factorizations, n_solves, n_restarts).

    `model` is ``(primitives, indptr, indices, residual weights, constant target, driven
    rows, initial coordinates, driver laws)``; `settings` ``(tolerance, max_iterations,
    chord)``; `out` ``(coordinates, velocities, accelerations, iterations)``, filled row
    by row.  Unless `forces` is None — ``(loads, load laws, n_load_laws, force outputs,
    inertial, rows)`` — its rows receive the force columns of each sample
    (`sparsekin.engine.force_columns`); unless `guard` is None — ``(coordinate weights,
    (defect ratio, least defect, least correction))`` — a sample whose step fails the
    branch guard (`sparsekin.solve.branch_guard`) stops the loop as a failure would
    (status `BRANCH_SUSPECT`).

    A `forces` of None is a signature of its own, in which numba prunes the force branch
    before typing it: a run without forces never compiles the force kernels."""
    primitives, indptr, indices, weights, constant_target, driven_row, initial_coordinates, laws = model
    tolerance, max_iterations, chord = settings
    coordinates, velocities, accelerations, iterations = out
    system = (primitives, indptr, indices, weights)
    n = initial_coordinates.size
    n_driven = driven_row.size
    q = np.zeros(n + 3)  # the ground appended as a body of zeros
    qd = np.zeros(n + 3)
    qdd = np.zeros(n + 3)
    applied = np.zeros(n + 3)
    turns = np.zeros((n // 3 + 1, 2))  # cos and sin of each body's angle, the ground last
    predictor = np.empty(n)
    residual = np.empty(n)
    jac_data = np.zeros(indptr[n] + 1)  # one discard slot for the ground's columns
    lu = np.empty((n, n))
    pivots = np.zeros(n, dtype=np.int64)
    counts = np.zeros(2, dtype=np.int64)  # factorizations, solves
    work = (turns, residual, jac_data, lu, pivots, counts)
    target = constant_target.copy()
    velocity_rhs = np.zeros(n)
    target_acceleration = np.zeros(n)
    gamma = np.zeros(n)
    rhs = np.empty(n)
    value = np.empty(n_driven)
    rate = np.empty(n_driven)
    acceleration = np.empty(n_driven)
    if forces is not None:
        loads, load_laws, n_load_laws, force_outputs, inertial, rows = forces
        load_value = np.zeros(n_load_laws)
        load_rate = np.zeros(n_load_laws)
        load_acceleration = np.zeros(n_load_laws)
        reaction_work = np.zeros((force_outputs.joint_side.size, 3))
    n_restarts = 0
    h = 0.0
    for k in range(start, times.size):
        t = times[k]
        if k == 0:
            for c in range(n):
                predictor[c] = initial_coordinates[c]
        else:  # Taylor predictor, same operation order as the Python path
            h = t - times[k - 1]
            half_h2 = 0.5 * h * h
            for c in range(n):
                predictor[c] = (velocities[k - 1, c] * h + coordinates[k - 1, c]) + (half_h2 * accelerations[k - 1, c])
        evaluate_laws(laws, t, value, rate, acceleration)
        for d in range(n_driven):
            r = driven_row[d]
            target[r] = value[d]
            velocity_rhs[r] = rate[d]
            target_acceleration[r] = acceleration[d]

        # Chord Newton first (not at the first sample: no factorization yet), and on any
        # failure plain Newton from the predictor again.
        corrections, status = 0, CHORD_REJECTED
        for attempt in range(1 if k == start or not chord else 2):
            for c in range(n):
                q[c] = predictor[c]
            use_chord = attempt == 0 and chord and k > start
            corrections, status = _solve_positions(system, q, target, tolerance, max_iterations, use_chord, work)
            if status == CONVERGED:
                break
            n_restarts += use_chord
        if status != CONVERGED:
            return k, status, counts[0], counts[1], n_restarts

        # Phi_q qd = -Phi_t, then Phi_q qdd = gamma + target'', with the factorization at q.
        for r in range(n):
            rhs[r] = velocity_rhs[r]
        counts[1] += 1
        if not _solved(lu, pivots, rhs):
            return k, SINGULAR, counts[0], counts[1], n_restarts
        for c in range(n):
            qd[c] = rhs[c]
        fill_body_turns(q, turns)  # q moved by the last correction
        acceleration_rhs(primitives, q, qd, turns, gamma)
        for r in range(n):
            rhs[r] = gamma[r] + target_acceleration[r]
        counts[1] += 1
        if not _solved(lu, pivots, rhs):
            return k, SINGULAR, counts[0], counts[1], n_restarts
        for c in range(n):
            coordinates[k, c] = q[c]
            velocities[k, c] = qd[c]
            accelerations[k, c] = rhs[c]
        iterations[k] = corrections
        if guard is not None and k > 0:  # the predictor is still that of this step
            coordinate_weights, thresholds = guard
            if jumped(h, coordinates[k - 1], velocities[k - 1], accelerations[k - 1], coordinates[k], velocities[k],
                      accelerations[k], predictor, coordinate_weights, thresholds):  # fmt: skip
                return k, BRANCH_SUSPECT, counts[0], counts[1], n_restarts

        if forces is not None:  # Phi_q^T lam = Q - M qdd - h, with the same factorization
            for c in range(n):
                qdd[c] = accelerations[k, c]
            evaluate_laws(load_laws, t, load_value, load_rate, load_acceleration)
            fill_applied_forces(loads, q, qd, qdd, turns, load_value, inertial, applied)
            for c in range(n):
                rhs[c] = applied[c]
            dense_lu_solve_transposed(lu, pivots, rhs)
            counts[1] += 1
            for multiplier in rhs:
                if not math.isfinite(multiplier):
                    return k, SINGULAR, counts[0], counts[1], n_restarts
            fill_force_outputs(force_outputs, jac_data, rhs, q, turns, velocity_rhs, reaction_work, rows[k])
    return times.size, CONVERGED, counts[0], counts[1], n_restarts


def solve_compiled(
    discretization: Discretization,
    times: np.ndarray,
    tolerance: float,
    max_iterations: int,
    coordinates: np.ndarray,
    velocities: np.ndarray,
    accelerations: np.ndarray,
    iterations: np.ndarray,
    *,
    chord: bool = True,
    start: int = 0,
    forces: CompiledForces | None = None,
    guard: BranchGuard | None = None,
) -> CompiledOutcome:
    """Positions, velocities and accelerations at every time, in one compiled loop.

    The semantics are those of `sparsekin.solve_kinematics`; the caller validates
    `times`, `tolerance` and `max_iterations` as it does, and owns the output arrays,
    which are filled in place.  See the module docstring for what happens at a sample
    that cannot be solved.

    Parameters
    ----------
    discretization : Discretization
        The mechanism's arrays (`sparsekin.engine.discretization.discretize`): its laws
        must pass `supports_compiled`, its constraints have as many equations as
        coordinates.
    times : ndarray, shape (n_times,)
        Strictly increasing sample times, s.
    tolerance : float
        Largest accepted weighted residual (`ConstraintPattern.residual_weights`).
    max_iterations : int
        Most Newton corrections at one time.
    coordinates, velocities, accelerations : ndarray of float64, shape (n_times, n_coordinates)
        Filled with q, qd and qdd, C-contiguous.
    iterations : ndarray of int64, shape (n_times,)
        Filled with the Newton corrections at each time (those of the attempt that
        converged: chord corrections, or plain Newton's after a restart).
    chord : bool
        Try chord Newton first; False runs plain Newton at every sample, with the Python
        path's iterates and counts.
    start : int
        The first sample to solve; rows ``0 .. start - 1`` of the outputs hold samples
        solved before (the loop predicts sample `start` from row ``start - 1``).  A chunk
        of a long run starts at 1 with the last sample of the chunk before in row 0.
    forces : CompiledForces, optional
        Also the forces at each sample solved, into ``forces.rows``.
    guard : BranchGuard, optional
        Stop at a sample whose step fails the branch guard (`LoopStatus.BRANCH_SUSPECT`);
        by default no guard.

    Returns
    -------
    CompiledOutcome

    Examples
    --------
    >>> import numpy as np
    >>> from sparsekin.engine.discretization import discretize
    >>> from sparsekin.testset import task5
    >>> model = discretize(task5())
    >>> times = np.linspace(0.0, 1.0, 101)
    >>> q, qd, qdd = (np.empty((times.size, model.n_coordinates)) for _ in range(3))
    >>> counts = np.empty(times.size, dtype=np.int64)
    >>> outcome = solve_compiled(model, times, 1e-12, 12, q, qd, qdd, counts)
    >>> outcome.n_solved, outcome.status.name
    (101, 'SOLVED')
    """
    mechanism, pattern = discretization.mechanism, discretization.constraints
    unsupported = _unsupported_law(mechanism)
    if unsupported is not None:
        kind, element, law = unsupported
        built_in = ", ".join(law_kind.__name__ for law_kind in BUILT_IN_LAWS)
        raise ValueError(
            f"the laws of `mechanism` must be {built_in} for the compiled loop; {kind[:-1]} "
            f"{element.describe()!r} has a {type(law).__name__}."
        )
    n_times, n_coordinates = np.shape(times)[0], pattern.n_coordinates
    if pattern.n_equations != n_coordinates:
        raise ValueError(
            f"`pattern` must have as many equations as coordinates ({n_coordinates}), got {pattern.n_equations}."
        )
    _check_array(times, "times", (n_times,), np.float64)
    outputs = {"coordinates": coordinates, "velocities": velocities, "accelerations": accelerations}
    for name, array in outputs.items():
        _check_array(array, name, (n_times, n_coordinates), np.float64)
    _check_array(iterations, "iterations", (n_times,), np.int64)
    laws = discretization.driver_laws.table
    if forces is not None:
        _check_array(forces.rows, "forces.rows", (n_times, forces.rows.shape[1]), np.float64)
        forces = (forces.loads, forces.laws, int(forces.n_laws), forces.outputs, bool(forces.inertial), forces.rows)
    model = (pattern.primitives, pattern.indptr.astype(np.int64), pattern.indices.astype(np.int64),
             pattern.residual_weights, pattern.target, pattern.driven_row, pattern.initial_coordinates, laws)  # fmt: skip
    checked = None if guard is None else (pattern.coordinate_weights, guard_values(guard))
    n_solved, status, n_factorizations, n_solves, n_restarts = _run_time_loop(
        model, times, int(start), (float(tolerance), int(max_iterations), bool(chord)),
        (coordinates, velocities, accelerations, iterations), forces, checked,
    )  # fmt: skip
    return CompiledOutcome(int(n_solved), LoopStatus(status), int(n_factorizations), int(n_solves), int(n_restarts))


class CompiledKinematicLoop:
    """The compiled loop as a block stepper (`sparsekin.solve.steppers.BlockStepper`).

    Each `advance_block` runs the loop over the times given, from the last sample of the
    block before (row 0 of its arrays), the branch guard checked at every sample; it
    returns the samples solved, views of arrays it reuses.  At a sample the loop cannot
    solve, or whose step fails the guard, it stops: `stopped` becomes True and
    `handover` gives the last sample solved, for the Python stepper to go on from
    (`sparsekin.solve.steppers.FallbackStepper`), which fails there again with the
    detailed error if it must.

    Parameters
    ----------
    discretization : Discretization
        Square, its laws supported (`supports_compiled`).
    options : SolveOptions
    chunk : int
        Most samples per block.
    forces : CompiledForces, optional
        The force columns to compute at each sample (``rows`` gives their number; the
        rows are allocated here).
    """

    def __init__(self, discretization: Discretization, options, chunk: int, forces: CompiledForces | None = None):
        self.discretization, self.options = discretization, options
        n = discretization.n_coordinates
        self._rows = [np.empty((chunk + 1, n)) for _ in range(3)]
        self._iterations = np.zeros(chunk + 1, dtype=np.int64)
        self._times = np.empty(chunk + 1)
        self._forces = None if forces is None else forces._replace(rows=np.zeros((chunk + 1, forces.rows.shape[1])))
        self._counts = np.zeros(2, dtype=np.int64)  # factorizations and solves
        self._first = None  # (t, q) of the first sample: the reference of the lock-up diagnosis
        self._last = None  # (t, q, qd, qdd) of the last sample solved
        self.stopped = False

    def advance_block(self, times: np.ndarray) -> SampleBlock:
        start = 0 if self._last is None else 1  # row 0: the previous sample
        stop = start + min(len(times), self._times.size - 1)
        self._times[start:stop] = times[: stop - start]
        if start:
            self._times[0] = self._last[0]
            for array, state in zip(self._rows, self._last[1:]):
                array[0] = state
        forces = self._forces
        outcome = solve_compiled(
            self.discretization, self._times[:stop], self.options.tolerance, self.options.max_iterations,
            *(array[:stop] for array in self._rows), self._iterations[:stop], start=start,
            forces=None if forces is None else forces._replace(rows=forces.rows[:stop]), guard=self.options.guard,
        )  # fmt: skip
        self._counts += (outcome.n_factorizations, outcome.n_solves)
        solved = outcome.n_solved
        self.stopped = solved < stop
        if solved > start:
            if self._first is None:
                self._first = (self._times[0], self._rows[0][0].copy())
            self._last = (self._times[solved - 1], *(array[solved - 1].copy() for array in self._rows))
        rows = slice(start, solved)
        recorded = {} if forces is None else {FORCES: forces.rows[rows]}
        return SampleBlock(self._times[rows], *(array[rows] for array in self._rows), self._iterations[rows], recorded)

    def handover(self):
        """``((t, q, qd, qdd) of the last sample solved, (t, q) of the first)``, or None."""
        return None if self._last is None else (self._last, self._first)

    def stats(self) -> StepperStats:
        return StepperStats(int(self._counts[0]), int(self._counts[1]), path="compiled")


def _check_array(array, name: str, shape: tuple[int, ...], dtype) -> None:
    if not isinstance(array, np.ndarray) or array.shape != shape or array.dtype != dtype:
        got = f"{array.dtype} {array.shape}" if isinstance(array, np.ndarray) else type(array).__name__
        raise ValueError(f"`{name}` must be a {np.dtype(dtype)} array of shape {shape}, got {got}.")
    if not array.flags.c_contiguous or not array.flags.writeable:
        raise ValueError(f"`{name}` must be C-contiguous and writeable.")
