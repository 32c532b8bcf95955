"""Forward dynamics of a small or chain-like model: a block of output samples in one numba call.

For a model of a few dozen coordinates the generalized-α step of
`sparsekin.solve.dynamics.GeneralizedAlphaStepper` spends its time in Python call overhead,
not in arithmetic.  `CompiledDynamicsLoop` runs the same step — predictor, modified Newton
on the scaled index-3 saddle system, velocity and acceleration projections, step halving
and growth or error-controlled steps (``rtol``: the controller of
`sparsekin.solve.error_control` in `sparsekin.solve._error_control_kernels`), the work
and dissipated energy — for a whole block of samples inside one compiled function,
on a dense or banded LU of the saddle matrix (`sparsekin.solve._saddle_factorization`:
dense for small models, banded in reverse Cuthill–McKee order for chains such as the
IFToMM N-four-bar, as `sparsekin.solve.policy.plan_compiled_factorization` plans once the
start has fixed the saddle pattern).  It calls what the
Python path calls: the constraint wiring of `sparsekin.engine._kernels`, the laws of
`sparsekin.model.laws`, the cores of `sparsekin.engine._motion_kernels` (the same
functions `sparsekin.engine.saddle.DynamicSystem` calls) and the force columns of
`sparsekin.engine._force_kernels`, with the rules and constants of
`sparsekin.solve.dynamics`; only the linear algebra is its own (LAPACK or the sparse
refactorization there, these LUs here: the two paths agree to rounding, not bit for bit).
The rules are those of the Python stepper's dense path at every size: the (2, 2) regularization
on from the first step, no measured rounding floor (`RoundingFloor`), no extrapolated predictor.
For the banded chains above `sparsekin.solve.policy.SADDLE_DENSE_MAX_SIZE` unknowns the Python
stepper runs its large path's rules instead (`RoundingFloor` enabled), so there the two paths
agree to Newton's tolerance and the integrator's error, not to rounding (IFToMM A02, N = 40,
fixed 1 ms: B0 7.11e-4 against 6.95e-4 m off the exact answer, 20 026 against 20 018 steps;
tests/test_compiled_banded.py). On a narrow band (`FRESH_BAND`) the loop factors the iteration
matrix afresh at every step's first Newton iterate (A02: 4.3 Newton corrections and 14.2 solves
a step held, 2.05 and 6.1 fresh; docs/design-notes.md, "A02 under 5 s").

The start (the drawing assembled, redundant equations, consistent velocities,
accelerations and multipliers) is the Python stepper's, run once.  Contract, as for the
compiled kinematics (`sparsekin.solve._compiled`): the loop stops at the first sample it
cannot solve — a step failed after `MAX_HALVINGS` halvings, or a solve the Python path
would raise on — and returns the samples solved before it; the Python stepper then goes
on from the last of them (its state handed over, `resume`) and fails at that sample again with the
detailed error if it must.

Supported: everything `solve_dynamics` integrates whose laws are all built in
(`sparsekin.solve._compiled.supports_compiled`'s laws; actuators included).  Other
law objects run the Python stepper (`sparsekin.solve.policy.plan_saddle_solver`), and so
does a model with redundant equations (the multipliers of a redundant set are the Python
stepper's to publish).
"""

from __future__ import annotations

import math
import sys

import numpy as np
from numba import njit

from .._jit import JIT
from ..engine._dynamics_kernels import (
    add_transposed_product,
    fill_rounding_probe,
    fill_row_products,
    kinetic_potential_elastic,
    scatter_add,
    weighted_norm,
)
from ..engine._force_kernels import fill_force_outputs
from ..engine._kernels import acceleration_rhs, fill_body_turns, residual_jacobian
from ..engine.actuators import actuator_kernel_arrays
from ..engine.force_columns import ForceOutputs
from ..engine._motion_kernels import fill_motion_forces, fill_saddle_triplets, motion_powers
from ..model.laws import fill_laws
from ..results.schema import DRIFT, ENERGY, FORCES
from ._compiled import _unsupported_law
from ._error_control_kernels import accept_step, control_rules, control_state, next_step, restore_controller, step_to
from ._saddle_factorization import compiled_factorization, factor_saddle, solve_saddle
from .policy import plan_saddle_solver
from .steppers import SampleBlock, SampleSteps, StepperStats

__all__ = ["CompiledDynamicsLoop", "block_stepper", "compiled_start", "resume", "supports_compiled_dynamics"]

#: What a step, a projection or a block ends with (`_REJECTED`: the step's local error is above rtol).
_OK, _STEP_FAILED, _HAND_BACK, _REJECTED = 0, 1, 2, 3
#: The flat tuples the compiled functions share (flat: taking an item from a tuple of
#: tuples of arrays would count a reference to every array in it, which dominated a
#: small model's step).  The model (read only):
(_PRIMITIVES, _INDPTR, _INDICES, _WEIGHTS, _TARGET0, _DRIVEN_ROW, _DRIVER_LAWS, _KEPT_ROWS, _KEPT_ROW, _KEPT_WEIGHTS,
 _COORDINATE_WEIGHTS, _LOADS, _LOAD_LAWS, _ACTUATORS, _SLOTS, _SADDLE_INDPTR, _SADDLE_INDICES) = range(17)  # fmt: skip
