"""The constraint projections of forward dynamics (`sparsekin.solve.dynamics`): after each
step the velocities are moved onto Φq q̇ + Φt = 0 and the accelerations onto Φq q̈ = γ by
the smallest change in the metric of the iteration matrix's leading block (ALI3-P).

`ConstraintProjections` is the part of `GeneralizedAlphaStepper` that solves them
(`_project`, on the held factorization with iterative refinement on the matrix at the
converged state; on the large path both in one refinement, `_project_together`, each pass
solving the two right-hand sides in one pass over the factors); the stepper chooses their
targets, bounds and noise.  It uses the
stepper's ``system``, ``solver``, ``assembler``, ``pattern``, ``_floor``, ``_weights``,
``_projection_work``, ``_pair_work``, ``_last_projections``, ``_projection_step``, ``_factor``,
``_publishes`` and ``n_singular_projections``, and sets its ``_velocity_drift``.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine import _dynamics_kernels, _projection_kernels
from .error_control import StepFailed as _StepFailed

__all__ = ["PROJECTION_ITERATIONS", "REFINEMENT_CONTRACTION", "SAME_STEP", "TARGET_MARGIN", "WARM_START",
           "ConstraintProjections"]

#: Most solves of one velocity projection, and the contraction its iterative refinement
#: must keep on the held factorization.
PROJECTION_ITERATIONS = 8
REFINEMENT_CONTRACTION = 0.1
#: `ConstraintProjections._project_together` makes the acceleration target again after a
#: velocity increment unless the move of the target per unit increment, measured at the
#: step's first increment, predicts a move within this fraction of the acceleration bound.
TARGET_MARGIN = 0.01
#: `ConstraintProjections._project_together` starts each projection from its change of the
#: step before (same h) instead of from zero where `RoundingFloor.starts_cold` does not
#: predict that two solves from zero will do (False: from zero, as `_project` does).
WARM_START = True
#: Steps within this relative difference are the same step for `WARM_START` (the steps of a
#: run at a fixed largest step differ in their last bits: t − t₋₁).
SAME_STEP = 1e-9


class ConstraintProjections:
    """The projections' solves, a base of `sparsekin.solve.dynamics.GeneralizedAlphaStepper`."""

    def _project(self, q, v, lam, coefficients, drift, bound: float, what: str, noise: float = 0.0,
                 acts_above: float | None = None):
        """The smallest change Δ, in the metric A, that removes `drift` (Φq times the
        velocities or accelerations minus their target, every equation) and its
        multipliers μ, ``[Δ; μ]`` (None if the drift is within `bound` already):

            [[A, Φqᵀ], [Φq, 0]] [Δ; μ] = [0; drift],

        A the iteration matrix's leading block and Φq at the converged q.  The held
        factorization (of an earlier state) preconditions iterative refinement on the
        matrix at q, refactored when the refinement stops contracting, or contracts too
        slowly to reach `bound` in the solves left (`_converges_in_time`): a correction along
        stale normals would turn part of it along the motion, an energy error that adds
        up step after step.  Where Φq has lost rank for an instant the refinement stalls
        even on a fresh factorization (its (2, 2) block −r I makes it a penalty projection
        there, ALI3-P's): what it removed is kept if it left less drift than there was —
        the rest lies along Φq's vanishing singular values σ, where the drift is σ times
        the velocity error and removing it would take a change drift / σ along a direction
        that the rounding decides.  An increment below `noise` ends the refinement once the
        drift left is within `bound`.  With `acts_above` below `bound` a drift between the two
        takes one pass (the acceleration projection's stability target, whatever the
        tolerance: `error_control.ACCELERATION_TOLERANCE`).  On the large path the
        refinement's residual is formed without assembling the matrix (`DynamicSystem.product`)."""
        system, n = self.system, self.system.n
        weights = system.kept(self.assembler.weights)
        drift = system.kept(drift)
        before = _dynamics_kernels.weighted_norm(drift, weights)
        if before <= (bound if acts_above is None else min(bound, acts_above)):  # (as `_Column`)
            return None
        # in two arrays made at `start` (10^6 bodies: no temporaries), the increments solved in
        # place of the residual [0; drift] − S · solution
        solution, residual, zeros = self._projection_work[0], self._projection_work[1], self._projection_work[4]
        residual[:n], residual[n:], solution[:] = 0.0, drift, 0.0
        matrix, last, fresh, filled = None, math.inf, False, False
        for iteration in range(PROJECTION_ITERATIONS):
            increment = self.solver.solve(residual, out=residual)
            solution += increment
            size = _dynamics_kernels.weighted_norm(increment[:n], self._weights)
            if size <= bound or (size <= noise and self._drift_left(drift, solution) <= bound):
                if math.isfinite(last):
                    self._floor.refined(what, size / last)
                return solution
            if (iteration == 0 and self._floor.skips_refinement(what, size, noise)
                    and self._drift_left(drift, solution) <= bound):  # fmt: skip
                return solution  # the next increment would be far below the noise (`RoundingFloor`)
            if size > REFINEMENT_CONTRACTION * last or not (fresh or _converges_in_time(
                    size, size / last, bound, PROJECTION_ITERATIONS - iteration - 1)):  # fmt: skip
                if fresh:
                    break
                self._factor(q, v, zeros, lam, coefficients)
                matrix, fresh, filled = None, True, False
                residual[:n], residual[n:], solution[:] = 0.0, drift, 0.0
                last = math.inf
                continue
            last = size
            if self._floor.enabled:  # the large path: S x without assembling S
                product = system.product(q, v, zeros, lam, *coefficients, solution, residual, same_state=filled)
                filled = True
            else:
                matrix = self._projection_matrix(q, v, lam, coefficients) if matrix is None else matrix
                product = matrix @ solution
            np.subtract(0.0, product[:n], out=residual[:n])
            np.subtract(drift, product[n:], out=residual[n:])
        left = self._drift_left(drift, solution)
        if left <= bound:  # Φq near a loss of rank: the normal direction is ill-determined, the drift is not
            return solution
        if fresh and left <= before:
            self.n_singular_projections += 1
            return solution
        raise _StepFailed(f"the {what} projection does not converge (increment {size:.3g})")

    def _apply_acceleration_change(self, a, lam, change) -> tuple:
        """q̈ less the projection's change and λ less its multipliers, in arrays of their own
        (`StateArrays`) where Newton's stay for the next step's Newton to start from: returns
        the projected q̈ and λ and Newton's λ (on the dense path None, λ changed in place)."""
        projected = np.subtract(a, change[: a.size], out=self._arrays.take(a.size))
        if self._floor.enabled and self.system.kept_rows.size == self.pattern.n_equations:  # (no copy of λ first)
            return projected, np.subtract(lam, change[a.size :], out=self._arrays.take(lam.size)), lam
        newton_lam = None
        if self._floor.enabled:
            newton_lam, lam = lam, self._arrays.copy_of(lam)
        if self.system.kept_rows.size == self.pattern.n_equations:
            lam -= change[a.size :]
        else:
            lam[self.system.kept_rows] -= change[a.size :]
        return projected, lam, newton_lam

    def _project_together(self, q, v, a, lam, coefficients, velocity: tuple, acceleration: tuple):
        """Both projections of the large path in one refinement, their solves paired (one
        pass over the factors for both right-hand sides, `RefactorSolver.solve_pair`):
        the velocities are moved in place; returns the accelerations' change and
        multipliers ``[Δ; μ]`` (None if none is needed).

        `velocity` and `acceleration` are the targets ``(drift, bound, noise)`` of
        `_paired_targets` (which keeps Φq q̈ for the acceleration drifts at moved
        velocities).  The acceleration target γ(q, v) depends on the projected
        velocities: its first solve takes the drift at the
        velocities before their projection, and every later test and residual the drift
        at the velocities moved so far (made again after each velocity increment; an
        acceleration projection found done is tested again at the new target).  Each
        column stops by `_project`'s rules (its increment within its bound, or within its
        noise with the drift left within its bound, or after one solve when
        `RoundingFloor.skips_refinement`); a refinement that stops contracting refactors
        the matrix at the current state, and the columns not done start again on it.
        Measured on the N-four-bar chain (10^4 bodies): projecting the velocities moves the
        acceleration target by 6e-11 (its bound 1e-10), an increment of 4e-9 against the
        refinement's noise of 4e-6.

        A column starts from its change of the step before (`_Column.warm`: its solution
        array kept from that step, taken at the same h) rather than from zero: the changes
        move slowly (10^4 bodies, after the crossing: 2.4e-5 and 4.8e-2, the same to 0.5 %
        the next step), so that 2 passes reach the noise where 3–5 did from zero on a held
        matrix a few steps old.  At least two passes: the first only corrects that change,
        its increment measures its Δ and not its μ (a multiplier error that the next pass
        turns into Δ through the held matrix's stale Φq; stopping there left B0 0.7 % off).
        It starts from zero instead where the contraction measured lately predicts that two
        solves from zero will do (`RoundingFloor.starts_cold`: a 10^5-body chain at every
        step; a 10^4-body chain after its crossing takes 3–5 from zero), as a warm start
        takes a residual pass more."""
        system, n = self.system, self.system.n
        weights = system.kept(self.assembler.weights)
        zeros, drift_out = self._projection_work[4], self._projection_work[3]
        # (h, velocities and accelerations solved, the sizes of their changes)
        last, step = self._last_projections, self._projection_step
        warm = WARM_START and last is not None and math.isclose(last[0], step, rel_tol=SAME_STEP)
        work, cold = self._projection_work, self._floor.starts_cold
        warm_moves = warm and last[1] and not cold("velocity", last[3], velocity[2])
        warm_follows = warm and last[2] and not cold("acceleration", last[4], acceleration[2])
        moves = _Column("velocity", *velocity, work[0], work[1], weights, system, warm_moves)
        follows = _Column("acceleration", *acceleration, *self._pair_work[:2], weights, system, warm_follows,
                          self._acceleration_acts_above)  # fmt: skip
        columns = (moves, follows)  # the velocities move; the accelerations' target follows them
        fresh, filled, gain, paired = False, False, None, hasattr(self.solver, "solve_pair")
        self._last_projections = None  # their solution arrays hold this step's changes only once it is done
        self._velocity_drift = None  # (the published drift: made with the drift left at the final velocities)
        if moves.warm_started or follows.warm_started:
            self._warm_residuals(q, v, lam, coefficients, moves, follows, drift_out)
            filled = True
        for iteration in range(PROJECTION_ITERATIONS):
            active = [column for column in columns if column.active]
            if not active:
                break
            if len(active) == 2 and paired:
                self.solver.solve_pair(moves.residual, follows.residual)
            else:
                for column in active:
                    self.solver.solve(column.residual, out=column.residual)
            # each solution += its increment (a first solve since `start`: 0 + increment), the increments'
            # sizes, and the velocities moved by theirs, in one call
            first, second = active[0], active[-1]
            first.size, size = _projection_kernels.add_increments(
                first.solution, first.residual, first.first and not first.warm_started, second.solution,
                second.residual, second.first and not second.warm_started, second is not first, self._weights, n, v,
                first is moves)  # fmt: skip
            second.size = size if second is not first else first.size
            for column in active:
                column.solves += 1
                if not column.warm_started and column.solves == 1:  # its change, within the contraction
                    column.opening = column.size
                elif not column.warm_started and column.solves == 2 and column.opening > 0.0:
                    self._floor.contracted(column.what, column.size / column.opening)  # (`starts_cold`)
            if moves in active:  # (moved by `add_increments`)
                self._velocity_drift = None
            if moves in active and (gain is None or gain * moves.size > TARGET_MARGIN * follows.bound):
                # the accelerations' target at the moved velocities, and (first) how far it moved
                moved = self._move_acceleration_target(q, v, follows, gain is None)
                if gain is None:  # how far the target moves per velocity increment, this step
                    gain = moved / moves.size if moves.size > 0.0 else math.inf
            restart, lefts = False, self._paired_drift_lefts(active, v)
            for column in active:
                if column.warm_started and column.first:
                    column.last = column.size  # the last step's change corrected: one more pass at least
                elif column.size <= column.bound or (column.size <= column.noise
                                                   and self._column_left(lefts, column) <= column.bound):  # fmt: skip
                    if math.isfinite(column.last) and not column.warm_started:  # (a contraction from zero)
                        self._floor.refined(column.what, column.size / column.last)
                    column.active, column.done = False, True
                elif (column.first and self._floor.skips_refinement(column.what, column.size, column.noise)
                        and self._column_left(lefts, column) <= column.bound):  # fmt: skip
                    column.active, column.done = False, True
                elif column.size > REFINEMENT_CONTRACTION * column.last or not (fresh or _converges_in_time(
                        column.size, column.size / column.last, column.bound,
                        PROJECTION_ITERATIONS - iteration - 1)):  # fmt: skip
                    if fresh:
                        column.active = False  # tested at the end, as `_project` does
                    else:
                        restart = True
                else:
                    column.last = column.size
                column.first = False
            if moves in active and follows not in active and follows.drift_left(self) > follows.bound:
                follows.resume()  # done (or never needed) at the velocities before: not at these
            if restart:  # a fresh matrix at the current state; the columns not done start again
                self._factor(q, v, zeros, lam, coefficients)
                fresh, filled = True, False
                if moves.started and not moves.done:  # (not started: its solution is an earlier step's)
                    v += moves.solution[:n]
                    self._velocity_drift = None
                    moves.start()
                    follows.drift = system.kept(self._moved_acceleration_drift(q, v, drift_out))
                    follows.start()
                elif not follows.done:
                    follows.start()
                continue
            refined = [(column.solution, column.drift, column.residual) for column in columns
                       if column.active and not column.first]  # fmt: skip
            if refined:  # their residuals [0; drift] − S · solution, in one pass
                system.residuals(q, v, zeros, lam, *coefficients, *refined, same_state=filled)
                filled = True
        for column in columns:
            if column.started and column.first:  # started again, not solved since: no change yet
                column.solution[:] = 0.0
            if column.done or not column.started:
                continue
            left = self._drift_left(column.drift, column.solution)
            if left <= column.bound:
                continue
            if fresh and left <= column.before:
                self.n_singular_projections += 1
                continue
            raise _StepFailed(f"the {column.what} projection does not converge (increment {column.size:.3g})")
        changes = (column.change(self._weights) for column in columns)
        self._last_projections = (step, moves.started, follows.started, *changes)
        return follows.solution if follows.started else None

    def _warm_residuals(self, q, v, lam, coefficients, moves, follows, drift_out) -> None:
        """The residuals of `_project_together`'s columns started from the step before's changes
        (`_Column.warm`), in one pass: the velocities moved by theirs first, and the
        accelerations' target made again at them (an acceleration column started from zero
        starts again from its new drift)."""
        n = self.system.n
        if moves.warm_started:
            v -= moves.solution[:n]
            follows.drift = self.system.kept(self._moved_acceleration_drift(q, v, drift_out))
            if not follows.active and follows.drift_left(self) > follows.bound:
                follows.resume()  # (from zero: its residual is its drift)
            elif follows.active and not follows.warm_started:
                follows.start()
        refined = [(column.solution, column.drift, column.residual) for column in (moves, follows)
                   if column.warm_started]  # fmt: skip
        self.system.residuals(q, v, self._projection_work[4], lam, *coefficients, *refined)

    def _paired_targets(self, q, v, a, coefficients, h: float) -> tuple:
        """`_velocity_target` and `_acceleration_target` of the large path (``(drift, bound,
        noise)`` each), both drifts in one pass over Φq (`fill_drift_pair`: the same numbers),
        Φq q̈ kept for the acceleration drifts at moved velocities (`_moved_acceleration_drift`)."""
        self._projection_step = h  # (`_project_together` starts from the last changes at the same h only)
        velocity = self._velocity_target(v, coefficients, h, drift=False)
        made = self._drifts_made  # (both drifts, Φq q̈ and γ at (q, v) made with Newton's last refill: `_refill`)
        acceleration = self._acceleration_target(q, v, a, coefficients, None, made)  # γ at (q, v), bound, noise
        p, assembler, work, pair = self.pattern, self.assembler, self._projection_work, self._pair_arrays()
        if not made:
            _dynamics_kernels.fill_drift_pair(p.indptr, p.indices, assembler.values, v, assembler.velocity_rhs,
                                              work[2], a, assembler.acceleration_rhs, work[3], pair[2])  # fmt: skip
        self._drifts_made = False
        return (work[2], *velocity[1:]), (work[3], *acceleration[1:])

    def _pair_arrays(self) -> tuple:
        """The accelerations' solution and residual, and Φq q̈ (`_pair_work`, made at the first call)."""
        if self._pair_work is None:
            size, m = self.system.size, self.pattern.n_equations
            self._pair_work = (np.zeros(size), np.zeros(size), np.zeros(m))
        return self._pair_work

    def _refill(self, q, v, a, lam, scale: float, settled: bool, last: bool) -> tuple:
        """Φ and Φq at Newton's iterate q: ``(the weighted norm of Φ, whether Newton's
        right-hand side is finite, None where it is not made)``, in one pass with what follows
        where the model allows it (`DynamicSystem.fill_constraints_newton_rhs`): Newton's
        right-hand side (scaled by `scale`, into ``_rhs``) where Newton goes on (not
        `settled`, not the `last` iterate); on the large path, where it may stop (`settled`),
        the projections' drifts, Φq q̈ and γ at (q, v, q̈), which `_paired_targets` takes
        (`_drifts_made`: the iterate that ends Newton is the last refill)."""
        system, self._drifts_made = self.system, False
        if not (settled or last):
            made = system.fill_constraints_newton_rhs(q, v, a, lam, scale, self._rhs)
            if made is not None:
                return made
        elif settled and self._floor.enabled:
            work = self._projection_work
            norm = system.fill_constraints_drifts(q, v, a, work[2], self._pair_arrays()[2], work[3])
            if norm is not None:
                self._drifts_made = True
                return norm, None
        return system.fill_constraints(q), None

    def _moved_acceleration_drift(self, q, v, out):
        """The acceleration drift Φq q̈ − γ(q, v) of `_project_together` at the velocities `v`
        moved so far (every equation, into `out`): γ made again, Φq q̈ that of `_paired_targets`
        (q̈ and Φq have not changed since), in one pass (`Assembler.fill_acceleration_drift`)."""
        self.assembler.fill_acceleration_drift(q, v, self._pair_work[2], out)
        return out

    def _move_acceleration_target(self, q, v, follows, measure: bool) -> float:
        """`follows`'s drift made again at the moved velocities `v` (`_moved_acceleration_drift`);
        with `measure`, returns the weighted norm of its move (else 0).  When every equation is
        kept its drift is the array made again, and the move is measured in the same pass."""
        system, out = self.system, self._projection_work[3]
        if follows.drift is out:
            return self.assembler.fill_acceleration_drift(q, v, self._pair_work[2], out,
                                                          self.assembler.weights if measure else None)  # fmt: skip
        before = follows.drift
        follows.drift = system.kept(self._moved_acceleration_drift(q, v, out))
        if not measure:
            return 0.0
        return _dynamics_kernels.weighted_norm(follows.drift - before, system.kept(self.assembler.weights))

    def _paired_drift_lefts(self, active, v) -> dict:
        """The drift left (`_drift_left`) of each active column of `_project_together`, by
        name, where both will test it in this pass (their increments above the bound, and
        within the noise or skipping the refinement): one pass over Φq for both
        (`drift_left_norms`, the same numbers); else none (`_column_left` makes them).  In
        the last step of an `advance` (`_publishes`) with every equation kept, the same pass
        makes the drift of the velocities `v` that `_publish` records (`_velocity_drift`,
        which any later move of `v` clears): a pass over Φq fewer.  A warm column's first
        pass tests nothing (it takes one more pass whatever its increment): without this, a
        warm step made the pass for nothing (at 10^6 bodies 15 ms, a pass over Φq)."""
        tested = [column for column in active if column.size > column.bound and not (
            column.warm_started and column.first) and (column.size <= column.noise or (
            column.first and self._floor.skips_refinement(column.what, column.size, column.noise)))]  # fmt: skip
        if len(tested) < 2:
            return {}
        (first, second), system, p = tested, self.system, self.pattern
        publish = self._publishes and system.kept_rows.size == p.n_equations
        lefts = _dynamics_kernels.drift_left_norms(p.indptr, p.indices, self.assembler.values, system.kept_row,
                                                   first.solution[: system.n], first.drift, second.solution[: system.n],
                                                   second.drift, self.assembler.weights, v,
                                                   self.assembler.velocity_rhs, publish)  # fmt: skip
        if publish:
            self._velocity_drift = lefts[2]
        return {first.what: lefts[0], second.what: lefts[1]}

    def _column_left(self, lefts: dict, column) -> float:
        """The drift `column` leaves: from `lefts` (`_paired_drift_lefts`), else made and kept there."""
        if column.what not in lefts:
            lefts[column.what] = self._drift_left(column.drift, column.solution)
        return lefts[column.what]

    def _projection_matrix(self, q, v, lam, coefficients):
        """The matrix the projections solve with, at the converged state (`_project`)."""
        return self.system.fill_matrix(q, v, np.zeros(self.system.n), lam, *coefficients)

    def _drift_left(self, drift, solution) -> float:
        """The weighted drift of the kept equations, `drift` (theirs), after a projection's
        change ``solution[:n]`` (Φq at the converged q), in one pass."""
        system, p = self.system, self.pattern
        return _dynamics_kernels.drift_left_norm(p.indptr, p.indices, self.assembler.values, system.kept_row,
                                                 solution[: system.n], drift, self.assembler.weights)  # fmt: skip


