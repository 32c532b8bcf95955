"""The step-size controller of `sparsekin.solve.error_control` as numba kernels (the compiled dynamics loop).

`sparsekin.solve._compiled_dynamics` takes error-controlled steps (``rtol``) with these
kernels: the same estimate, acceptance test and next step as `StepSizeController`
(`check`, `factor`, `next_step`) and the same landing on output times (`step_to`), with
the controller's state in one array (`CONTROL_FIELDS`) and its constants in one tuple
(`control_rules`, read from `sparsekin.solve.error_control`, the one place they are set).
Nothing here allocates: the kernels run inside the loop compiled without reference counts.

The state array, shape (``len(CONTROL_FIELDS)``,): the last estimate (relative to rtol),
whether the next step is held (0/1), whether the last step was rejected (0/1), the longest
step accepted lately, and the counts of rejected and uncontrolled steps.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT
from ..engine._dynamics_kernels import weighted_norm
from . import error_control

__all__ = ["CONTROL_FIELDS", "control_rules", "control_state", "restore_controller", "accept_step", "next_step",
           "step_to"]

#: The fields of the controller's state array (`StepSizeController`'s attributes).
CONTROL_FIELDS = ("error", "hold", "retry", "longest", "n_rejected", "n_uncontrolled")
_ERROR, _HOLD, _RETRY, _LONGEST, _REJECTED, _UNCONTROLLED = range(len(CONTROL_FIELDS))
#: Positions in `control_rules`.
_RTOL, _CONSTANT, _MAX_STEP, _SAFETY, _GROWTH, _SHRINK, _SHORTEST_FRACTION, _MEMORY, _ORDER = range(9)


def control_rules(controller) -> tuple:
    """``(rtol, |C|, max_step, SAFETY, GROWTH_LIMIT, SHRINK_LIMIT, SHORTEST_FRACTION, MEMORY,
    ORDER)`` of a `StepSizeController`, or all zeros for a run of fixed steps (None): an
    rtol of 0 tells the compiled loop to take fixed steps."""
    if controller is None:
        return (0.0,) * 9
    rules = error_control
    return (float(controller.rtol), float(controller.constant), float(controller.max_step), rules.SAFETY,
            rules.GROWTH_LIMIT, rules.SHRINK_LIMIT, rules.SHORTEST_FRACTION, rules.MEMORY, float(rules.ORDER))  # fmt: skip


def control_state(controller) -> np.ndarray:
    """The state array of `controller` (a `StepSizeController`; zeros for None)."""
    values = np.zeros(len(CONTROL_FIELDS))
    if controller is not None:
        values[:] = (controller.error, controller.hold, controller._retry, controller._longest, controller.n_rejected,
                     controller.n_uncontrolled)  # fmt: skip
    return values


def restore_controller(controller, values: np.ndarray) -> None:
    """`controller` (a `StepSizeController`, or None) set to the state array `values`."""
    if controller is None:
        return
    controller.error, controller.hold, controller._retry = float(values[_ERROR]), bool(values[_HOLD]), bool(values[_RETRY])
    controller._longest = float(values[_LONGEST])
    controller.n_rejected, controller.n_uncontrolled = int(values[_REJECTED]), int(values[_UNCONTROLLED])


@njit(inline="always", **JIT)
def _shortest(values, rules):
    """`StepSizeController.shortest`."""
    return rules[_SHORTEST_FRACTION] * values[_LONGEST]


@njit(**JIT)
def accept_step(values, rules, pseudo_new, pseudo_old, weights, h, newton_error, change):
    """`StepSizeController.check` on the step of `h` s from ã `pseudo_old` to `pseudo_new`:
    records the estimate; False (a rejection, counted) if it is above rtol and the step
    longer than the shortest allowed, else True.  `change` is scratch of ã's size."""
    for c in range(change.size):
        change[c] = pseudo_new[c] - pseudo_old[c]
    error = rules[_CONSTANT] * h * h * weighted_norm(change, weights) / (rules[_RTOL] + newton_error)
    values[_ERROR] = error
    values[_HOLD] = 1.0 if (values[_RETRY] != 0.0 or newton_error > rules[_RTOL]) else 0.0
    too_large = not error <= 1.0  # NaN included
    if too_large and h > _shortest(values, rules) * (1.0 + 1e-9):
        values[_REJECTED] += 1.0
        values[_RETRY] = 1.0
        return False
    if too_large:
        values[_UNCONTROLLED] += 1.0
    values[_RETRY] = 0.0
    values[_LONGEST] = max(h, values[_LONGEST] * rules[_MEMORY])
    return True


@njit(inline="always", **JIT)
def _factor(values, rules):
    """`StepSizeController.factor`."""
    error = values[_ERROR]
    if error <= 0.0:
        return rules[_GROWTH]
    if not error < math.inf:  # a non-finite estimate: the shortest allowed
        return rules[_SHRINK]
    return min(rules[_GROWTH], max(rules[_SHRINK], rules[_SAFETY] * error ** (-1.0 / rules[_ORDER])))


@njit(**JIT)
def next_step(values, rules, h, proposed, grow):
    """`StepSizeController.next_step`: the step after one of `h` s (accepted or rejected),
    `proposed` the step asked for before it; `grow` False holds it."""
    factor = _factor(values, rules)
    if not grow or values[_HOLD] != 0.0:
        factor = min(factor, 1.0)
    if h < proposed and factor >= 1.0:
        return proposed
    if grow:
        return min(rules[_MAX_STEP], max(h * factor, _shortest(values, rules)))
    return min(rules[_MAX_STEP], h * factor)


@njit(inline="always", **JIT)
def step_to(remaining, proposed):
    """`sparsekin.solve.error_control.step_to`: the step toward an output time `remaining` s away."""
    if remaining <= proposed * (1.0 + 1e-9):
        return remaining
    if remaining < 2.0 * proposed:
        return 0.5 * remaining
    return proposed
