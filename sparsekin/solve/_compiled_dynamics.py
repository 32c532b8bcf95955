"""Forward dynamics of a small model: a block of output samples in one numba call, dense LU.

For a model of a few dozen coordinates the generalized-α step of
`sparsekin.solve.dynamics.GeneralizedAlphaStepper` spends its time in Python call overhead,
not in arithmetic.  `CompiledDynamicsLoop` runs the same step — predictor, modified Newton
on the scaled index-3 saddle system, velocity projection, step halving and growth, the
work and dissipated energy — for a whole block of samples inside one compiled function,
on a dense LU (`sparsekin.engine._lu_kernels`) of the saddle matrix.  It calls what the
Python path calls: the constraint wiring of `sparsekin.engine._kernels`, the laws of
`sparsekin.model.laws`, the cores of `sparsekin.engine._motion_kernels` (the same
functions `sparsekin.engine.saddle.DynamicSystem` calls) and the force columns of
`sparsekin.engine._force_kernels`, with the rules and constants of
`sparsekin.solve.dynamics`; only the linear algebra is its own (LAPACK there, this LU
here: the two paths agree to rounding, not bit for bit).

The start (the drawing assembled, redundant equations, consistent velocities,
accelerations and multipliers) is the Python stepper's, run once.  Contract, as for the
compiled kinematics (`sparsekin.solve._compiled`): the loop stops at the first sample it
cannot solve — a step failed after `MAX_HALVINGS` halvings, or a solve the Python path
would raise on — and returns the samples solved before it; the Python stepper then goes
on from the last of them (its state handed over, `GeneralizedAlphaStepper.resume`) and
fails at that sample again with the detailed error if it must.

Supported: everything `solve_dynamics` integrates whose laws are all built in
(`sparsekin.solve._compiled.supports_compiled`'s laws; actuators included).  Other
law objects run the Python stepper (`sparsekin.solve.policy.plan_saddle_solver`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT
from ..engine._dynamics_kernels import (
    add_transposed_product,
    fill_row_products,
    kinetic_potential_elastic,
    scatter_add,
    weighted_norm,
)
from ..engine._force_kernels import fill_force_outputs
from ..engine._kernels import fill_body_turns, fill_residual_jacobian
from ..engine._lu_kernels import dense_lu_solve
from ..engine.actuators import actuator_kernel_arrays
from ..engine.force_columns import ForceOutputs
from ..engine._motion_kernels import fill_motion_forces, fill_saddle_triplets, motion_powers
from ..model.laws import fill_laws
from ..results.schema import DRIFT, ENERGY, FORCES
from ._compiled import _factor, _unsupported_law
from .steppers import SampleBlock, SampleSteps, StepperStats

__all__ = ["CompiledDynamicsLoop", "supports_compiled_dynamics"]

#: What a step, a projection or a block ends with.
_OK, _STEP_FAILED, _HAND_BACK = 0, 1, 2
#: Positions in the state's scalars and counts.
_TIME, _STEP, _WORK, _DISSIPATED, _POWER, _DAMPING, _BALANCE0 = range(7)
_STEPS, _SUBDIVISIONS, _NEWTON, _STALLS, _FACTORIZATIONS, _SOLVES, _FACTORED = range(7)
#: Most samples in one call (a Ctrl-C waits for the call to end).
MAX_BLOCK = 1000


def supports_compiled_dynamics(mechanism) -> bool:
    """Whether every driver and load law is one the compiled loop evaluates."""
    return _unsupported_law(mechanism) is None


# ---------------------------------------------------------------------- the system
@njit(inline="always", **JIT)
def _set_time(model, work, t):
    """Driver targets and rates, and the load laws, at time `t` (`DynamicSystem.set_time`)."""
    constraints, loads = model[0], model[1]
    driven_row, driver_laws = constraints[5], constraints[6]
    target, velocity_rhs, driver_values, law_values = work[4], work[5], work[7], work[8]
    fill_laws(driver_laws, t, driver_values[0], driver_values[1], driver_values[2])
    for d in range(driven_row.size):
        target[driven_row[d]] = driver_values[0, d]
        velocity_rhs[driven_row[d]] = driver_values[1, d]
    fill_laws(loads[1], t, law_values[0], law_values[1], law_values[2])


@njit(inline="always", **JIT)
def _fill_constraints(model, work, q):
    """Φ and Φq at `q`; the weighted norm of Φ on the kept rows (`DynamicSystem.fill_constraints`)."""
    primitives, weights, kept_rows, kept_weights = model[0][0], model[0][3], model[0][7], model[0][9]
    q_constraints, turns_constraints, residual, jac_data, target, kept_residual = work[0], work[1], work[2], work[3], work[4], work[6]
    n = q.size
    for c in range(n):
        q_constraints[c] = q[c]
    fill_residual_jacobian(primitives, q_constraints, turns_constraints, target, weights, residual, jac_data)
    for k in range(kept_rows.size):
        kept_residual[k] = residual[kept_rows[k]]
    return weighted_norm(kept_residual, kept_weights)


@njit(inline="always", **JIT)
def _load(motion, q, v, a):
    """The system's copies with the ground appended, and the turns at `q`."""
    q_g, v_g, a_g, turns = motion
    for c in range(q.size):
        q_g[c], v_g[c], a_g[c] = q[c], v[c], a[c]
    fill_body_turns(q_g, turns)


