"""Forward dynamics: `solve_dynamics` integrates M q̈ + Φqᵀλ = Q, Φ(q, t) = 0 in time.

The integrator is generalized-α (Arnold & Brüls 2007) on the index-3 equations, in the
absolute coordinates of the kinematics.  A step of size h from (q_n, q̇_n, q̈_n, ã_n, λ_n)
solves for q_{n+1} and λ_{n+1}

    q_{n+1}  = q_n + h q̇_n + h² (½ − β) ã_n + h² β ã_{n+1}
    q̇_{n+1}  = q̇_n + h (1 − γ) ã_n + h γ ã_{n+1}
    (1 − α_m) ã_{n+1} + α_m ã_n = (1 − α_f) q̈_{n+1} + α_f q̈_n
    f(q_{n+1}, q̇_{n+1}, q̈_{n+1}, λ_{n+1}) = M q̈ + h − Q + Φqᵀ λ = 0,   Φ(q_{n+1}, t_{n+1}) = 0

by Newton on q and λ; with ∂q̈/∂q = β′ = (1 − α_m) / (h² β (1 − α_f)) and ∂q̇/∂q = γ′ =
γ / (h β) its matrix is the saddle matrix of `sparsekin.engine.saddle`.  Scaled as in
Bottasso, Bauchau & Cardona (2008) — the first block row divided by β′ and the unknown
λ by β′ — it reads [[M + (γ′/β′) C_t + K_t/β′, Φqᵀ], [Φq, 0]], whose condition does not
grow as h⁻⁴.  The parameters follow from ρ∞, the spectral radius at infinite frequency:
α_m = (2ρ∞ − 1)/(ρ∞ + 1), α_f = ρ∞/(ρ∞ + 1), γ = ½ + α_f − α_m, β = ¼ (γ + ½)².  ρ∞ = 1
is the trapezoidal rule (no numerical damping; energy error bounded, O(h²)); smaller
ρ∞ damps the highest frequencies.

After each step the velocities are projected on Φq q̇ + Φt = 0 and then the
accelerations on Φq q̈ = γ (with the iteration matrix's leading block as the metric, as
in ALI3-P): the position constraints hold to the Newton tolerance by construction, the
velocity constraints to the same by the projection, so neither drifts, and the
accelerations and multipliers carry no undamped (−1)ⁿ oscillation at ρ∞ = 1 (on the large
path both projections share one refinement, their solves paired: `_project_together`).  Newton is
modified: the factorization of the last step is reused while its corrections contract
(`CONTRACTION`) fast enough to converge in the corrections left, refactored otherwise.  A step whose
Newton fails is halved (up to `MAX_HALVINGS` times) and the step grows back, doubling
after `GROWTH_AFTER` good steps, up to `max_step`; or chosen by its error (``rtol``, `error_control`).

The initial state: the drawing assembled at t0 by the smallest weighted change;
velocities, the bodies' `velocity` made consistent by the smallest mass-weighted change
(one solve of [[M, Φqᵀ], [Φq, 0]]); accelerations and multipliers from the same matrix.

`GeneralizedAlphaStepper` is the algorithm with its state, a `sparsekin.solve.steppers.Stepper`
(`start`, `advance`, `linearization`, `stats`; `state` and `recorded` besides);
`solve_dynamics` validates once (`SolveOptions`, `DynamicsOptions`, `Request` of
`sparsekin.solve.options`) and `run_dynamics` records through the run driver
(`sparsekin.solve.run`): the same pipeline as the kinematics, with the driver forces and
reactions made from the integrator's λ (`ForceOutputs.fill`) and the energy balance and
drift as recorded variables (`sparsekin.results.schema`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..engine import _dynamics_kernels, _kernels
from ..engine.discretization import Discretization, discretize
from ..engine.linalg import SingularMatrix
from ..engine.linearization import Linearization
from ..engine.multipliers import redundant_minimum_norm
from ..engine.newton import NEWTON_MAXITER
from ..engine.pattern import ConstraintPattern
from ..engine.reduced import kept_equations
from ..engine.saddle import DynamicSystem
from ..errors import ConvergenceError, ModelError, RedundantConstraintWarning, warn_caller
from ..model.mechanism import Mechanism
from ..results.dynamics import DynamicsResult
from ..results.recording import open_recorder
from ..results.schema import DRIFT, ENERGY, FORCES
from ._compiled_dynamics import block_stepper
from ._dynamics_start import assembled, initial_momenta, initial_velocities, redundant_equations, undetermined
from ._state_arrays import StateArrays
from .error_control import StepFailed as _StepFailed
from .error_control import StepSizeController, advance_controlled, step_acceleration_bound, step_velocity_bound
from .kinematics import recorded_result
from .observers import RecordedVariables
from .options import DynamicsOptions, Request, SolveOptions, check_progress, check_times, checked_rho_inf
from .policy import LINEAR_SOLVERS, plan_saddle_solver
from .projections import PROJECTION_ITERATIONS, REFINEMENT_CONTRACTION, ConstraintProjections, _converges_in_time
from .rounding_floor import EXTRAPOLATION_RATIO, RoundingFloor, rounding_response
from .run import run
from .steppers import SampleBlock, StepperStats

__all__ = ["GeneralizedAlpha", "DynamicState", "GeneralizedAlphaStepper", "solve_dynamics", "run_dynamics",
           "LINEAR_SOLVERS", "PROJECTION_ITERATIONS", "REFINEMENT_CONTRACTION"]

#: Default Newton and projection tolerance: the velocity error that the steps of one second
#: of motion may leave in all (lengths relative to the model size per second, rad/s).  A
#: step of h seconds leaves at most ``tolerance · h`` (`step_velocity_bound`): a Newton
#: error δq is a velocity error γ′ δq ≈ 2 δq / h, and it has the same sign step after step
#: (held matrix, smooth predictor error), so per-step errors add up over the ~1/h steps of
#: a second.  A bound per step that does not shrink with h gives an error that grows as the
#: step shrinks (the N-four-bar's error stopped falling as h², docs/design-notes.md).
DEFAULT_TOLERANCE = 1e-10
#: A correction below this multiple of the rounding of q (relative) cannot be improved.
ROUNDING = 8.0 * np.finfo(float).eps
#: A freshly factored Newton that stops contracting within STALL · √n times that floor has
#: converged as far as the matrix's conditioning allows: near singular configurations (the
#: N-four-bar at its flat crossings stalls at 4e-12), and on long chains, whose corrections
#: stall higher with their size (N-four-bar, 10^4 bodies: ~1e-11 at some steps; 10^5
#: bodies: 3e-10 to 8e-10 at every step).
STALL = 1e4
#: The same for a held factorization, whose corrections' ratio is noise below NOISE · √n
#: times the floor (it would otherwise be refactored for nothing: a 10^4-body chain did
#: so at every second step).
NOISE = 1e2
#: Most Newton corrections in one step (`SolveOptions.max_iterations`, the kinematics' default).
MAX_ITERATIONS = NEWTON_MAXITER
#: A correction of modified Newton must be at most this fraction of the one before, or
#: the matrix is refactored at the current iterate.
CONTRACTION = 0.3
#: The iteration matrix's (2, 2) block is −REGULARIZATION · (largest mass) · I: Newton's
#: multiplier updates stay bounded where Φq loses rank for an instant (sparsekin.engine.saddle).
REGULARIZATION = 1e-10
#: A failing step is halved at most this many times.
MAX_HALVINGS = 12
#: After this many good steps in a row at a reduced step, the step doubles.
GROWTH_AFTER = 4


@dataclass(frozen=True)
class GeneralizedAlpha:
    """Generalized-α parameters from the spectral radius at infinite frequency.

    Parameters
    ----------
    rho_inf : float
        In [0, 1]: 1 no numerical damping (the trapezoidal rule), 0 the most.
    """

    rho_inf: float = 0.9

    def __post_init__(self) -> None:
        checked_rho_inf(self.rho_inf)

    @property
    def coefficients(self) -> tuple[float, float, float, float]:
        """``(alpha_m, alpha_f, gamma, beta)``."""
        rho = float(self.rho_inf)
        alpha_m = (2.0 * rho - 1.0) / (rho + 1.0)
        alpha_f = rho / (rho + 1.0)
        gamma = 0.5 + alpha_f - alpha_m
        return alpha_m, alpha_f, gamma, 0.25 * (gamma + 0.5) ** 2


class DynamicState(NamedTuple):
    """The integrator's state after a step: everything the next step starts from.

    Attributes
    ----------
    time : float
        s.
    coordinates, velocities, accelerations : ndarray, shape (n_coordinates,)
        q, q̇ and q̈ (m, rad and their rates).
    pseudo_accelerations : ndarray, shape (n_coordinates,)
        Generalized-α's ã.
    multipliers : ndarray, shape (n_equations,)
        λ of every equation as the integrator solves them (0 on those left out as
        redundant; `linearization` publishes the minimum-norm ones).
    step : float
        The step the next one starts with, s.
    work, dissipated : float
        Work of the loads, actuators and drivers, and energy dissipated by dampers, since
        the start, J.
    newton_accelerations : ndarray, shape (n_coordinates,), optional
        q̈ as Newton solved the step, before the acceleration projection (None: the same as
        `accelerations`): the next step's Newton starts from them.
    newton_multipliers : ndarray, shape (n_equations,), optional
        λ as Newton solved the step, before the acceleration projection (None: the same as
        `multipliers`; the large path only): the next step's Newton starts from them.
    """

    time: float
    coordinates: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    pseudo_accelerations: np.ndarray
    multipliers: np.ndarray
    step: float
    work: float
    dissipated: float
    newton_accelerations: np.ndarray | None = None
    newton_multipliers: np.ndarray | None = None

    @property
    def newton_start(self) -> np.ndarray:
        """The q̈ the next step's Newton starts from: `newton_accelerations`, else `accelerations`."""
        return self.accelerations if self.newton_accelerations is None else self.newton_accelerations

    @property
    def newton_start_multipliers(self) -> np.ndarray:
        """The λ the next step's Newton starts from: `newton_multipliers`, else `multipliers`."""
        return self.multipliers if self.newton_multipliers is None else self.newton_multipliers