#: the work arrays: the constraints' side (`Assembler`), the system's (`DynamicSystem`), scratch
(_Q_CONSTRAINTS, _TURNS_CONSTRAINTS, _RESIDUAL, _JACOBIAN, _TARGET, _VELOCITY_RHS, _KEPT_RESIDUAL, _DRIVER_VALUES,
 _LAW_VALUES, _Q_GROUND, _V_GROUND, _A_GROUND, _TURNS, _APPLIED, _DATA, _ROWS, _COLS, _VALS, _SCRATCH,
 _ACTUATOR_WEIGHTS, _DRIFT, _ZEROS, _GOAL, _SOLUTION, _REFINED, _INCREMENT, _PRODUCT, _FORCE, _RHS,
 _DELTA, _V_CONSTRAINTS, _ACCELERATION_RHS) = range(32)  # fmt: skip
#: the state: q, q̇, q̈, ã, λ, Newton's q̈ (before its projection), the scalars, the held LU, the counts
_Q, _V, _A, _PSEUDO, _LAM, _START, _SCALARS, _LU, _PIVOTS, _COUNTS = range(10)
_TIME, _STEP, _WORK, _DISSIPATED, _POWER, _DAMPING, _BALANCE0, _GOOD, _REFINEMENT_RATE = range(9)
_STEPS, _SUBDIVISIONS, _NEWTON, _STALLS, _FACTORIZATIONS, _SOLVES, _FACTORED, _SINGULAR_PROJECTIONS = range(8)
#: Positions in the rules (`compiled_start`).
(_ROUNDING, _STALL, _NOISE, _CONTRACTION, _PROJECTION_ITERATIONS, _REFINEMENT_CONTRACTION, _MAX_HALVINGS,
 _GROWTH_AFTER) = range(8)  # fmt: skip
#: Most samples in one call (a Ctrl-C waits for the call to end).
MAX_BLOCK = 1000
#: The banded acceleration projection's predicted second increment within bound / this: not solved.
PREDICTED_INCREMENT_SAFETY = 10.0
#: Bands of kl + ku up to this are factored at every step (N-four-bars: 10-18; lattices: 34-58).
FRESH_BAND = 20


def supports_compiled_dynamics(mechanism) -> bool:
    """Whether every driver and load law is one the compiled loop evaluates."""
    return _unsupported_law(mechanism) is None


def block_stepper(stepper, options, chunk: int, forces=None):
    """The block stepper of a forward-dynamics run (`sparsekin.solve.dynamics.run_dynamics`):
    a `CompiledDynamicsLoop` around `stepper` (a `GeneralizedAlphaStepper` not started yet)
    where `sparsekin.solve.policy.plan_saddle_solver` plans the loop ``"compiled"`` (small
    and chain-like models whose laws are all built in), else
    ``SampleSteps(stepper, stepper.recorded)``."""
    pattern = stepper.discretization.constraints
    plan = plan_saddle_solver(pattern.n_coordinates + pattern.n_equations, options.linear_solver, options.thresholds,
                              supports_compiled_dynamics(stepper.mechanism), stepper.discretization)  # fmt: skip
    if plan.loop == "compiled":
        return CompiledDynamicsLoop(stepper, chunk, forces, options.thresholds, options.linear_solver == "auto")
    return SampleSteps(stepper, stepper.recorded)


def compiled_start(stepper) -> tuple[tuple, tuple, tuple]:
    """After ``stepper.start``: the step's parameters ``(alpha_m, alpha_f, gamma, beta,
    tolerance, max_iterations, max_step, regularization)``, its rules ``(ROUNDING, STALL,
    NOISE, CONTRACTION, PROJECTION_ITERATIONS, REFINEMENT_CONTRACTION, MAX_HALVINGS,
    GROWTH_AFTER)``, and ``(power, dissipated
    power, energy balance of the first sample)`` at its state.  (A friend of
    `GeneralizedAlphaStepper`: it reads the stepper's own state, as `resume` sets it, and
    the constants of the stepper's module, `sparsekin.solve.dynamics`, which imports this one.)"""
    rules = sys.modules[type(stepper).__module__]

    settings = (*stepper.integrator.coefficients, float(stepper.tolerance), int(stepper.options.max_iterations),
                float(stepper.max_step), float(stepper._regularization))  # fmt: skip
    constants = (rules.ROUNDING, rules.STALL, rules.NOISE, rules.CONTRACTION, rules.PROJECTION_ITERATIONS,
                 rules.REFINEMENT_CONTRACTION, rules.MAX_HALVINGS, rules.GROWTH_AFTER)  # fmt: skip
    return settings, constants, (*stepper._power, stepper._balance0)


def resume(stepper, arrays, t: float, step: float, work: float, dissipated: float, power) -> None:
    """``stepper`` (a `GeneralizedAlphaStepper`) goes on from the state the compiled loop
    reached: ``arrays = (q, q̇, q̈, ã, λ, Newton's q̈)`` at time `t` with the next `step`, the
    `work` and `dissipated` energy so far and ``power = (power, dissipated power)`` there; its
    held factorization is dropped, its sample published again."""
    q, v, a, pseudo, lam, newton = arrays
    stepper._state = type(stepper.state)(t, q, v, a, pseudo, lam, step, work, dissipated, newton)
    stepper._power = tuple(power)
    stepper._factored = False
    stepper._publish()