@njit(inline="always", **JIT)
def _velocity_drift(model, work, v, out):
    """Φq v + Φt of every equation, at the last `_fill_constraints`."""
    indptr, indices = model[0][1], model[0][2]
    fill_row_products(indptr, indices, work[3], v, out)
    velocity_rhs = work[5]
    for r in range(out.size):
        out[r] -= velocity_rhs[r]


@njit(inline="always", **JIT)
def _motion_residual(model, work, system, q, v, a, lam, out):
    """``M a + h − Q + Φqᵀ λ`` (`DynamicSystem.residual`)."""
    loads, actuators = model[1][0], model[1][2]
    motion, applied = system[0], system[1]
    _load(motion, q, v, a)
    fill_motion_forces(loads, actuators, motion[0], motion[1], motion[2], motion[3], work[8][0], applied, out)
    for c in range(out.size):
        out[c] = -out[c]
    add_transposed_product(model[0][1], model[0][2], work[3], lam, out)


@njit(inline="always", **JIT)
def _fill_matrix(model, work, system, q, v, a, lam, coefficients, regularization):
    """The saddle matrix's CSR values (`DynamicSystem.fill_matrix`) into ``system[2]``."""
    constraints, loads, saddle = model[0], model[1], model[2]
    motion, data, triplets, scratch, actuator_weights = system[0], system[2], system[3], system[4], system[5]
    _load(motion, q, v, a)
    fill_saddle_triplets(loads[0], constraints[0], loads[2], motion[0], motion[1], motion[2], motion[3], work[8][0],
                         lam, actuator_weights, (constraints[1], constraints[2], work[3]), constraints[8],
                         constraints[7].size, coefficients, regularization, scratch, triplets[0], triplets[1],
                         triplets[2])  # fmt: skip
    scatter_add(triplets[2], saddle[0], data)


@njit(inline="always", **JIT)
def _refactor(model, work, system, state, settings, q, v, a, lam, coefficients):
    """Fill the regularized matrix and factor it (`GeneralizedAlphaStepper._factor`)."""
    saddle, lu, pivots, counts = model[2], state[6], state[7], state[8]
    _fill_matrix(model, work, system, q, v, a, lam, coefficients, settings[7])
    counts[_FACTORIZATIONS] += 1
    if not _factor(saddle[1], saddle[2], system[2], lu, pivots):
        return False
    counts[_FACTORED] = 1
    return True


@njit(inline="always", **JIT)
def _solve(state, rhs, out):
    """`out` = the held factorization's solution of `rhs`; False if not finite."""
    for k in range(rhs.size):
        out[k] = rhs[k]
    state[8][_SOLVES] += 1
    dense_lu_solve(state[6], state[7], out)
    for value in out:
        if not math.isfinite(value):
            return False
    return True


