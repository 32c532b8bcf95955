"""Error-controlled steps of forward dynamics (`rtol`): the local error of a generalized-α step and the step size.

`sparsekin.solve.dynamics.GeneralizedAlphaStepper` takes steps of its largest size,
halved after a Newton failure, unless it is given a relative tolerance ``rtol``; then
`StepSizeController` chooses every step from an estimate of the step's local error.

**The estimate.**  Generalized-α's pseudo-accelerations ã approximate the accelerations
half a shift off the grid, ã_n = q̈(t_n + Δh) + O(h²) with Δ = α_m − α_f = ½ − γ (from
(1 − α_m) ã_{n+1} + α_m ã_n = (1 − α_f) q̈_{n+1} + α_f q̈_n expanded about t_n).  Putting
that and the exact solution's Taylor series into the position formula

    q_{n+1} = q_n + h q̇_n + h² (½ − β) ã_n + h² β ã_{n+1}

leaves, from exact values at t_n, the local error (numerical minus exact)

    e = h³ q⃛ (β + Δ/2 − 1/6) = h³ q⃛ (β − γ/2 + 1/12)   (`local_error_constant`),

1/12 for ρ∞ = 1 (the trapezoidal rule's), 0.0840 for ρ∞ = 0.9.  With q⃛ ≈ (ã_{n+1} − ã_n)/h

    e ≈ (β − γ/2 + 1/12) h² (ã_{n+1} − ã_n),

the step's result minus the second-order-consistent predictor of Zienkiewicz & Xie's
estimator for Newmark (β − 1/6 there: their a is ã for α_m = α_f = 0), generalized as in
Géradin & Cardona's book.  It costs one pass over ã per step and falls as h³ on a smooth
motion (tests/test_dynamics_error_control.py checks the order and the constant).

**The norm.**  Lengths relative to the model size, angles in rad (the coordinates'
weights of the Newton tolerance): ``error = max_i w_i |e_i| / rtol``, so `rtol` is the
local error of one step as a fraction of the model's size (and in rad for angles): an
absolute tolerance scaled by the model, the same for every body wherever it is drawn
(absolute coordinates make a tolerance relative to |q_i| depend on where the origin is).

**The controller** (Hairer, Nørsett & Wanner, II.4): a step is accepted when
``error <= 1``; the next one is h · min(`GROWTH_LIMIT`, max(`SHRINK_LIMIT`, `SAFETY` ·
error^(−1/3))), never above the largest step.  A rejected step is taken again from the
same state with the shorter step, not shorter than `StepSizeController.shortest` (1/16
of the longest step accepted lately: at a singular crossing the estimate is noise that no
step size brings down).  Output times are met exactly: the last step before a
sample ends on it, and when the sample is less than two steps away the distance is split
in two equal steps (no sliver step, which the index-3 form's 1/h² scaling dislikes).

**The compiled loop** (`sparsekin.solve._compiled_dynamics`, small and chain-like models) runs the same
controller from `sparsekin.solve._error_control_kernels`, with these constants: a change
here is a change there (tests/test_compiled_dynamics.py compares the two steppers' steps).
"""

from __future__ import annotations


import math

import numpy as np

from ..engine import _dynamics_kernels
from ..errors import ConvergenceError
from ..model.mechanism import Analysis

__all__ = ["RTOL_RANGE", "SAFETY", "GROWTH_LIMIT", "SHRINK_LIMIT", "StepSizeController", "StepFailed",
           "ErrorTooLarge", "advance_controlled", "local_error_constant", "step_to",
           "step_velocity_bound", "ACCELERATION_TOLERANCE", "step_acceleration_bound"]

#: Smallest and largest accepted `rtol` (`sparsekin.model.mechanism.Analysis.rtol_range`).
RTOL_RANGE = Analysis.rtol_range
#: The next step is this fraction of the one the estimate says would leave exactly `rtol`.
SAFETY = 0.9
#: A step grows at most this factor over the last one (generalized-α's ã is a shifted
#: acceleration: a sudden change of h changes that shift), and shrinks at most to
#: `SHRINK_LIMIT` of it after a rejection.
GROWTH_LIMIT = 2.0
SHRINK_LIMIT = 0.2
#: The estimate shortens a step to no less than this fraction of the longest step accepted
#: lately, which fades by `MEMORY` per accepted step (a step may fall 16× at once, and then
#: by half in 35 steps): a step already that short is accepted above the tolerance.
SHORTEST_FRACTION = 1.0 / 16.0
MEMORY = 0.98
#: The order of the local error estimate (h³).
ORDER = 3