def _converges_in_time(correction: float, rate: float, target: float, corrections_left: int) -> bool:
    """Whether corrections shrinking by `rate` each reach `target` within `corrections_left`
    more (modified Newton: a held matrix that contracts slowly is refactored before the
    step runs out of corrections, as in Hairer & Wanner's simplified Newton)."""
    return correction * rate ** max(corrections_left, 0) <= target


class _Column:
    """One projection of `ConstraintProjections._project_together`: its target, its arrays
    (``solution``, and ``residual``, in which its increments are solved) and its state."""

    def __init__(self, what: str, drift, bound: float, noise: float, solution, residual, weights, system,
                 warm: bool = False, acts_above: float | None = None) -> None:  # fmt: skip
        self.what, self.bound, self.noise, self.weights = what, bound, noise, weights
        self.drift = system.kept(drift)
        self.before = _dynamics_kernels.weighted_norm(self.drift, weights)
        self.solution, self.residual, self.n = solution, residual, system.n
        self.active = self.done = self.started = self.first = False
        self.size, self.last = math.inf, math.inf
        self.warm_started, self.opening, self.solves = False, 0.0, 0  # (opening: its first increment from 0)
        if self.before > bound:
            self.warm() if warm else self.start(measured=True)
        elif acts_above is not None and self.before > acts_above:  # within its bound, not below: one pass
            self.start(measured=True)

    def start(self, measured: bool = False) -> None:
        """From no change: the residual [0; drift] (`measured`: `before` is its drift's norm
        already).  Its solution is made by its next solve (`first`), not set to 0 here."""
        n = self.n
        if not (self.started or measured):
            self.before = _dynamics_kernels.weighted_norm(self.drift, self.weights)
        self.residual[:n], self.residual[n:] = 0.0, self.drift
        self.active, self.done, self.started, self.first, self.last = True, False, True, True, math.inf
        self.warm_started, self.opening, self.solves = False, 0.0, 0

    def warm(self) -> None:
        """From the change of the step before, still in `solution` (Δ and μ: μ from zero left
        B0 15 % off), its residual formed before the first solve (`_warm_residuals`); its
        first increment (that change's correction) never ends it."""
        self.active, self.done, self.started, self.first, self.last = True, False, True, True, math.inf
        self.warm_started = True

    def resume(self) -> None:
        """Again, from its change so far (none if it had not started): its residual is formed
        before the next solve."""
        if not self.started:
            self.start()
            return
        self.active, self.done, self.first, self.last = True, False, False, math.inf

    def change(self, coordinate_weights) -> float:
        """The weighted size of its change (0 if it did not start): its first increment from
        zero (the same within the contraction), else its solution's."""
        if not self.started:
            return 0.0
        if self.opening > 0.0:
            return self.opening
        return _dynamics_kernels.weighted_norm(self.solution[: self.n], coordinate_weights)

    def drift_left(self, projections) -> float:
        """The weighted drift its change so far leaves (its drift if it has not started)."""
        if not self.started:
            return _dynamics_kernels.weighted_norm(self.drift, self.weights)
        return projections._drift_left(self.drift, self.solution)
