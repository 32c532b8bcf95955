"""The branch guard: does a solved kinematic step look like a jump to another assembly branch?

Over a step h of a smooth motion ``q1 - q0 = h/2 (qd0 + qd1) - h²/12 (qdd1 - qdd0) +
O(h^5)`` (the corrected trapezoidal rule); a step that jumped breaks it by a finite amount,
after Newton travelled a finite distance from its predictor (the thresholds and their
reasons: `BRANCH_DEFECT_RATIO`).  Both the Python stepper and the
compiled loop judge their steps with `jumped`.

>>> import numpy as np
>>> h, t = 0.1, np.array([0.0, 0.1])
>>> before = (np.sin(t[:1]), np.cos(t[:1]), -np.sin(t[:1]))
>>> after = (np.sin(t[1:]), np.cos(t[1:]), -np.sin(t[1:]))
>>> branch_jump(h, before, after, after[0] - 0.01, np.ones(1))
False
>>> branch_jump(h, before, (after[0], -after[1], after[2]), after[0] - 0.01, np.ones(1))
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .._jit import JIT

__all__ = ["BranchGuard", "BRANCH_DEFECT_RATIO", "BRANCH_MIN_DEFECT", "BRANCH_MIN_CORRECTION", "branch_jump", "jumped",
           "guard_values"]

#: Branch guard.  Over a step h from sample 0 to sample 1 of a smooth motion,
#: ``q1 - q0 = h/2 (qd0 + qd1) - h²/12 (qdd1 - qdd0) + O(h^5)`` (the corrected trapezoidal
#: rule).  A solution that jumped to another assembly branch breaks this by a finite
#: amount, and Newton travelled a finite distance from the predictor to reach it.  The
#: step is halved when both happen: the defect of that rule exceeds `BRANCH_DEFECT_RATIO`
#: times the displacement (and `BRANCH_MIN_DEFECT`), and Newton's total correction exceeds
#: `BRANCH_MIN_CORRECTION` — distances are the largest coordinate, angles in rad and
#: lengths relative to the model size.  For a harmonic motion of angular frequency w the
#: defect ratio is about (h w)^4 / 720: a step must cover more than 1.5 rad of phase to
#: be halved without cause.  Near a dead centre, where the motion stops being smooth on
#: the scale of the step, Newton from the predictor moves little (Task 5 at 1 ms: 1.5e-3
#: rad at the last sample before it), whereas a jump moves by the distance between the
#: branches (0.13 rad for the four-bar of tests/test_branch_following.py).
BRANCH_DEFECT_RATIO = 0.01
BRANCH_MIN_DEFECT = 1e-8
BRANCH_MIN_CORRECTION = 5e-3


@dataclass(frozen=True)
class BranchGuard:
    """The branch guard's thresholds (see `BRANCH_DEFECT_RATIO`); a ratio of ``inf`` switches it off."""

    defect_ratio: float = BRANCH_DEFECT_RATIO
    min_defect: float = BRANCH_MIN_DEFECT
    min_correction: float = BRANCH_MIN_CORRECTION


def branch_jump(step: float, before, after, predicted: np.ndarray, weights: np.ndarray,
                guard: BranchGuard = BranchGuard()) -> bool:  # fmt: skip
    """Whether the step of length `step` (s) from the state `before` to `after` (each
    ``(q, qd, qdd)``), Newton having started from `predicted`, looks like a jump; lengths
    weighted by `weights` (`ConstraintPattern.coordinate_weights`)."""
    return bool(jumped(step, *before, *after, predicted, weights, guard_values(guard)))


def guard_values(guard: BranchGuard) -> tuple[float, float, float]:
    """The guard's thresholds as the kernels take them."""
    return float(guard.defect_ratio), float(guard.min_defect), float(guard.min_correction)


@njit(**JIT)
def jumped(h, q0, qd0, qdd0, q1, qd1, qdd1, predicted, weights, guard):
    """Whether a solved step looks like a jump to another assembly branch.

    The defect ``q1 - q0 - h/2 (qd0 + qd1) + h²/12 (qdd1 - qdd0)``, the displacement
    ``q1 - q0`` and Newton's correction ``q1 - predicted`` are each measured by their
    largest weighted coordinate; `guard` is ``(defect ratio, least defect, least
    correction)``.  A NaN anywhere counts as a jump.
    """
    ratio, min_defect, min_correction = guard
    defect = 0.0
    displacement = 0.0
    correction = 0.0
    for i in range(q0.size):
        move = q1[i] - q0[i]
        d = abs(move - 0.5 * h * (qd0[i] + qd1[i]) + (h * h / 12.0) * (qdd1[i] - qdd0[i])) * weights[i]
        m = abs(move) * weights[i]
        c = abs(q1[i] - predicted[i]) * weights[i]
        if not d <= defect:  # also true for a NaN
            defect = d
        displacement = max(displacement, m)
        correction = max(correction, c)
    return defect > min_defect and defect > ratio * displacement and correction > min_correction