def local_error_constant(gamma: float, beta: float) -> float:
    """C of the local position error C h³ q⃛ of a generalized-α step: β − γ/2 + 1/12
    (module docstring).

    >>> round(local_error_constant(0.5, 0.25), 6)  # the trapezoidal rule's 1/12
    0.083333
    """
    return beta - 0.5 * gamma + 1.0 / 12.0


class StepFailed(Exception):
    """A step's Newton or projection failed (`sparsekin.solve.dynamics`): it is halved."""


class ErrorTooLarge(Exception):
    """The step's estimated local error exceeds the tolerance (`StepSizeController.check`)."""


class StepSizeController:
    """The step sizes of an error-controlled run.

    Parameters
    ----------
    rtol : float
        Local error of one step relative to the model size (angles: rad).
    gamma, beta : float
        Generalized-α's parameters.
    weights : ndarray, shape (n_coordinates,)
        1 / model size for x and y, 1 for angles.
    max_step : float
        The user's largest step, s: never exceeded.

    Attributes
    ----------
    error : float
        The last estimate (relative to `rtol`; ≤ 1 on an accepted step).
    n_rejected : int
        Steps taken again shorter because their estimate exceeded `rtol`.
    n_uncontrolled : int
        Steps accepted above `rtol` because they were at `shortest` already.  Where Φq
        loses rank for an instant (the N-four-bar's flat crossings), Newton's error along
        its vanishing singular values makes the estimate noise that no step size brings
        down: followed, it shrank the steps of A02 (N = 40) to 1e-6 s at a crossing, where
        steps that short land at the singular instant and each lose energy (a lasting
        −2.3e-3 J there, 1e-4 of the initial kinetic energy).
    """

    def __init__(self, rtol: float, gamma: float, beta: float, weights: np.ndarray, max_step: float) -> None:
        self.rtol = rtol
        self.constant = abs(local_error_constant(gamma, beta))
        self.weights = weights
        self.max_step = max_step
        self.error, self.hold = 0.0, False
        self.n_rejected = self.n_uncontrolled = 0
        self._retry, self._longest = False, 0.0
        self._change = np.empty(weights.size)

    def estimate(self, pseudo_new: np.ndarray, pseudo_old: np.ndarray, h: float, newton_error: float = 0.0) -> float:
        """The local error of a step of `h` s from the pseudo-accelerations before and
        after it, weighted, relative to `rtol` plus `newton_error` (1 = at the tolerance).

        The estimate also sees the error Newton's stop left: an error δq in q is one of
        δq / (β h²) in ã, (C / β) δq in the estimate.  Newton goes to the rounding of q
        (1e-15 of the model size), except where Φq loses rank for an instant (a flat
        crossing of the N-four-bar), where its corrections stall higher (~1e-11); there the
        stepper passes its last correction as `newton_error` (weighted like the tolerance),
        at most a fresh matrix's stall level (`sparsekin.solve.dynamics.STALL`: a larger
        correction accepted on a held matrix is an error the estimate should reject)."""
        change = np.subtract(pseudo_new, pseudo_old, out=self._change)
        return self.constant * h * h * _dynamics_kernels.weighted_norm(change, self.weights) / (self.rtol + newton_error)

    def check(self, pseudo_new: np.ndarray, pseudo_old: np.ndarray, h: float, newton_error: float = 0.0) -> None:
        """Record the step's estimate (`estimate`, in `error`); `ErrorTooLarge` if above the
        tolerance (a non-finite estimate is too large), unless the step is no longer than
        `shortest`: that one is accepted (`n_uncontrolled`).  The step after a rejection,
        or after a step whose tolerance Newton's stall widened, does not grow (`hold`)."""
        error = self.estimate(pseudo_new, pseudo_old, h, newton_error)
        self.error = error
        # no growth right after a rejection (Hairer & Wanner), nor after a step whose tolerance
        # Newton's stall widened (its estimate says little of the next step's error)
        self.hold = self._retry or newton_error > self.rtol
        too_large = not error <= 1.0  # NaN included
        if too_large and h > self.shortest * (1.0 + 1e-9):
            self.n_rejected += 1
            self._retry = True
            raise ErrorTooLarge(f"local error {error:.3g} × rtol")
        self.n_uncontrolled += too_large
        self._retry = False
        self._longest = max(h, self._longest * MEMORY)

    @property
    def shortest(self) -> float:
        """The shortest step the estimate may ask for: `SHORTEST_FRACTION` of the longest
        step accepted lately (0 before the first)."""
        return SHORTEST_FRACTION * self._longest

    def factor(self) -> float:
        """How much longer (or shorter) than the last step the next one may be."""
        if self.error <= 0.0:
            return GROWTH_LIMIT
        if not self.error < math.inf:  # a non-finite estimate: the shortest allowed
            return SHRINK_LIMIT
        return min(GROWTH_LIMIT, max(SHRINK_LIMIT, SAFETY * self.error ** (-1.0 / ORDER)))

    def next_step(self, h: float, proposed: float, grow: bool = True) -> float:
        """The step after one of `h` s was taken (accepted or rejected: `error` says),
        `proposed` the step the controller had asked for (`h` shorter when it ended on an
        output time): a short last step before a sample that was well within the
        tolerance keeps the proposal; `grow` False holds the step (after a Newton failure,
        whose halvings may go below `shortest`: the estimate does not lift it back)."""
        factor = self.factor()
        if not grow or self.hold:
            factor = min(factor, 1.0)
        if h < proposed and factor >= 1.0:
            return proposed
        return min(self.max_step, max(h * factor, self.shortest) if grow else h * factor)