# ---------------------------------------------------------------------- the system
@njit(inline="always", **JIT)
def _set_time(model, work, t):
    """Driver targets and rates, and the load laws, at time `t` (`DynamicSystem.set_time`)."""
    driven_row, driver_values, law_values = model[_DRIVEN_ROW], work[_DRIVER_VALUES], work[_LAW_VALUES]
    target, velocity_rhs = work[_TARGET], work[_VELOCITY_RHS]
    fill_laws(model[_DRIVER_LAWS], t, driver_values[0], driver_values[1], driver_values[2])
    for d in range(driven_row.size):
        target[driven_row[d]] = driver_values[0, d]
        velocity_rhs[driven_row[d]] = driver_values[1, d]
    fill_laws(model[_LOAD_LAWS], t, law_values[0], law_values[1], law_values[2])


@njit(inline="always", **JIT)
def _fill_constraints(model, work, q):
    """Φ and Φq at `q`; the weighted norm of Φ on the kept rows (`DynamicSystem.fill_constraints`)."""
    q_constraints, residual, kept_residual = work[_Q_CONSTRAINTS], work[_RESIDUAL], work[_KEPT_RESIDUAL]
    kept_rows = model[_KEPT_ROWS]
    for c in range(q.size):
        q_constraints[c] = q[c]
    residual_jacobian(model[_PRIMITIVES], q_constraints, work[_TURNS_CONSTRAINTS], work[_TARGET],
                           model[_WEIGHTS], residual, work[_JACOBIAN])  # fmt: skip
    for k in range(kept_rows.size):
        kept_residual[k] = residual[kept_rows[k]]
    return weighted_norm(kept_residual, model[_KEPT_WEIGHTS])


@njit(inline="always", **JIT)
def _load(work, q, v, a):
    """The system's copies with the ground appended, and the turns at `q`."""
    q_g, v_g, a_g = work[_Q_GROUND], work[_V_GROUND], work[_A_GROUND]
    for c in range(q.size):
        q_g[c], v_g[c], a_g[c] = q[c], v[c], a[c]
    fill_body_turns(q_g, work[_TURNS])


@njit(inline="always", **JIT)
def _velocity_drift(model, work, v, out):
    """Φq v + Φt of every equation, at the last `_fill_constraints`."""
    fill_row_products(model[_INDPTR], model[_INDICES], work[_JACOBIAN], v, out)
    velocity_rhs = work[_VELOCITY_RHS]
    for r in range(out.size):
        out[r] -= velocity_rhs[r]


@njit(inline="always", **JIT)
def _kept_drift_norm(model, work, v):
    """The weighted norm of the velocity drift on the kept rows (into ``work[_KEPT_RESIDUAL]``)."""
    drift, kept_drift, kept_rows = work[_DRIFT], work[_KEPT_RESIDUAL], model[_KEPT_ROWS]
    _velocity_drift(model, work, v, drift)
    for k in range(kept_rows.size):
        kept_drift[k] = drift[kept_rows[k]]
    return weighted_norm(kept_drift, model[_KEPT_WEIGHTS])


@njit(inline="always", **JIT)
def _motion_residual(model, work, q, v, a, lam, out):
    """``M a + h − Q + Φqᵀ λ`` (`DynamicSystem.residual`)."""
    _load(work, q, v, a)
    fill_motion_forces(model[_LOADS], model[_ACTUATORS], work[_Q_GROUND], work[_V_GROUND], work[_A_GROUND],
                       work[_TURNS], work[_LAW_VALUES][0], work[_APPLIED], out)  # fmt: skip
    for c in range(out.size):
        out[c] = -out[c]
    add_transposed_product(model[_INDPTR], model[_INDICES], work[_JACOBIAN], lam, out)


@njit(**JIT)
def _fill_matrix(model, work, q, v, a, lam, coefficients, regularization):
    """The saddle matrix's CSR values (`DynamicSystem.fill_matrix`) into ``work[_DATA]``."""
    _load(work, q, v, a)
    vals = work[_VALS]
    fill_saddle_triplets(model[_LOADS], model[_PRIMITIVES], model[_ACTUATORS], work[_Q_GROUND], work[_V_GROUND],
                         work[_A_GROUND], work[_TURNS], work[_LAW_VALUES][0], lam, work[_ACTUATOR_WEIGHTS],
                         (model[_INDPTR], model[_INDICES], work[_JACOBIAN]), model[_KEPT_ROW],
                         model[_KEPT_ROWS].size, coefficients, regularization, work[_SCRATCH], work[_ROWS],
                         work[_COLS], vals)  # fmt: skip
    scatter_add(vals, model[_SLOTS], work[_DATA])


@njit(**JIT)
def _refactor(model, work, state, settings, q, v, a, lam, coefficients):
    """Fill the regularized matrix and factor it (`GeneralizedAlphaStepper._factor`)."""
    counts = state[_COUNTS]
    _fill_matrix(model, work, q, v, a, lam, coefficients, settings[7])
    counts[_FACTORIZATIONS] += 1
    if not factor_saddle(model[_SADDLE_INDPTR], model[_SADDLE_INDICES], work[_DATA], state[_LU], state[_PIVOTS]):
        return False
    counts[_FACTORED] = 1
    return True


@njit(inline="always", **JIT)
def _solve(state, rhs, out):
    """`out` = the held factorization's solution of `rhs`; False if not finite."""
    for k in range(rhs.size):
        out[k] = rhs[k]
    state[_COUNTS][_SOLVES] += 1
    solve_saddle(state[_LU], state[_PIVOTS], out)
    for value in out:
        if not math.isfinite(value):
            return False
    return True