# ---------------------------------------------------------------------- one step
@njit(**JIT)
def _project_velocities(model, work, system, state, settings, rules_, q, v, lam, coefficients, h):
    """`GeneralizedAlphaStepper._project_velocities`, on the held dense factorization."""
    tolerance = settings[4]
    rounding, noise, iterations, refinement = rules_[0], rules_[2], rules_[4], rules_[5]
    constraints, saddle = model[0], model[2]
    kept_rows, kept_weights, coordinate_weights = constraints[7], constraints[9], constraints[10]
    n, n_kept = q.size, kept_rows.size
    size_ = n + n_kept
    scratch = system[6]
    drift_all, zeros = scratch[0], scratch[1]
    goal, solution, residual, increment, product = scratch[2], scratch[3], scratch[4], scratch[5], scratch[6]
    kept_drift = work[6]
    scale = max(1.0, weighted_norm(v, coordinate_weights))
    bound = max(tolerance * h * scale, rounding * noise * scale)
    _velocity_drift(model, work, v, drift_all)
    for k in range(n_kept):
        kept_drift[k] = drift_all[kept_rows[k]]
    if weighted_norm(kept_drift, kept_weights) <= bound:
        return _OK
    _fill_matrix(model, work, system, q, v, zeros, lam, coefficients, 0.0)
    for k in range(size_):
        goal[k] = 0.0 if k < n else kept_drift[k - n]
        solution[k] = 0.0
        residual[k] = goal[k]
    last, fresh, size = math.inf, False, math.inf
    for _ in range(iterations):
        if not _solve(state, residual, increment):
            return _HAND_BACK  # the Python stepper raises SingularMatrix here
        for k in range(size_):
            solution[k] += increment[k]
        size = weighted_norm(increment[:n], coordinate_weights)
        if size <= bound:
            for c in range(n):
                v[c] -= solution[c]
            return _OK
        if size > refinement * last:
            if fresh:
                break
            if not _refactor(model, work, system, state, settings, q, v, zeros, lam, coefficients):
                return _STEP_FAILED
            _fill_matrix(model, work, system, q, v, zeros, lam, coefficients, 0.0)
            fresh = True
            for k in range(size_):
                solution[k] = 0.0
                residual[k] = goal[k]
            last = math.inf
            continue
        last = size
        fill_row_products(saddle[1], saddle[2], system[2], solution, product)
        for k in range(size_):
            residual[k] = goal[k] - product[k]
    # Φq near a loss of rank: the normal direction is ill-determined, the drift is not
    for c in range(n):
        increment[c] = v[c] - solution[c]
    _velocity_drift(model, work, increment[:n], drift_all)
    for k in range(n_kept):
        kept_drift[k] = drift_all[kept_rows[k]]
    if weighted_norm(kept_drift, kept_weights) <= bound:
        for c in range(n):
            v[c] -= solution[c]
        return _OK
    return _STEP_FAILED