def step_to(remaining: float, proposed: float) -> float:
    """The step to take toward an output time `remaining` s away with `proposed` the
    controller's step: all of it within the proposal (1e-9 relative), half of it within
    two proposals (no sliver step just before the sample), else the proposal."""
    if remaining <= proposed * (1.0 + 1e-9):
        return remaining
    if remaining < 2.0 * proposed:
        return 0.5 * remaining
    return proposed


def advance_controlled(stepper, t: float, max_halvings: int, growth_after: int) -> float:
    """Integrate `stepper` (a `GeneralizedAlphaStepper` with a ``controller``) to time `t`
    in error-controlled steps; returns the step proposed for the next interval.

    A step whose estimate exceeds ``rtol`` (`ErrorTooLarge`) is taken again from the same
    state with the controller's shorter step, on a fresh factorization; a step whose Newton
    or projection fails (`StepFailed`) is halved as in fixed-step runs, and the step is then
    held (not grown) for `growth_after` steps, after which the large path's
    regularization is lifted (`RoundingFloor.recovered`).

    Raises
    ------
    ConvergenceError
        The step fell below the largest step over 2^`max_halvings`; the stepper's state
        is the last good one.
    """
    controller = stepper.controller
    proposed, held = stepper.state.step, 0
    shortest = stepper.max_step * 0.5**max_halvings
    while stepper.state.time < t:
        now = stepper.state.time
        h = step_to(t - now, proposed)
        try:
            stepper._state = stepper._step(stepper.state, h, t if h == t - now else now + h)
        except ErrorTooLarge as rejection:
            proposed, failure = controller.next_step(h, h), str(rejection)  # (not the exception: its
            # traceback held the attempt's arrays through the substeps after it)
            stepper._factored = False
        except StepFailed as newton:
            proposed, held, failure = 0.5 * h, growth_after, str(newton)
            stepper.n_subdivisions += 1
            stepper._factored = False
            stepper._floor.failed()
        else:
            proposed = controller.next_step(h, proposed, grow=held == 0)
            if held:
                held -= 1
                if not held:
                    stepper._floor.recovered()
            continue
        if proposed < shortest:
            raise ConvergenceError(f"the step from t = {now:.9g} s fell below {shortest:.3g} s ({failure})",
                                   time=now + h, driver_values={}) from None  # fmt: skip
    return proposed


def step_velocity_bound(tolerance: float, h: float) -> float:
    """The velocity error a step of `h` s may leave (Newton, projection): ``tolerance · h``,
    so that the errors of one second add up to at most `tolerance` whatever the step."""
    return tolerance * h


#: The acceleration projection opens where the drift exceeds this tolerance, however loose
#: `tolerance` (the default's): it damps the (−1)ⁿ oscillation of q̈ and λ that
#: generalized-α leaves undamped (ρ∞ near 1) and that 1/σ amplifies at a flat crossing
#: (docs/dynamics-theory.md, "Singular configurations"), so when it acts is stability's
#: choice, not accuracy's.  Opened at a looser tolerance it fell silent, λ's second difference
#: was 3x λ 14 ms before the crossing (the default's 0.03x), and the 10^4-body chain at 1e-6
#: in 0.5 ms steps stopped there.  A drift within the tolerance's bound takes one pass (from zero, no
#: refinement): enough to damp the oscillation, 0.76 of the default's CPU at 10^4 and 1e-6.
ACCELERATION_TOLERANCE = 1e-10


def step_acceleration_bound(tolerance: float) -> float:
    """The acceleration drift (per unit of max(1, ‖q̈‖), weighted) above which the
    acceleration projection acts: `tolerance`, but no more than `ACCELERATION_TOLERANCE`."""
    return min(tolerance, ACCELERATION_TOLERANCE)