@njit(inline="always", **JIT)
def _rounding_response(model, work, state, n, floor):
    """`sparsekin.solve.rounding_floor.rounding_response` on the held factorization (in the
    work arrays of Newton's right-hand side and correction, free after a correction)."""
    rhs, delta = work[_RHS], work[_DELTA]
    fill_rounding_probe(model[_KEPT_WEIGHTS], floor, n, rhs)
    if not _solve(state, rhs, delta):
        return 0.0
    return weighted_norm(delta[:n], model[_COORDINATE_WEIGHTS])


# ---------------------------------------------------------------------- one step
@njit(inline="always", **JIT)
def _converges_in_time(correction, rate, target, corrections_left):
    """`sparsekin.solve.projections._converges_in_time`."""
    return correction * rate ** max(corrections_left, 0) <= target


@njit(inline="always", **JIT)
def _project_velocities(model, work, state, settings, rules_, q, v, lam, coefficients, h):
    """`GeneralizedAlphaStepper._project_velocities`: nothing to do when the drift is within
    the bound (most steps), else `_refine_projection` and v ← v − Δ."""
    scale = max(1.0, weighted_norm(v, model[_COORDINATE_WEIGHTS]))
    bound = max(settings[4] * h * scale, rules_[_ROUNDING] * rules_[_NOISE] * scale)
    if _kept_drift_norm(model, work, v) <= bound:
        return _OK
    outcome = _refine_projection(model, work, state, settings, rules_, q, v, lam, coefficients, bound, False)
    if outcome == _OK:
        solution = work[_SOLUTION]
        for c in range(q.size):
            v[c] -= solution[c]
    return outcome


@njit(inline="always", **JIT)
def _project_accelerations(model, work, state, settings, rules_, after, coefficients, filled):
    """`GeneralizedAlphaStepper._project_accelerations`: a and ã ← − Δ, λ ← λ − μ (Newton's q̈
    kept), where Φq a − γ − target'' exceeds the bound on the kept rows (`filled`: `_refine_projection`)."""
    q, v, a, pseudo, lam, start = after
    kept_rows, coordinate_weights = model[_KEPT_ROWS], model[_COORDINATE_WEIGHTS]
    n, n_kept = q.size, kept_rows.size
    v_constraints, gamma = work[_V_CONSTRAINTS], work[_ACCELERATION_RHS]
    drift, kept_drift = work[_DRIFT], work[_KEPT_RESIDUAL]
    for c in range(n):
        v_constraints[c], start[c] = v[c], a[c]
    acceleration_rhs(model[_PRIMITIVES], work[_Q_CONSTRAINTS], v_constraints, work[_TURNS_CONSTRAINTS], gamma)
    driven_row, driver_values = model[_DRIVEN_ROW], work[_DRIVER_VALUES]
    for d in range(driven_row.size):
        gamma[driven_row[d]] += driver_values[2, d]
    fill_row_products(model[_INDPTR], model[_INDICES], work[_JACOBIAN], a, drift)
    for r in range(drift.size):
        drift[r] -= gamma[r]
    for k in range(n_kept):
        kept_drift[k] = drift[kept_rows[k]]
    scale = max(1.0, weighted_norm(a, coordinate_weights))
    bound = max(settings[4] * scale, rules_[_ROUNDING] * rules_[_NOISE] * scale)
    if weighted_norm(kept_drift, model[_KEPT_WEIGHTS]) <= bound:
        return _OK
    outcome = _refine_projection(model, work, state, settings, rules_, q, v, lam, coefficients, bound, filled)
    if outcome == _OK:
        solution = work[_SOLUTION]
        for c in range(n):
            a[c] -= solution[c]
            pseudo[c] -= solution[c]
        for k in range(n_kept):
            lam[kept_rows[k]] -= solution[n + k]
    return outcome


@njit(**JIT)
def _refine_projection(model, work, state, settings, rules_, q, v, lam, coefficients, bound, filled):
    """The projection's solve ``[Δ; μ]`` into ``work[_SOLUTION]`` (drift on the kept rows in
    ``work[_KEPT_RESIDUAL]``), refined on the held factorization (dense or banded), refactored when the
    refinement stalls (`GeneralizedAlphaStepper._project`; a function of its own: it runs at
    a few steps only, and compiles once).  The matrix the solution refines to is filled in
    ``work[_DATA]`` unless `filled`; then the contraction the velocity projection measured on
    the same factorization and matrix (``state[_SCALARS][_REFINEMENT_RATE]``) predicts the
    second increment (A02: the two contractions within 0.98–1.23 of each other)."""
    iterations, refinement = rules_[_PROJECTION_ITERATIONS], rules_[_REFINEMENT_CONTRACTION]
    coordinate_weights, kept_drift, kept_rows = model[_COORDINATE_WEIGHTS], work[_KEPT_RESIDUAL], model[_KEPT_ROWS]
    n, n_kept = q.size, kept_rows.size
    size_ = n + n_kept
    zeros, goal, solution, residual = work[_ZEROS], work[_GOAL], work[_SOLUTION], work[_REFINED]
    increment, product = work[_INCREMENT], work[_PRODUCT]
    before = weighted_norm(kept_drift, model[_KEPT_WEIGHTS])
    if not filled:
        _fill_matrix(model, work, q, v, zeros, lam, coefficients, 0.0)
    for k in range(size_):
        goal[k] = 0.0 if k < n else kept_drift[k - n]
        solution[k] = 0.0
        residual[k] = goal[k]
    scalars = state[_SCALARS]
    contraction = scalars[_REFINEMENT_RATE] if filled else 0.0
    scalars[_REFINEMENT_RATE] = 0.0
    last, fresh, size = math.inf, False, math.inf
    for iteration in range(iterations):
        if not _solve(state, residual, increment):
            return _HAND_BACK  # the Python stepper raises SingularMatrix here
        for k in range(size_):
            solution[k] += increment[k]
        size = weighted_norm(increment[:n], coordinate_weights)
        if last < math.inf:
            scalars[_REFINEMENT_RATE] = size / last
        if size <= bound:
            return _OK
        if iteration == 0 and contraction > 0.0 and PREDICTED_INCREMENT_SAFETY * contraction * size <= bound:
            return _OK
        slow = not (fresh or _converges_in_time(size, size / last, bound, iterations - iteration - 1))
        if size > refinement * last or slow:
            if fresh:
                break
            if not _refactor(model, work, state, settings, q, v, zeros, lam, coefficients):
                return _STEP_FAILED
            _fill_matrix(model, work, q, v, zeros, lam, coefficients, 0.0)
            fresh = True
            for k in range(size_):
                solution[k] = 0.0
                residual[k] = goal[k]
            last = math.inf
            continue
        last = size
        fill_row_products(model[_SADDLE_INDPTR], model[_SADDLE_INDICES], work[_DATA], solution, product)
        for k in range(size_):
            residual[k] = goal[k] - product[k]
    drift, left = work[_DRIFT], work[_KEPT_RESIDUAL]
    fill_row_products(model[_INDPTR], model[_INDICES], work[_JACOBIAN], solution[:n], drift)
    for k in range(n_kept):
        left[k] = goal[n + k] - drift[kept_rows[k]]
    remaining = weighted_norm(left, model[_KEPT_WEIGHTS])
    if remaining <= bound:  # Φq near a loss of rank: the normal direction is ill-determined, the drift is not
        return _OK
    if fresh and remaining <= before:  # kept where Φq has lost rank if it left less drift than there was
        state[_COUNTS][_SINGULAR_PROJECTIONS] += 1
        return _OK
    return _STEP_FAILED