@njit(**JIT)
def _step(model, work, system, state, settings, rules_, h, t_next, after):
    """One generalized-α step of size `h` from the state into `after` ``(q, v, a, pseudo,
    lam)`` (`GeneralizedAlphaStepper._step`); returns `_OK`, `_STEP_FAILED` or `_HAND_BACK`."""
    alpha_m, alpha_f, gamma, beta, tolerance, max_iterations = settings[:6]
    rounding, stall_factor, noise, contraction = rules_[0], rules_[1], rules_[2], rules_[3]
    q0, v0, a0, p0, lam0 = state[0], state[1], state[2], state[3], state[4]
    scalars, counts = state[5], state[8]
    q, v, a, pseudo, lam = after
    constraints = model[0]
    kept_rows, coordinate_weights = constraints[7], constraints[10]
    n, n_kept = q.size, kept_rows.size
    force, rhs, delta = system[7][0], system[7][1], system[7][2]
    beta_prime = (1.0 - alpha_m) / (h * h * beta * (1.0 - alpha_f))
    gamma_prime = gamma / (h * beta)
    coefficients = (1.0, gamma_prime / beta_prime, 1.0 / beta_prime)
    half_minus_beta = 0.5 - beta
    for c in range(n):  # predictor: the accelerations of the last step
        a[c] = a0[c]
        predicted = ((1.0 - alpha_f) * a[c] + alpha_f * a0[c] - alpha_m * p0[c]) / (1.0 - alpha_m)
        q[c] = q0[c] + h * v0[c] + h * h * (half_minus_beta * p0[c] + beta * predicted)
        v[c] = v0[c] + h * ((1.0 - gamma) * p0[c] + gamma * predicted)
    for r in range(lam.size):
        lam[r] = lam0[r]
    _set_time(model, work, t_next)
    last, fresh, rate, settled, stalled = math.inf, False, contraction, False, 0.0
    bound = tolerance / gamma_prime
    for iteration in range(max_iterations + 1):
        phi_norm = _fill_constraints(model, work, q)
        floor = rounding * (1.0 + weighted_norm(q, coordinate_weights))
        stall = stall_factor * math.sqrt(n) * floor
        if settled and phi_norm <= max(bound, floor, stalled):
            break
        if iteration == max_iterations:
            return _STEP_FAILED
        _motion_residual(model, work, system, q, v, a, lam, force)
        if not math.isfinite(phi_norm):
            return _STEP_FAILED
        for c in range(n):
            if not math.isfinite(force[c]):
                return _STEP_FAILED
        if counts[_FACTORED] == 0:
            if not _refactor(model, work, system, state, settings, q, v, a, lam, coefficients):
                return _STEP_FAILED
            fresh = True
        scale = -1.0 / beta_prime
        for c in range(n):
            rhs[c] = force[c] * scale
        residual = work[2]
        for k in range(n_kept):
            rhs[n + k] = -residual[kept_rows[k]]
        if not _solve(state, rhs, delta):
            return _STEP_FAILED
        counts[_NEWTON] += 1
        correction = weighted_norm(delta[:n], coordinate_weights)
        if not math.isfinite(correction):
            return _STEP_FAILED
        for c in range(n):
            q[c] += delta[c]
            v[c] += gamma_prime * delta[c]
            a[c] += beta_prime * delta[c]
        for k in range(n_kept):
            lam[kept_rows[k]] += beta_prime * delta[n + k]
        if iteration > 0:
            rate = correction / last
        left = rate / (1.0 - rate) * correction if rate < 1.0 else math.inf
        settled = left <= bound or correction <= floor
        if not settled and rate > contraction and iteration > 0:
            if correction <= (stall if fresh else noise * stall / stall_factor):
                settled = True
                counts[_STALLS] += 1
                stalled = stall
            elif fresh:
                return _STEP_FAILED
            else:
                counts[_FACTORED] = 0  # a fresh matrix at the next iterate
        else:
            fresh = False
        last = correction
    outcome = _project_velocities(model, work, system, state, settings, rules_, q, v, lam, coefficients, h)
    if outcome != _OK:
        return outcome
    hh = h * h
    for c in range(n):
        pseudo[c] = (q[c] - q0[c] - h * v0[c] - hh * half_minus_beta * p0[c]) / (hh * beta)
    _load(system[0], q, v, a)
    motion = system[0]
    power, damping = motion_powers(model[1][0], model[1][2], motion[0], motion[1], motion[3], work[8][0], lam,
                                   constraints[5], work[5])  # fmt: skip
    scalars[_WORK] = scalars[_WORK] + 0.5 * h * (scalars[_POWER] + power)
    scalars[_DISSIPATED] = scalars[_DISSIPATED] + 0.5 * h * (scalars[_DAMPING] + damping)
    scalars[_POWER], scalars[_DAMPING] = power, damping
    counts[_STEPS] += 1
    return _OK


# ---------------------------------------------------------------------- samples
@njit(**JIT)
def _publish(model, work, system, state, k, out, forces):
    """Row `k` of the outputs: q, q̇, q̈, energy and drift, and the force columns
    (`GeneralizedAlphaStepper._publish` and the run's force columns)."""
    q, v, a, lam, scalars = state[0], state[1], state[2], state[4], state[5]
    coordinates, velocities, accelerations, energy, drift = out[0], out[1], out[2], out[4], out[5]
    loads = model[1][0]
    phi = _fill_constraints(model, work, q)
    drift_all = system[6][0]
    _velocity_drift(model, work, v, drift_all)
    drift_norm = weighted_norm(drift_all, model[0][3])
    motion = system[0]
    _load(motion, q, v, a)
    kinetic, potential, elastic = kinetic_potential_elastic(loads.masses, loads.gravity, loads.spring, loads.torsion,
                                                            motion[0], motion[1], motion[3])  # fmt: skip
    balance = kinetic + potential + elastic + scalars[_DISSIPATED] - scalars[_WORK]
    energy[k, 0], energy[k, 1], energy[k, 2] = kinetic, potential, elastic
    energy[k, 3], energy[k, 4], energy[k, 5] = scalars[_DISSIPATED], scalars[_WORK], balance - scalars[_BALANCE0]
    drift[k, 0], drift[k, 1] = phi, drift_norm
    for c in range(q.size):
        coordinates[k, c], velocities[k, c], accelerations[k, c] = q[c], v[c], a[c]
    outputs, reaction_work, rows = forces
    if rows.shape[1]:
        fill_force_outputs(outputs, work[3], lam, motion[0], motion[3], work[5], reaction_work, rows[k])


