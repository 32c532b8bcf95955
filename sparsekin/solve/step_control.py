"""Step control between two output times, for every stepper: halve on rejection, grow back.

A stepper that cannot take the step from its current sample to the next output time in
one go hands `march` a function that attempts one step; `march` covers the interval in
steps halved after each rejected attempt and doubled again (up to the whole interval)
after each accepted one.  The attempt raises `StepRejected` to be halved.  Below
`StepControl.guarded_halvings` halvings the attempt is told to skip its own acceptance
test (the branch guard of a kinematic step: a step that short that still looks like a
jump is accepted); below `StepControl.failure_halvings` a rejection is final
(`StepAbandoned`), and the stepper explains it.

>>> steps = []
>>> def attempt(t0, t1, guarded):
...     if t1 - t0 > 0.3:
...         raise StepRejected("too long")
...     steps.append((t0, t1))
...     return 1
>>> march(0.0, 1.0, attempt)  # each step grown back to 0.5 is rejected and halved again
MarchOutcome(corrections=4, halvings=4)
>>> [round(t1, 2) for _, t1 in steps]
[0.25, 0.5, 0.75, 1.0]
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

__all__ = ["StepControl", "StepRejected", "StepAbandoned", "MarchOutcome", "march", "BRANCH_MAX_HALVINGS",
           "FAILURE_MAX_HALVINGS"]

#: How many times a step is halved at most: for a suspect branch (then the result is
#: accepted) and for a failure of Newton (then the analysis stops).
BRANCH_MAX_HALVINGS = 8
FAILURE_MAX_HALVINGS = 20


@dataclass(frozen=True)
class StepControl:
    """How often a step may be halved: its acceptance test is skipped below
    `guarded_halvings`; a rejection below `failure_halvings` ends the run."""

    guarded_halvings: int = BRANCH_MAX_HALVINGS
    failure_halvings: int = FAILURE_MAX_HALVINGS


class StepRejected(Exception):
    """An attempted step failed (Newton did not converge, a singular matrix, a suspect step)."""

    @property
    def reason(self) -> str:
        return str(self.args[0]) if self.args else "the step was rejected"


class StepAbandoned(Exception):
    """A step from `t_from` to `t_to` was rejected on the shortest step allowed.

    Attributes
    ----------
    t_from, t_to : float
        The last time reached, and the time of the step that failed there.
    reason : str
        Why the last attempt failed.
    halvings : int
        How many times a step was halved before.
    """

    def __init__(self, t_from: float, t_to: float, reason: str, halvings: int) -> None:
        super().__init__(t_from, t_to, reason, halvings)
        self.t_from, self.t_to, self.reason, self.halvings = t_from, t_to, reason, halvings


class MarchOutcome(NamedTuple):
    """The Newton corrections over all accepted steps, and how many times a step was halved."""

    corrections: int
    halvings: int


def march(start: float, end: float, attempt: Callable[[float, float, bool], int],
          control: StepControl = StepControl()) -> MarchOutcome:  # fmt: skip
    """Cover `start` … `end` in steps, from half the interval on.

    ``attempt(t_from, t_to, guarded)`` takes one step from the state at `t_from` (the last
    accepted) to `t_to` and returns its Newton corrections, or raises `StepRejected`;
    `guarded` is False for steps shorter than the interval over 2^`guarded_halvings`.

    Raises
    ------
    StepAbandoned
        A step no longer than the interval over 2^`failure_halvings` was rejected.
    """
    span = end - start
    t = start
    h = 0.5 * span
    halvings, corrections = 1, 0
    while True:
        last = end - t <= h * (1.0 + 1e-9)
        step = end - t if last else h
        t_next = end if last else t + h
        try:
            corrections += attempt(t, t_next, step > span / 2**control.guarded_halvings)
        except StepRejected as rejection:
            if step <= span / 2**control.failure_halvings:
                raise StepAbandoned(t, t_next, rejection.reason, halvings) from None
            h = 0.5 * step
            halvings += 1
            continue
        t = t_next
        if last:
            return MarchOutcome(corrections, halvings)
        h = min(2.0 * h, span)