@njit(inline="always", **JIT)
def _step(model, work, state, settings, rules_, h, t_next, after, control):
    """One generalized-α step of size `h` from the state into `after` ``(q, v, a, pseudo,
    lam, start)`` (`GeneralizedAlphaStepper._step`); returns `_OK`, `_STEP_FAILED`, `_HAND_BACK`
    or, with an rtol in `control` (`_advance_samples`), `_REJECTED`."""
    alpha_m, alpha_f, gamma, beta, tolerance, max_iterations = settings[:6]
    rounding, stall_factor, noise, contraction = rules_[0], rules_[1], rules_[2], rules_[3]
    q0, v0, a0, p0, lam0, s0 = state[_Q], state[_V], state[_A], state[_PSEUDO], state[_LAM], state[_START]
    scalars, counts = state[_SCALARS], state[_COUNTS]
    q, v, a, pseudo, lam, _ = after
    kept_rows, coordinate_weights, residual = model[_KEPT_ROWS], model[_COORDINATE_WEIGHTS], work[_RESIDUAL]
    n, n_kept = q.size, kept_rows.size
    force, rhs, delta = work[_FORCE], work[_RHS], work[_DELTA]
    beta_prime = (1.0 - alpha_m) / (h * h * beta * (1.0 - alpha_f))
    gamma_prime = gamma / (h * beta)
    coefficients = (1.0, gamma_prime / beta_prime, 1.0 / beta_prime)
    half_minus_beta = 0.5 - beta
    for c in range(n):  # predictor: Newton's accelerations of the last step
        a[c] = s0[c]
        predicted = ((1.0 - alpha_f) * a[c] + alpha_f * a0[c] - alpha_m * p0[c]) / (1.0 - alpha_m)
        q[c] = q0[c] + h * v0[c] + h * h * (half_minus_beta * p0[c] + beta * predicted)
        v[c] = v0[c] + h * ((1.0 - gamma) * p0[c] + gamma * predicted)
    for r in range(lam.size):
        lam[r] = lam0[r]
    _set_time(model, work, t_next)
    if state[_LU][1].size and state[_LU][3].sum() <= FRESH_BAND:  # a narrow band: factored at every step
        counts[_FACTORED] = 0
    last, fresh, rate, settled, stalled = math.inf, False, contraction, False, 0.0
    bound = tolerance * h / gamma_prime  # `step_velocity_bound`: tolerance · h per step
    for iteration in range(max_iterations + 1):
        phi_norm = _fill_constraints(model, work, q)
        floor = rounding * (1.0 + weighted_norm(q, coordinate_weights))
        stall = stall_factor * math.sqrt(n) * floor
        if settled and phi_norm <= max(bound, floor, stalled):
            break
        if iteration == max_iterations:
            return _STEP_FAILED
        _motion_residual(model, work, q, v, a, lam, force)
        if not math.isfinite(phi_norm):
            return _STEP_FAILED
        for c in range(n):
            if not math.isfinite(force[c]):
                return _STEP_FAILED
        if counts[_FACTORED] == 0:
            if not _refactor(model, work, state, settings, q, v, a, lam, coefficients):
                return _STEP_FAILED
            fresh = True
        scale = -1.0 / beta_prime
        for c in range(n):
            rhs[c] = force[c] * scale
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
            elif fresh and phi_norm <= floor and correction <= _rounding_response(
                    model, work, state, n, floor):  # fmt: skip
                settled = True  # an ill-conditioned matrix's rounding (a flat crossing)
                counts[_STALLS] += 1
                stalled = stall
            elif fresh:
                return _STEP_FAILED
            else:
                counts[_FACTORED] = 0  # a fresh matrix at the next iterate
        else:
            if not (settled or fresh) and iteration > 0 and not _converges_in_time(
                    correction, rate, max(bound, floor), max_iterations - iteration - 1):  # fmt: skip
                counts[_FACTORED] = 0  # the held matrix contracts, but too slowly for the corrections left
            fresh = False
        last = correction
    solves = counts[_SOLVES]
    outcome = _project_velocities(model, work, state, settings, rules_, q, v, lam, coefficients, h)
    if outcome != _OK:
        return outcome
    filled = counts[_SOLVES] > solves and state[_LU][1].size > 0  # banded: that projection's matrix
    hh = h * h
    for c in range(n):
        pseudo[c] = (q[c] - q0[c] - h * v0[c] - hh * half_minus_beta * p0[c]) / (hh * beta)
    outcome = _project_accelerations(model, work, state, settings, rules_, after, coefficients, filled)
    if outcome != _OK:
        return outcome
    control_rules_ = control[0]
    if control_rules_[0] > 0.0 and not accept_step(control[1], control_rules_, pseudo, p0, control[4], h,
                                                   min(last, stall) if stalled else 0.0, control[3]):  # fmt: skip
        return _REJECTED  # rtol: taken again shorter (`StepSizeController.check`)
    _load(work, q, v, a)
    power, damping = motion_powers(model[_LOADS], model[_ACTUATORS], work[_Q_GROUND], work[_V_GROUND], work[_TURNS],
                                   work[_LAW_VALUES][0], lam, model[_DRIVEN_ROW], work[_VELOCITY_RHS])  # fmt: skip
    scalars[_WORK] = scalars[_WORK] + 0.5 * h * (scalars[_POWER] + power)
    scalars[_DISSIPATED] = scalars[_DISSIPATED] + 0.5 * h * (scalars[_DAMPING] + damping)
    scalars[_POWER], scalars[_DAMPING] = power, damping
    counts[_STEPS] += 1
    return _OK