@njit(inline="always", **JIT)
def _copy_state(source, target):
    """q, q̇, q̈, ã and λ (the first five arrays) of `source` into `target`."""
    for c in range(source[0].size):
        target[0][c], target[1][c], target[2][c], target[3][c] = source[0][c], source[1][c], source[2][c], source[3][c]
    for r in range(source[4].size):
        target[4][r] = source[4][r]


@njit(**JIT)
def _advance_samples(model, state, settings, rules_, times, out, forces):
    """Integrate from the state to each of `times` in turn, publishing row k of `out`
    ``(coordinates, velocities, accelerations, iterations, energy, drift)`` (and of
    ``forces[2]``) at ``times[k]``; returns the samples solved.  At a sample it cannot
    solve it stops with the state of the sample before (see the module docstring)."""
    constraints, loads, saddle = model
    q0 = state[0]
    n, m, n_kept = q0.size, constraints[4].size, constraints[7].size
    size = n + n_kept
    n_laws = state[9]
    work = (np.zeros(n + 3), np.zeros((n // 3 + 1, 2)), np.zeros(m), np.zeros(constraints[1][-1] + 1),
            constraints[4].copy(), np.zeros(m), np.zeros(n_kept), np.zeros((3, constraints[5].size)),
            np.zeros((3, n_laws)))  # fmt: skip
    n_triplets = saddle[0].size
    motion = (np.zeros(n + 3), np.zeros(n + 3), np.zeros(n + 3), np.zeros((n // 3 + 1, 2)))
    system = (motion, np.zeros(n + 3), np.zeros(saddle[1][-1] + 1),
              (np.zeros(n_triplets, dtype=np.int64), np.zeros(n_triplets, dtype=np.int64), np.zeros(n_triplets)),
              (np.zeros(6), np.zeros(6), np.zeros((2, 6)), np.zeros((6, 6)), np.zeros((6, 6))), np.zeros(n_laws),
              (np.zeros(m), np.zeros(n), np.zeros(size), np.zeros(size), np.zeros(size), np.zeros(size),
               np.zeros(size)),
              (np.zeros(n), np.zeros(size), np.zeros(size)))  # fmt: skip
    after = (np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(m))
    saved = (np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(m), np.zeros(state[5].size))
    scalars, counts = state[5], state[8]
    max_step, max_halvings, growth_after = settings[6], rules_[6], rules_[7]
    iterations = out[3]
    for k in range(times.size):
        t = times[k]
        _copy_state(state, saved)
        for j in range(scalars.size):
            saved[5][j] = scalars[j]
        step, good, before = scalars[_STEP], 0, counts[_NEWTON]
        while scalars[_TIME] < t:
            now = scalars[_TIME]
            remaining = t - now
            h = remaining if remaining <= step * (1.0 + 1e-9) else step
            outcome = _step(model, work, system, state, settings, rules_, h, t if h == remaining else now + h, after)
            if outcome == _OK:
                _copy_state(after, state)
                scalars[_TIME] = t if h == remaining else now + h
                good += 1
                if step < max_step and good >= growth_after:
                    step, good = min(2.0 * step, max_step), 0
                continue
            step *= 0.5
            good = 0
            counts[_SUBDIVISIONS] += 1
            counts[_FACTORED] = 0
            if outcome == _HAND_BACK or step < max_step * 0.5**max_halvings:
                _copy_state(saved, state)
                for j in range(scalars.size):
                    scalars[j] = saved[5][j]
                return k
        scalars[_STEP] = step
        iterations[k] = counts[_NEWTON] - before
        _publish(model, work, system, state, k, out, forces)
    return times.size


class CompiledDynamicsLoop:
    """The compiled generalized-α loop as a block stepper (`sparsekin.solve.steppers.BlockStepper`).

    The first sample is the Python stepper's `start`; every block after it runs in one
    compiled call from the state of the sample before.  At a sample the loop cannot
    solve, the Python stepper resumes from the last sample solved (`stepper.resume`) and
    solves the rest one sample per block, failing there with the detailed error if it
    must.

    Attributes
    ----------
    fell_back : bool
        Whether the Python stepper took over.
    n_compiled : int
        Samples the compiled loop solved.

    Parameters
    ----------
    stepper : GeneralizedAlphaStepper
        Not started yet; ``stepper.compiled_settings()`` gives the step's parameters and rules.
    chunk : int
        Most samples per block (at most `MAX_BLOCK`).
    forces : ForceOutputs, optional
        The force columns to record (`sparsekin.engine.force_columns`).
    """

    def __init__(self, stepper, chunk: int, forces=None) -> None:
        self.stepper, self.forces = stepper, forces
        self._steps = SampleSteps(stepper, stepper.recorded)
        self._chunk = max(1, min(int(chunk), MAX_BLOCK))
        self._state = None
        self.fell_back = False
        self.n_compiled = 0  # samples the compiled loop solved

    def advance_block(self, times: np.ndarray) -> SampleBlock:
        python = self.stepper
        if python.time is None or self.fell_back:
            return self._steps.advance_block(times)
        if self._state is None:
            self._prepare()
        count = min(len(times), self._chunk)
        times = np.ascontiguousarray(times[:count], dtype=float)
        out = tuple(array[:count] for array in self._out)
        forces = (*self._forces[:2], self._forces[2][:count])
        counts = self._state[8].copy()
        solved = int(_advance_samples(self._model, self._state, self._settings, self._rules, times, out, forces))
        self._count(self._state[8] - counts)
        self.n_compiled += solved
        if solved < count:
            self.fell_back = True
            q, v, a, pseudo, lam, scalars = (array.copy() for array in self._state[:6])
            python.resume(q, v, a, pseudo, lam, scalars[_TIME], scalars[_STEP], scalars[_WORK], scalars[_DISSIPATED],
                          (scalars[_POWER], scalars[_DAMPING]))  # fmt: skip
            if solved == 0:
                return self._steps.advance_block(times)
        recorded = {ENERGY: out[4][:solved], DRIFT: out[5][:solved]}
        if self.forces is not None:
            recorded[FORCES] = forces[2][:solved]
        return SampleBlock(times[:solved], out[0][:solved], out[1][:solved], out[2][:solved], out[3][:solved], recorded)

    def stats(self) -> StepperStats:
        python = self.stepper.stats()
        return python._replace(n_factorizations=python.n_factorizations + self._factorizations,
                               n_solves=python.n_solves + self._solves)  # fmt: skip

    _factorizations = _solves = 0

    def _count(self, counts: np.ndarray) -> None:
        """The Python stepper's counters moved on by the compiled loop's."""
        python = self.stepper
        python.n_steps += int(counts[_STEPS])
        python.n_subdivisions += int(counts[_SUBDIVISIONS])
        python.n_newton += int(counts[_NEWTON])
        python.n_stalls += int(counts[_STALLS])
        self._factorizations += int(counts[_FACTORIZATIONS])
        self._solves += int(counts[_SOLVES])

    def _prepare(self) -> None:
        """The model's arrays and the state after the Python stepper's start."""
        python = self.stepper
        system, pattern = python.system, python.pattern
        assembler, loads, kept = system.assembler, system.loads, system.kept_rows
        actuators = actuator_kernel_arrays(loads.actuators, loads.n_laws, pattern.n_bodies)
        constraints = (pattern.primitives, pattern.indptr, pattern.indices,
                       assembler.weights, pattern.target.astype(float), pattern.driven_row,
                       python.discretization.driver_laws.table, kept.astype(np.int64), system.kept_row,
                       np.ascontiguousarray(assembler.weights[kept]), pattern.coordinate_weights)  # fmt: skip
        saddle = system.saddle
        self._model = (constraints, (loads.arrays, loads.laws, actuators), (saddle.slots, saddle.indptr, saddle.indices))
        self._settings, self._rules = python.compiled_settings()
        start = python.state
        power, damping = python.power
        scalars = np.array([start.time, start.step, start.work, start.dissipated, power, damping, python.balance0])
        counts = np.zeros(7, dtype=np.int64)
        self._state = (start.coordinates.copy(), start.velocities.copy(), start.accelerations.copy(),
                       start.pseudo_accelerations.copy(), start.multipliers.copy(), scalars,
                       np.zeros((system.size, system.size)), np.zeros(system.size, dtype=np.int64), counts,
                       int(loads.n_laws))  # fmt: skip
        n, rows = pattern.n_coordinates, self._chunk
        self._out = (np.zeros((rows, n)), np.zeros((rows, n)), np.zeros((rows, n)), np.zeros(rows, dtype=np.int64),
                     np.zeros((rows, 6)), np.zeros((rows, 2)))  # fmt: skip
        outputs = ForceOutputs(python.discretization, (), ()) if self.forces is None else self.forces
        self._forces = (outputs.arrays(), np.zeros((len(outputs.joint_indices), 3)),
                        np.zeros((rows, outputs.n_columns)))  # fmt: skip