class GeneralizedAlphaStepper(ConstraintProjections):
    """Integrate a mechanism's equations of motion from sample to sample.

    Parameters
    ----------
    model : Mechanism or Discretization
    max_step : float
        Largest integration step, s (or ``dynamics.max_step``).
    integrator : GeneralizedAlpha
        Default: from ``dynamics.rho_inf``.
    tolerance : float
        Newton and projection tolerance (`DEFAULT_TOLERANCE`): the velocity error the
        steps of one second leave in all (lengths relative to the model size per second,
        rad/s; a step of h seconds leaves ``tolerance · h``).
    linear_solver : {"auto", "dense", "superlu", "refactor"}
        The saddle matrix's solver, planned by `sparsekin.solve.policy.plan_saddle_solver`
        (``"auto"``: dense LU up to `~sparsekin.solve.policy.SADDLE_DENSE_MAX_SIZE`
        unknowns, `RefactorSolver` above, a fresh SuperLU factorization each time for grid
        models from `~sparsekin.solve.policy.MIN_MESH_SADDLE_SIZE`).
    pattern : ConstraintPattern, optional
        With a Mechanism: its pattern, if built already.
    options : SolveOptions, optional
        Instead of `tolerance` and `linear_solver` (checked already); its
        ``max_iterations`` bounds the Newton corrections of a step.
    dynamics : DynamicsOptions, optional
        Instead of `max_step` (and the ρ∞ of `integrator`); its ``rtol``: `StepSizeController`.

    Attributes
    ----------
    time : float or None
        The current time, None before `start`.
    state : DynamicState
        After `start`: the current state, one value (a step writes its state into arrays
        of states let go of that nothing else holds: a caller may keep a state or its arrays).
    system : DynamicSystem
    n_steps, n_subdivisions, n_newton, n_stalls, n_singular_projections : int
        Steps accepted, step halvings, Newton corrections, Newton iterations accepted at
        the rounding floor of an ill-conditioned matrix (`STALL`, `NOISE`), projections
        accepted where Φq had lost rank (`_project`).
    redundant_rows : ndarray of int
        Equations left out as redundant (`redundant_labels` in words).

    Notes
    -----
    A `sparsekin.solve.steppers.Stepper`: `start` and `advance` return the Newton
    corrections, `linearization` publishes the sample with its λ, `stats` the counts;
    `recorded` gives the sample's energy balance and drift (the schema's ``energy`` and
    ``drift``).  ``SampleSteps(stepper, stepper.recorded)`` is its block stepper.
    """

    def __init__(self, model: Mechanism | Discretization, max_step: float | None = None, *,
                 integrator: GeneralizedAlpha | None = None, tolerance: float = DEFAULT_TOLERANCE,
                 linear_solver: str = "auto", pattern: ConstraintPattern | None = None,
                 options: SolveOptions | None = None, dynamics: DynamicsOptions | None = None) -> None:  # fmt: skip
        self.discretization = model if isinstance(model, Discretization) else discretize(model, pattern)
        self.mechanism, self.pattern = self.discretization.mechanism, self.discretization.constraints
        if dynamics is None:
            rho_inf = GeneralizedAlpha().rho_inf if integrator is None else integrator.rho_inf
            dynamics = DynamicsOptions(max_step, rho_inf)
        if dynamics.max_step is None:
            raise ValueError("`max_step` must be a positive number, got None.")
        self.max_step, self.rtol, self.controller = dynamics.max_step, dynamics.rtol, None
        self.integrator = GeneralizedAlpha(dynamics.rho_inf) if integrator is None else integrator
        self.options = SolveOptions(tolerance, MAX_ITERATIONS, linear_solver) if options is None else options
        self.tolerance = self.options.tolerance
        self.solver, self.path = None, "none"
        self.system: DynamicSystem | None = None
        self.redundant_rows = np.zeros(0, dtype=np.int64)
        self._floor = RoundingFloor(False)
        self._previous: tuple | None = None  # q̈ and λ at the start of the last step, its size
        self.n_steps = self.n_subdivisions = self.n_newton = self.n_stalls = self.n_singular_projections = 0
        self._state: DynamicState | None = None
        self._factored, self._good = False, 0  # good steps in a row at a reduced step
        self._balance0: float | None = None
        self._recorded: dict = {}
        # (a step that ends a sample makes `_publish`'s drift and energies by the way)
        self._until, self._publishes, self._velocity_drift, self._step_energies = None, False, None, None
        self._drifts_made = False  # (`_refill`)

    # ------------------------------------------------------------------ public
    @property
    def state(self) -> DynamicState:
        if self._state is None:
            raise RuntimeError("no state yet: call `start` first.")
        return self._state

    @property
    def time(self) -> float | None:
        return None if self._state is None else self._state.time

    @property
    def assembler(self):
        return self.system.assembler

    @property
    def n_factorizations(self) -> int:
        return self.solver.n_factorizations + self.solver.n_refactorizations

    def start(self, t: float) -> int:
        """The consistent initial state at time `t` (s) (`state`); no Newton correction (0).

        Raises
        ------
        ModelError
            The drawing cannot be assembled, or the motion is not determined (a moving
            part with neither mass nor constraint).
        """
        t = float(t)
        pattern = self.pattern
        n, m = pattern.n_coordinates, pattern.n_equations
        kept = self._kept_rows(t)
        self.system = system = DynamicSystem(self.discretization, kept)
        self.solver = self._make_solver(system)
        # Newton's rhs (its correction solved in place; `DynamicSystem.newton_rhs` fills it); the
        # projections': solution, residual (Newton's rhs), drift, drift left, zeros
        self._rhs = np.zeros(system.size)
        self._projection_work = (np.zeros(system.size), self._rhs, np.zeros(m), np.zeros(m), np.zeros(n))
        self._pair_work = self._last_projections = self._projection_step = None  # `_project_together`'s
        self._weights = self.pattern.coordinate_weights  # a new array at every call of the property
        self._row_weights = system.kept(system.assembler.weights)  # of the kept equations
        self._floor = RoundingFloor(self.path != "dense")
        self._previous, self._arrays = None, StateArrays()  # the states' arrays, used again
        self.controller = None if self.rtol is None else StepSizeController(
            self.rtol, *self.integrator.coefficients[2:], self._weights, self.max_step)  # fmt: skip
        masses = system.loads.arrays.masses
        self._regularization = REGULARIZATION * max(float(masses.mass.max(initial=0.0)),
                                                    float(masses.inertia.max(initial=0.0)), 1e-300)  # fmt: skip
        # (Φ and Φq at q, at time t: `assembled` returns once they are within the tolerance there)
        q = assembled(self.system, self.pattern, t, self.tolerance, 2 * self.options.max_iterations)
        # velocities: smallest mass-weighted change of the given ones; then accelerations, λ
        matrix = system.fill_matrix(q, np.zeros(n), np.zeros(n), np.zeros(m), 1.0, 0.0, 0.0)
        try:
            self.solver.factor(matrix)
            rhs = np.concatenate([initial_momenta(matrix, initial_velocities(self.mechanism, n), kept.size),
                                  system.assembler.velocity_rhs[kept]])  # fmt: skip
            v = self.solver.solve(rhs)[:n].copy()
            applied = system.applied_forces(q, v, np.zeros(n), np.zeros(n))
            system.assembler.fill_acceleration_rhs(q, v)
            solution = self.solver.solve(np.concatenate([applied, system.assembler.acceleration_rhs[kept]]))
        except SingularMatrix:
            raise ModelError(undetermined(self.mechanism, pattern)) from None
        a = solution[:n].copy()
        lam = np.zeros(m)
        lam[kept] = solution[n:]
        self._factored = False
        self._state = DynamicState(t, q, v, a, a.copy(), lam, self.max_step, 0.0, 0.0)
        self._power = system.powers(q, v, lam)
        self._balance0 = None  # the balance is measured from the first sample's
        self._publish()
        return 0

    def advance(self, t: float) -> int:
        """Integrate to time `t` (s, after the current one) in steps of at most `max_step`
        (`state`); returns the Newton corrections.

        Raises
        ------
        ConvergenceError
            A step failed after `MAX_HALVINGS` halvings; `state` is the last good one.
        """
        # (the state at the call is not kept in a local: held through the substeps of a halved
        # step it was a third state beside the two a step holds, 140 MB at 10^6 bodies)
        t, now = float(t), self.state.time
        if not t > now:
            raise ValueError(f"`t` must be after the current time {now!r}, got {t!r}.")
        step, good, before = self._state.step, self._good, self.n_newton  # good steps counted across samples
        self._until = t  # (a step that ends there makes the drift `_publish` records: `_paired_drift_lefts`)
        if self.controller is not None:  # rtol: every step chosen by its error estimate
            step = advance_controlled(self, t, MAX_HALVINGS, GROWTH_AFTER)
        while self._state.time < t:
            now = self._state.time
            remaining = t - now
            h = remaining if remaining <= step * (1.0 + 1e-9) else step
            try:
                self._state = self._step(self._state, h, t if h == remaining else now + h)
            except _StepFailed as failure:
                step *= 0.5
                good = 0
                self.n_subdivisions += 1
                self._factored = False
                self._floor.failed()
                if step < self.max_step * 0.5**MAX_HALVINGS:
                    raise ConvergenceError(f"the step from t = {now:.9g} s failed after {MAX_HALVINGS} halvings "
                                           f"({failure})", time=now + h, driver_values={}) from None  # fmt: skip
                continue
            good += 1
            if step < self.max_step and good >= GROWTH_AFTER:
                step, good = min(2.0 * step, self.max_step), 0
            if step == self.max_step:
                self._floor.recovered()
        self._state, self._good = self._state._replace(step=step), good
        self._publish(self._constraint_norm)
        return self.n_newton - before

    def linearization(self) -> Linearization:
        """The current sample (valid until the next step): Φq at q, −Φt, and λ (`multipliers`;
        no factorization of Φq: the forces take λ as it is)."""
        state, assembler, kept = self.state, self.assembler, self.system.kept_rows
        q, v = state.coordinates, state.velocities
        q_ground, v_ground, turns = np.zeros(q.size + 3), np.zeros(q.size + 3), np.zeros((q.size // 3 + 1, 2))
        q_ground[:-3], v_ground[:-3] = q, v
        _kernels.fill_body_turns(q_ground, turns)
        return Linearization(
            state.time, q, v, state.accelerations, (q_ground, v_ground, turns), assembler.values,
            assembler.csr_positions, lambda: assembler.jacobian, assembler.velocity_rhs, None,
            None if kept.size == self.pattern.n_equations else kept, self.redundant_rows, self._multipliers(),
        )  # fmt: skip

    def _multipliers(self) -> np.ndarray:
        """λ of every equation at the current sample: the integrator's, or for a model with
        redundant equations (left out, λ = 0 in the integration) the ones of minimum norm
        with the same constraint forces Φqᵀλ (`redundant_minimum_norm`; Φq is the state's,
        refilled by `_publish`)."""
        state = self.state
        if not self.redundant_rows.size:
            return state.multipliers
        return redundant_minimum_norm(self.assembler.jacobian, self.system.kept_rows, self.redundant_rows,
                                      state.multipliers)  # fmt: skip

    def recorded(self) -> dict:
        """The current sample's energy balance and drift, one row each (the schema's
        ``energy`` and ``drift``; new arrays)."""
        return self._recorded

    def stats(self) -> StepperStats:
        solver = self.solver
        if solver is None:
            return StepperStats(n_subdivisions=self.n_subdivisions, path=self.path,
                                redundant_equations=self.redundant_labels)  # fmt: skip
        return StepperStats(solver.n_factorizations, solver.n_solves, solver.n_refactorizations, self.n_subdivisions,
                            self.path, self.redundant_labels)  # fmt: skip

    def _publish(self, phi: float | None = None) -> None:
        """Φ and Φq at the state's q (what `linearization` publishes; refilled unless `phi`,
        their norm, says a step left them there), and the state's energy and drift
        (`recorded`)."""
        state, system = self._state, self.system
        q, v = state.coordinates, state.velocities
        stepped = phi is not None  # (then the drift and energies the step made where it did: `_publishes`)
        phi = system.fill_constraints(q) if phi is None else phi
        p, assembler = self.pattern, system.assembler  # ‖Φq q̇ + Φt‖ of every equation (one pass if all are kept)
        if stepped and self._velocity_drift is not None:  # made with the drifts left (`_paired_drift_lefts`)
            drift = self._velocity_drift
        elif system.kept_rows.size == p.n_equations:  # kept_row is then every row's own index
            drift = _dynamics_kernels.drift_left_norm(p.indptr, p.indices, assembler.values, system.kept_row, v,
                                                      assembler.velocity_rhs, assembler.weights)  # fmt: skip
        else:
            drift = _dynamics_kernels.weighted_norm(system.velocity_drift(v, self._projection_work[3]), assembler.weights)
        energies = self._step_energies if stepped else None
        kinetic, potential, elastic = system.energies(q, v) if energies is None else energies
        balance = kinetic + potential + elastic + state.dissipated - state.work
        if self._balance0 is None:
            self._balance0 = balance
        self._recorded = {
            ENERGY: np.array([[kinetic, potential, elastic, state.dissipated, state.work, balance - self._balance0]]),
            DRIFT: np.array([[phi, drift]]),
        }

    # ------------------------------------------------------------------ one step
    def _step(self, state: DynamicState, h: float, t_next: float) -> DynamicState:
        alpha_m, alpha_f, gamma, beta = self.integrator.coefficients
        system, solver, tol = self.system, self.solver, self.tolerance
        kept, n = system.kept_rows, system.n
        beta_prime = (1.0 - alpha_m) / (h * h * beta * (1.0 - alpha_f))
        gamma_prime = gamma / (h * beta)
        coefficients = (1.0, gamma_prime / beta_prime, 1.0 / beta_prime)
        # predictor: Newton's accelerations of the last step (before their projection),
        # extrapolated from the one before where that paid (`RoundingFloor.extrapolates`)
        # (into arrays of states let go of that no one holds: `StateArrays`)
        q, v, a = self._arrays.step_begins(n)
        self._publishes, self._velocity_drift, self._step_energies = t_next == self._until, None, None
        extrapolate = (self._previous is not None and h <= EXTRAPOLATION_RATIO * self._previous[1]
                       and self._floor.extrapolates())  # fmt: skip
        start = state.newton_start
        previous, ratio = (self._previous[0], h / self._previous[1]) if extrapolate else (start, 0.0)
        _dynamics_kernels.predict(state.coordinates, state.velocities, state.accelerations, state.pseudo_accelerations,
                                  alpha_m, alpha_f, gamma, beta, h, q, v, a, start, previous, ratio)  # fmt: skip
        del previous  # (spare once the step stands: `StateArrays` counts its references)
        lam = self._predicted_multipliers(state, h)
        system.set_time(t_next)
        if self._floor.step_begins():  # the held matrix too old (`MAX_MATRIX_AGE`)
            self._factored = False
        weights = self._weights
        rhs = self._rhs
        all_kept = kept.size == self.pattern.n_equations
        last, fresh, rate, settled, stalled = math.inf, False, CONTRACTION, False, 0.0
        # Converged: the error left in q by the last correction and the constraint residual,
        # as velocity errors (γ′ δq), within the step's share of the tolerance, or at the
        # rounding floor of q; on the large path, the error left also when it is within that
        # floor (with the residuals summed exactly a long chain's held matrix keeps contracting
        # down to it: correcting it away took a fourth correction a step).
        bound = step_velocity_bound(tol, h) / gamma_prime
        max_iterations = self.options.max_iterations
        q_size = _dynamics_kernels.weighted_norm(q, weights)  # then from `newton_update`
        for iteration in range(max_iterations + 1):  # (Φ with what follows it where it can: `_refill`)
            phi_norm, finite = self._refill(q, v, a, lam, -1.0 / beta_prime, settled, iteration == max_iterations)
            floor = ROUNDING * (1.0 + q_size)
            stall = STALL * math.sqrt(n) * floor
            if settled and self._constraints_met(phi_norm, max(bound, floor, stalled)):
                break
            if iteration == max_iterations:
                raise _StepFailed(f"no convergence in {max_iterations} corrections")
            if finite is None:  # (the residual scaled, −Φ)
                finite = system.newton_rhs(q, v, a, lam, -1.0 / beta_prime, rhs)
            if not (math.isfinite(phi_norm) and finite):
                raise _StepFailed("non-finite residual")
            if not self._factored:
                self._factor(q, v, a, lam, coefficients)
                fresh = True
            try:
                delta = solver.solve(rhs, out=rhs)
            except SingularMatrix as error:
                raise _StepFailed(str(error)) from None
            self.n_newton += 1
            correction, q_size = _dynamics_kernels.newton_update(delta, gamma_prime, beta_prime, kept, all_kept, weights,
                                                               q, v, a, lam)  # fmt: skip
            if not math.isfinite(correction):
                raise _StepFailed("non-finite correction")  # (q, v, a, λ are this attempt's: the step is halved)
            if iteration > 0:
                rate = correction / last
            else:
                self._floor.predicted(extrapolate, correction)
            left = rate / (1.0 - rate) * correction if rate < 1.0 else math.inf
            settled = left <= self._floor.settling(bound, floor) or correction <= floor
            if not settled and rate > CONTRACTION and iteration > 0:
                if correction <= (stall if fresh else self._floor.noise(NOISE * stall / STALL)):
                    # at the rounding floor of the (ill-conditioned) matrix: the ratio of two
                    # corrections there is noise, not a slow contraction
                    settled = True
                    self.n_stalls += 1
                    stalled = stall
                    self._floor.measured(correction, fresh)
                elif fresh and phi_norm <= floor and correction <= rounding_response(
                        solver, rhs, n, self._row_weights, weights, floor):  # fmt: skip
                    settled, stalled = True, stall  # Φ at q's rounding, S ill-conditioned (a flat crossing)
                    self.n_stalls += 1
                elif fresh:
                    raise _StepFailed(f"Newton does not contract ({correction:.3g} after {last:.3g})")
                else:
                    self._factored = False  # a fresh matrix at the next iterate
            elif (self._floor.enabled and not (settled or fresh) and iteration > 0
                  and correction <= self._floor.noise(NOISE * stall / STALL)):  # fmt: skip
                settled, stalled = True, stall  # within the held matrix's noise, contracting or not (`NOISE`)
                self.n_stalls += 1
            else:
                if not (settled or fresh) and iteration > 0 and not _converges_in_time(
                        correction, rate, max(bound, floor), max_iterations - iteration - 1):  # fmt: skip
                    self._factored = False  # the held matrix contracts, but too slowly for the corrections left
                fresh = False
            last = correction
        self._floor.converged(max(last, NOISE * stall / STALL))  # the projections' noise
        pseudo = self._arrays.take(n)  # ã, from q alone: the acceleration projection moves it with q̈
        _dynamics_kernels.pseudo_accelerations(q, state.coordinates, state.velocities, state.pseudo_accelerations, h,
                                               beta, pseudo)  # fmt: skip
        if self._floor.enabled:  # the large path: both projections in one refinement, paired solves
            velocity, acceleration = self._paired_targets(q, v, a, coefficients, h)
            change = self._project_together(q, v, a, lam, coefficients, velocity, acceleration)
            self._floor.step()
        else:
            self._project_velocities(q, v, lam, coefficients, h)
            self._floor.step()
            change = self._project_accelerations(q, v, a, lam, coefficients)
        if change is not None:
            pseudo -= change[:n]  # ã moves with q̈
        if self.controller is not None:  # rtol: ErrorTooLarge, the step is taken again shorter
            self.controller.check(pseudo, state.pseudo_accelerations, h, min(last, stall) if stalled else 0.0)
        # the step stands: Newton's start two steps back is spare (the projected q̈ and λ go there)
        self._arrays.retire((self._previous,), (state, (q, v, a, lam, pseudo)))
        self._previous = (start, h, state.newton_start_multipliers)  # the next step extrapolates from them
        newton, newton_lam = a, None
        if change is not None:
            a, lam, newton_lam = self._apply_acceleration_change(a, lam, change)
        if self._publishes:  # (`_publish` takes the energies at this state: the motion loaded once)
            power, self._step_energies = system.powers_and_energies(q, v, lam)
        else:
            power = system.powers(q, v, lam)
        work = state.work + 0.5 * h * (self._power[0] + power[0])
        dissipated = state.dissipated + 0.5 * h * (self._power[1] + power[1])
        self._power = power
        self.n_steps += 1
        self._constraint_norm = phi_norm  # Φ and Φq are at q, t_next
        new = DynamicState(t_next, q, v, a, pseudo, lam, state.step, work, dissipated, newton, newton_lam)
        self._arrays.retire((state,), (new, self._previous))  # what it held and these do not: spare
        return new

    def _constraints_met(self, residual: float, limit: float) -> bool:
        """Newton's last test, once its corrections have settled: the constraints' residual
        (weighted norm) within `limit`.  (A prototype of another method may stop on the
        corrections alone: benchmarks/compare_ali3p.py.)"""
        return residual <= limit

    def _factor(self, q, v, a, lam, coefficients) -> None:
        regularization = self._floor.regularization(self._regularization)
        self._factor_filled(self.system.fill_matrix(q, v, a, lam, *coefficients, regularization))

    def _factor_filled(self, matrix) -> None:
        self._floor.refactored()
        try:
            self.solver.factor(matrix)
        except SingularMatrix as error:
            raise _StepFailed(f"singular iteration matrix ({error})") from None
        self._factored = True

    def _project_velocities(self, q, v, lam, coefficients, h: float) -> None:
        """The velocities moved onto Φq v + Φt = 0 along Φq's normals (`_project`,
        `_velocity_target`)."""
        drift, bound, noise = self._velocity_target(v, coefficients, h)
        change = self._project(q, v, lam, coefficients, drift, bound, "velocity", noise)
        if change is not None:
            v -= change[: v.size]

    def _velocity_target(self, v, coefficients, h: float, drift: bool = True) -> tuple:
        """The velocity projection's drift Φq v + Φt (every equation), bound and noise.  The
        drift left is at most ``tolerance · h · max(1, ‖v‖)``: a drift d comes back as a
        velocity kick of about 2 d in the next step.  On the large path the refinement also
        stops at a fraction (`PROJECTION_NOISE`) of Newton's velocity noise γ′ · floor
        (`RoundingFloor`) once the drift is within the bound.  (Without `drift`: None in its
        place.)"""
        scale = max(1.0, _dynamics_kernels.weighted_norm(v, self._weights))
        bound = max(step_velocity_bound(self.tolerance, h) * scale, ROUNDING * NOISE * scale)
        noise = self._floor.projection_noise(coefficients[1] / coefficients[2])  # γ′ = (γ′/β′) / (1/β′)
        return self.system.velocity_drift(v, self._projection_work[2]) if drift else None, bound, noise

    def _project_accelerations(self, q, v, a, lam, coefficients):
        """The change that moves the accelerations onto Φq q̈ = γ at the projected velocities
        (`_project`, `_acceleration_target`), and its multipliers: None if none is needed
        (`_apply_acceleration_change` applies it to q̈, ã and λ, so that M q̈ + Φqᵀλ keeps
        its value)."""
        drift, bound, noise = self._acceleration_target(q, v, a, coefficients, self._projection_work[2])
        return self._project(q, v, lam, coefficients, drift, bound, "acceleration", noise,
                             self._acceleration_acts_above)  # fmt: skip

    def _acceleration_target(self, q, v, a, coefficients, out, made: bool = False) -> tuple:
        """The acceleration projection's drift Φq q̈ − γ(q, v) (every equation, into `out`),
        bound and noise.  The index-3 accelerations and multipliers carry an oscillation that
        ρ∞ = 1 does not damp (with ã = q̈, a_{n+1} = 4 (q_{n+1} − q_n − h q̇_n) / h² − a_n:
        an error in a_n comes back with the sign flipped at every step), which the
        multipliers amplify by 1/σ where Φq loses rank for an instant (σ its smallest
        singular value): Newton then failed at the N-four-bar's flat crossings.  ALI3-P
        projects the accelerations for the same reason.  The drift left is at most
        ``tolerance · max(1, ‖q̈‖)``; it acts above `_acceleration_acts_above`, from at most
        `ACCELERATION_TOLERANCE` (stability's, `step_acceleration_bound`; one pass within the
        bound).  (With `out` None: γ made, unless `made`, None in the drift's place.)"""
        assembler = self.assembler
        if not made:
            assembler.fill_acceleration_rhs(q, v)
        scale = max(1.0, _dynamics_kernels.weighted_norm(a, self._weights))
        bound = max(self.tolerance * scale, ROUNDING * NOISE * scale)
        self._acceleration_acts_above = max(step_acceleration_bound(self.tolerance) * scale, ROUNDING * NOISE * scale)
        noise = self._floor.projection_noise(1.0 / coefficients[2])  # β′
        drift = None if out is None else self.system.jacobian_product(a, assembler.acceleration_rhs, out)
        return drift, bound, noise

    def _predicted_multipliers(self, state: DynamicState, h: float) -> np.ndarray:
        """The λ Newton starts the step from (a new state array): Newton's of the last step (before
        the acceleration projection), on the large path extrapolated linearly from the step
        before's (`RoundingFloor.extrapolates_multipliers`).  Newton's q̈ start predicts its
        accelerations to 1e-10 of a step, so that its first correction is λ's error through
        the held matrix's stale Φq: on a 10^4-body chain after its flat crossing, a constant λ
        (0.37 off) left a first correction 3x too small and a second one 4x larger (the held
        matrix refactored at every step), the extrapolated one is 3e-3 off."""
        start, previous = state.newton_start_multipliers, self._previous
        if (previous is None or not h <= EXTRAPOLATION_RATIO * previous[1]
                or not self._floor.extrapolates_multipliers()):  # fmt: skip
            return self._arrays.copy_of(start)
        lam = np.subtract(start, previous[2], out=self._arrays.take(start.size))
        lam *= h / previous[1]
        lam += start
        return lam

    # ------------------------------------------------------------------ start
    def _kept_rows(self, t: float) -> np.ndarray:
        """All equations but the redundant ones (found at the drawing, as the kinematics does)."""
        self.redundant_rows = redundant_equations(self.discretization, t)
        if self.redundant_rows.size:
            labels = self.redundant_labels
            shown = ", ".join(labels[:6]) + (", …" if len(labels) > 6 else "")
            warn_caller(f"{len(labels)} redundant equations left out of the equations of motion ({shown}); the forces "
                        "of a redundant set are not unique: the minimum-norm ones are given", RedundantConstraintWarning)  # fmt: skip
        return kept_equations(self.pattern.n_equations, self.redundant_rows)

    @property
    def redundant_labels(self) -> tuple[str, ...]:
        """The equations left out as redundant, in words (``joints[3] (revolute …) x``)."""
        from ..analysis.describe import equation_label

        return tuple(equation_label(self.mechanism, self.pattern, int(r)) for r in self.redundant_rows)

    def _make_solver(self, system: DynamicSystem):
        plan = plan_saddle_solver(system.size, self.options.linear_solver, self.options.thresholds,
                                  discretization=self.discretization)  # fmt: skip
        self.path = plan.solver
        return plan.make_solver()


# ---------------------------------------------------------------------- the facade
def solve_dynamics(
    mechanism: Mechanism,
    times,
    max_step: float | None = None,
    *,
    rho_inf: float = 0.9,
    rtol: float | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    linear_solver: str = "auto",
    coordinates: bool = True,
    points=None,
    joints=None,
    forces="auto",
    store=None,
    progress=None,
) -> DynamicsResult:
    """The motion of `mechanism` under its masses, gravity and loads, at `times`.

    Parameters
    ----------
    mechanism : Mechanism
        Any mechanism whose motion its masses and constraints determine; drivers are
        prescribed motions (their forces are recorded as in inverse dynamics).
    times : array_like, shape (n_times,)
        Strictly increasing output times, s; the first is the initial state.
    max_step : float, optional
        Largest integration step, s (default: the shortest output interval, or
        ``analysis.max_step`` of the model when given).
    rho_inf : float
        Numerical damping of generalized-α, in [0, 1] (1: none).
    rtol : float, optional
        Error-controlled steps (`sparsekin.solve.error_control`), at most `max_step`: the
        local error of one step relative to the model size (rad for angles), in [1e-12,
        0.1].  Default: the model's ``analysis.rtol``, else none (steps of `max_step`).
    tolerance : float
        Newton and projection tolerance (`GeneralizedAlphaStepper`).
    linear_solver : {"auto", "dense", "superlu", "refactor"}
    coordinates, points, joints, forces, store, progress
        As for `sparsekin.solve_kinematics`.

    Returns
    -------
    DynamicsResult

    Raises
    ------
    ModelError
        If the drawing cannot be assembled or the motion is not determined.
    ConvergenceError
        If a step fails after halving; ``error.result`` holds the samples before it.
    AnalysisInterrupted
        On Ctrl-C, with the samples solved.

    Examples
    --------
    A pendulum of 1 kg on a massless 1 m link, released horizontal:

    >>> import numpy as np, sparsekin as sk
    >>> pendulum = sk.Mechanism(
    ...     points={"O": (0.0, 0.0), "P": (1.0, 0.0)},
    ...     bodies=[sk.Body("link", origin="O", points=("O", "P"), mass=1.0, com="P")],
    ...     joints=[sk.Revolute(("link", "ground"), at="O")], gravity=(0.0, -9.81))
    >>> result = sk.solve_dynamics(pendulum, times=[0.0, 0.1], max_step=1e-3)
    >>> round(float(result.point("P").position[1, 1]), 4)  # fallen ≈ g t² / 2 at first
    -0.049
    """
    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    times = check_times(times, mechanism)
    dynamics = DynamicsOptions(max_step, rho_inf, rtol).for_run(times, mechanism)
    options = SolveOptions(tolerance, MAX_ITERATIONS, linear_solver)
    check_progress(progress)
    request = Request(coordinates, points, joints, forces, energy=True)
    return run_dynamics(discretize(mechanism), times, options, dynamics, request, store=store, progress=progress)


def run_dynamics(discretization: Discretization, times: np.ndarray, options: SolveOptions, dynamics: DynamicsOptions,
                 request: Request = Request(energy=True), *, store=None, progress=None) -> DynamicsResult:  # fmt: skip
    """`solve_dynamics` on arguments checked already (`sparsekin.solve.options`): the layer
    under the facade, as `sparsekin.solve.kinematics.run_kinematics` is for the kinematics.

    ``dynamics.max_step`` must be set (`DynamicsOptions.for_run`).  The stepper runs under
    the run driver one output sample at a time (`SampleSteps`); each sample's driver
    forces and reactions come from the integrator's λ (`ForceOutputs.fill`), its energy
    and drift from the stepper (`GeneralizedAlphaStepper.recorded`).
    """
    selection = request.selection(discretization)
    stepper = GeneralizedAlphaStepper(discretization, options=options, dynamics=dynamics)
    recorder = open_recorder(selection, store, times.size, request.chunk_samples)
    variables, outputs = RecordedVariables(selection), selection.forces
    if outputs is not None:
        work, row = np.zeros((len(outputs.joint_indices), 3)), np.zeros(outputs.n_columns)

    def record(block: SampleBlock) -> None:
        forces, lin = block.recorded.get(FORCES), block.linearization
        if outputs is not None and forces is None:
            forces = outputs.fill(lin, lin.multipliers, work, row)[None]
        arrays = variables.block(block.coordinates, block.velocities, block.accelerations, forces)
        if selection.records_energy:
            arrays |= block.recorded
        recorder.add_block(block.times, arrays)

    def finish(state) -> DynamicsResult:
        return recorded_result(DynamicsResult, discretization, recorder, state.stepper.stats(), state.iterations,
                               times.size, "dynamics", n_steps=stepper.n_steps,
                               rho_inf=stepper.integrator.rho_inf)  # fmt: skip

    return run(block_stepper(stepper, options, recorder.size, outputs), times, record, finish, progress=progress,
               chunk=recorder.size)  # a compiled block stepper for small models