# ---------------------------------------------------------------------- samples
@njit(inline="always", **JIT)
def _publish(model, work, state, k, out, forces):
    """Row `k` of the outputs: q, q̇, q̈, energy and drift, and the force columns
    (`GeneralizedAlphaStepper._publish` and the run's force columns)."""
    q, v, a, lam, scalars = state[_Q], state[_V], state[_A], state[_LAM], state[_SCALARS]
    coordinates, velocities, accelerations, energy, drift = out[0], out[1], out[2], out[4], out[5]
    loads = model[_LOADS]
    phi = _fill_constraints(model, work, q)
    drift_all = work[_DRIFT]
    _velocity_drift(model, work, v, drift_all)
    drift_norm = weighted_norm(drift_all, model[_WEIGHTS])
    _load(work, q, v, a)
    kinetic, potential, elastic = kinetic_potential_elastic(loads.masses, loads.gravity, loads.spring, loads.torsion,
                                                            work[_Q_GROUND], work[_V_GROUND], work[_TURNS])  # fmt: skip
    balance = kinetic + potential + elastic + scalars[_DISSIPATED] - scalars[_WORK]
    energy[k, 0], energy[k, 1], energy[k, 2] = kinetic, potential, elastic
    energy[k, 3], energy[k, 4], energy[k, 5] = scalars[_DISSIPATED], scalars[_WORK], balance - scalars[_BALANCE0]
    drift[k, 0], drift[k, 1] = phi, drift_norm
    for c in range(q.size):
        coordinates[k, c], velocities[k, c], accelerations[k, c] = q[c], v[c], a[c]
    outputs, reaction_work, rows = forces
    if rows.shape[1]:
        fill_force_outputs(outputs, work[_JACOBIAN], lam, work[_Q_GROUND], work[_TURNS], work[_VELOCITY_RHS],
                           reaction_work, rows[k])  # fmt: skip


@njit(inline="always", **JIT)
def _copy_state(source, target):
    """q, q̇, q̈, ã, λ and Newton's q̈ (the first six arrays) of `source` into `target`."""
    for c in range(source[0].size):
        target[0][c], target[1][c], target[2][c], target[3][c] = source[0][c], source[1][c], source[2][c], source[3][c]
        target[5][c] = source[5][c]
    for r in range(source[4].size):
        target[4][r] = source[4][r]


@njit(**JIT)
def _work_arrays(model, n, n_laws):
    """The work arrays of a model of `n` coordinates and `n_laws` load laws (see `_Q_CONSTRAINTS` …),
    made once per run (`_advance_samples` allocates nothing)."""
    m, n_kept, n_triplets = model[_TARGET0].size, model[_KEPT_ROWS].size, model[_SLOTS].size
    size = n + n_kept
    return (np.zeros(n + 3), np.zeros((n // 3 + 1, 2)), np.zeros(m), np.zeros(model[_INDPTR][-1] + 1),
            model[_TARGET0].copy(), np.zeros(m), np.zeros(n_kept), np.zeros((3, model[_DRIVEN_ROW].size)),
            np.zeros((3, n_laws)), np.zeros(n + 3), np.zeros(n + 3), np.zeros(n + 3), np.zeros((n // 3 + 1, 2)),
            np.zeros(n + 3), np.zeros(model[_SADDLE_INDPTR][-1] + 1), np.zeros(n_triplets, dtype=np.int64),
            np.zeros(n_triplets, dtype=np.int64), np.zeros(n_triplets),
            (np.zeros(6), np.zeros(6), np.zeros((2, 6)), np.zeros((6, 6)), np.zeros((6, 6))), np.zeros(n_laws),
            np.zeros(m), np.zeros(n), np.zeros(size), np.zeros(size), np.zeros(size), np.zeros(size), np.zeros(size),
            np.zeros(n), np.zeros(size), np.zeros(size), np.zeros(n + 3), np.zeros(m))  # fmt: skip


@njit(inline="always", **JIT)
def _advance_controlled(model, work, state, settings, rules_, control, t, after):
    """Error-controlled steps to time `t` (`sparsekin.solve.error_control.advance_controlled`):
    a step whose local error is above rtol is taken again with the controller's shorter
    step, a failed one is halved and the steps after it held for `GROWTH_AFTER` steps, all
    on a fresh factorization.  Returns the step proposed for the next interval, or −1 at a
    step the Python stepper must take (`_HAND_BACK`) or below the largest step over
    2^`MAX_HALVINGS` (the Python stepper raises there)."""
    scalars, counts = state[_SCALARS], state[_COUNTS]
    rules, values = control[0], control[1]
    proposed, held = scalars[_STEP], 0
    shortest = settings[6] * 0.5 ** rules_[_MAX_HALVINGS]
    while scalars[_TIME] < t:
        now = scalars[_TIME]
        h = step_to(t - now, proposed)
        t_next = t if h == t - now else now + h
        outcome = _step(model, work, state, settings, rules_, h, t_next, after, control)
        if outcome == _OK:
            _copy_state(after, state)
            scalars[_TIME] = t_next
            proposed = next_step(values, rules, h, proposed, held == 0)
            held = max(held - 1, 0)
            continue
        counts[_FACTORED] = 0
        if outcome == _HAND_BACK:
            return -1.0
        if outcome == _REJECTED:
            proposed = next_step(values, rules, h, h, True)
        else:
            proposed, held = 0.5 * h, rules_[_GROWTH_AFTER]
            counts[_SUBDIVISIONS] += 1
        if proposed < shortest:
            return -1.0
    return proposed


@njit(inline="always", **JIT)
def _restore(saved, saved_scalars, saved_values, state, values):
    """The state, its scalars and the controller's `values` back to those of the sample before."""
    _copy_state(saved, state)
    scalars = state[_SCALARS]
    for j in range(scalars.size):
        scalars[j] = saved_scalars[j]
    for j in range(values.size):
        values[j] = saved_values[j]


@njit(**{**JIT, "_nrt": False})  # no reference counts: see the docstring
def _advance_samples(model, state, work, spare, settings, rules_, control, times, out, forces):
    """Integrate from the state to each of `times` in turn, publishing row k of `out`
    ``(coordinates, velocities, accelerations, iterations, energy, drift)`` (and of
    ``forces[2]``) at ``times[k]``; returns the samples solved.  At a sample it cannot
    solve it stops with the state of the sample before (see the module docstring).
    `work` is `_work_arrays`; `spare` is ``(after, saved, saved_scalars)``: the state after
    a step and at the sample before (q, q̇, q̈, ã, λ, Newton's q̈ each), and that sample's scalars.
    `control` is ``(rules, values, saved_values, scratch, weights)`` of the step-size controller
    (`sparsekin.solve._error_control_kernels`): with an rtol in its rules, the steps are
    error-controlled (`_advance_controlled`), else of the largest size, halved on a failure.

    Compiled without reference counting (numba's ``_nrt=False``): it allocates nothing and
    every array it touches is held by the caller for the whole call, so it needs none.
    With them, counting the references of the arrays its inlined functions take from the
    model's and work tuples was most of a small model's step (A01: ~16 µs of which ~60 %
    in ``NRT_incref``/``NRT_decref``; ~1–2 µs without).  The functions it calls keep
    theirs (`sparsekin._jit.JIT` sets ``_nrt=True`` explicitly, so none inherits this
    one's flag): the dense LU's scratch array is freed as before, and none of them returns
    an array."""
    after, saved, saved_scalars = spare
    scalars, counts = state[_SCALARS], state[_COUNTS]
    max_step, max_halvings, growth_after = settings[6], rules_[6], rules_[7]
    controlled, values, saved_values = control[0][0] > 0.0, control[1], control[2]
    iterations = out[3]
    for k in range(times.size):
        t = times[k]
        _copy_state(state, saved)
        for j in range(scalars.size):
            saved_scalars[j] = scalars[j]
        for j in range(values.size):
            saved_values[j] = values[j]
        step, good, before = scalars[_STEP], int(scalars[_GOOD]), counts[_NEWTON]  # good steps across samples
        if controlled:
            step = _advance_controlled(model, work, state, settings, rules_, control, t, after)
            if step < 0.0:
                _restore(saved, saved_scalars, saved_values, state, values)
                return k
        while scalars[_TIME] < t:
            now = scalars[_TIME]
            remaining = t - now
            h = remaining if remaining <= step * (1.0 + 1e-9) else step
            outcome = _step(model, work, state, settings, rules_, h, t if h == remaining else now + h, after, control)
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
                _restore(saved, saved_scalars, saved_values, state, values)
                return k
        scalars[_STEP], scalars[_GOOD] = step, good
        iterations[k] = counts[_NEWTON] - before
        _publish(model, work, state, k, out, forces)
    return times.size


class CompiledDynamicsLoop:
    """The compiled generalized-α loop as a block stepper (`sparsekin.solve.steppers.BlockStepper`).

    The first sample is the Python stepper's `start`; every block after it runs in one
    compiled call from the state of the sample before.  At a sample the loop cannot
    solve, the Python stepper resumes from the last sample solved (`resume`) and
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
        Not started yet (`compiled_start` reads its parameters and rules after its start).
    chunk : int
        Most samples per block (at most `MAX_BLOCK`).
    forces : ForceOutputs, optional
        The force columns to record (`sparsekin.engine.force_columns`).
    thresholds : Thresholds, optional
        The run's (`sparsekin.solve.policy.plan_compiled_factorization` plans the LU of the
        saddle matrix from them once the start has fixed its pattern).
    banded : bool
        Whether a banded LU may be planned (``linear_solver="auto"``), or the dense one only.
    """

    def __init__(self, stepper, chunk: int, forces=None, thresholds=None, banded: bool = True) -> None:
        self.stepper, self.forces = stepper, forces
        self._thresholds, self._banded = thresholds, banded
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
            factorization = None
            if not python.redundant_rows.size:  # the forces of a redundant set: the Python stepper's
                saddle = python.system.saddle
                factorization = compiled_factorization(saddle.indptr, saddle.indices, self._thresholds, self._banded)
            if factorization is None:  # (or a saddle too large for the dense LU and not banded)
                self.fell_back = True
                return self._steps.advance_block(times)
            self._prepare(factorization)
        count = min(len(times), self._chunk)
        times = np.ascontiguousarray(times[:count], dtype=float)
        out = tuple(array[:count] for array in self._out)
        forces = (*self._forces[:2], self._forces[2][:count])
        counts = self._state[_COUNTS].copy()
        solved = int(_advance_samples(self._model, self._state, self._work, self._spare, self._settings, self._rules,
                                      self._control, times, out, forces))  # fmt: skip
        self._count(self._state[_COUNTS] - counts)
        restore_controller(python.controller, self._control[1])
        self.n_compiled += solved
        if solved < count:
            self.fell_back = True
            scalars = [float(value) for value in self._state[_SCALARS]]
            resume(python, tuple(array.copy() for array in self._state[:6]), scalars[_TIME], scalars[_STEP],
                   scalars[_WORK], scalars[_DISSIPATED], (scalars[_POWER], scalars[_DAMPING]))  # fmt: skip
            python._good = int(scalars[_GOOD])
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
        if hasattr(python, "n_singular_projections"):
            python.n_singular_projections += int(counts[_SINGULAR_PROJECTIONS])
        self._factorizations += int(counts[_FACTORIZATIONS])
        self._solves += int(counts[_SOLVES])

    def _prepare(self, factorization: tuple) -> None:
        """The model's arrays and the state after the Python stepper's start, holding
        `factorization` (`sparsekin.solve._saddle_factorization.compiled_factorization`)."""
        python = self.stepper
        system, pattern = python.system, python.pattern
        assembler, loads, kept = system.assembler, system.loads, system.kept_rows
        actuators = actuator_kernel_arrays(loads.actuators, loads.n_laws, pattern.n_bodies)
        saddle = system.saddle
        self._model = (pattern.primitives, pattern.indptr, pattern.indices, assembler.weights,
                       pattern.target.astype(float), pattern.driven_row, python.discretization.driver_laws.table,
                       kept.astype(np.int64), system.kept_row, np.ascontiguousarray(assembler.weights[kept]),
                       pattern.coordinate_weights, loads.arrays, loads.laws, actuators, system.triplet_slots(),
                       saddle.indptr, saddle.indices)  # fmt: skip
        n, m = pattern.n_coordinates, python.state.multipliers.size
        self._work = _work_arrays(self._model, n, int(loads.n_laws))
        self._settings, self._rules, (power, damping, balance0) = compiled_start(python)
        values = control_state(python.controller)
        weights = pattern.coordinate_weights if python.controller is None else python.controller.weights
        self._control = (control_rules(python.controller), values, values.copy(), np.zeros(n),
                         np.ascontiguousarray(weights, dtype=float))  # fmt: skip
        start = python.state
        scalars = np.array([start.time, start.step, start.work, start.dissipated, power, damping, balance0,
                            python._good, 0.0])  # fmt: skip
        counts = np.zeros(8, dtype=np.int64)
        self._spare = (tuple(np.zeros(size) for size in (n, n, n, n, m, n)),
                       tuple(np.zeros(size) for size in (n, n, n, n, m, n)), np.zeros(scalars.size))  # fmt: skip
        # start[1:6]: q, q̇, q̈, ã, λ.  A dense factorization is held column-major (`compiled_factorization`):
        # the column-oriented substitutions of `dense_lu_solve` (a dozen per step on A03) then run along
        # contiguous memory (41 unknowns: 1.8 µs a solve against 2.4 row-major; the factorization within 5 %)
        self._state = (*(array.copy() for array in (*start[1:6], start.newton_start)), scalars, factorization,
                       np.zeros(system.size, dtype=np.int64), counts)  # fmt: skip
        rows = self._chunk
        self._out = (np.zeros((rows, n)), np.zeros((rows, n)), np.zeros((rows, n)), np.zeros(rows, dtype=np.int64),
                     np.zeros((rows, 6)), np.zeros((rows, 2)))  # fmt: skip
        outputs = ForceOutputs(python.discretization, (), ()) if self.forces is None else self.forces
        self._forces = (outputs.arrays(), np.zeros((len(outputs.joint_indices), 3)),
                        np.zeros((rows, outputs.n_columns)))  # fmt: skip
