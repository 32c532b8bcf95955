"""What the run driver drives: the stepper protocols, and the blocks of samples they hand over.

Two kinds of stepper solve an analysis's samples:

* a `Stepper` solves one sample at a time: ``start(t)`` the first, ``advance(t)`` each
  next, both returning the Newton corrections; after each it publishes the system at that
  sample, ``linearization()`` (`sparsekin.engine.linearization.Linearization`), and
  ``stats()`` gives its counts (`StepperStats`).  `KinematicStepper` is one; a dynamics
  integrator is another.
* a `BlockStepper` solves many samples in one call: ``advance_block(times)`` solves from
  ``times[0]`` on and returns the samples it solved as a `SampleBlock` (at least one
  unless it raises).  The compiled loop of a small model is one
  (`sparsekin.solve._compiled.CompiledKinematicLoop`); `SampleSteps` makes a block
  stepper of any `Stepper`, one sample per block, and `FallbackStepper` runs a block
  stepper that may stop early and goes on with a `Stepper` from its last sample.

The run driver (`sparsekin.solve.run`) knows only `BlockStepper`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, Protocol

import numpy as np

from ..engine.linearization import Linearization

__all__ = ["Stepper", "BlockStepper", "StepperStats", "SampleBlock", "SampleSteps", "FallbackStepper", "StillStepper"]


class StepperStats(NamedTuple):
    """A stepper's counts so far, the path it took and the equations it left out.

    Attributes
    ----------
    n_factorizations, n_solves, n_refactorizations : int
        Factorizations of the iteration matrix, linear solves, numeric refactorizations.
    n_subdivisions : int
        How many times a step was halved.
    path : str
        The linear-solver path (``"compiled"``, ``"refactor"``, …).
    redundant_equations : tuple of str
        Labels of the equations left out as redundant.
    """

    n_factorizations: int = 0
    n_solves: int = 0
    n_refactorizations: int = 0
    n_subdivisions: int = 0
    path: str = "none"
    redundant_equations: tuple = ()


class SampleBlock(NamedTuple):
    """Samples a stepper solved, one per row (views valid until its next call).

    Attributes
    ----------
    times : ndarray, shape (m,)
    coordinates, velocities, accelerations : ndarray, shape (m, n_coordinates)
    iterations : ndarray of int, shape (m,)
        Newton corrections per sample.
    recorded : dict
        Recorded variables (`sparsekin.results.schema` names) the stepper computed itself,
        one row per sample: the compiled loop's force columns, a dynamics run's energy
        and drift.
    linearization : Linearization or None
        The system at the block's sample, for a block of one sample from a `Stepper`.
    """

    times: np.ndarray
    coordinates: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    iterations: np.ndarray
    recorded: dict
    linearization: Linearization | None = None

    @property
    def size(self) -> int:
        return len(self.times)


class Stepper(Protocol):
    """Solves one sample at a time (see the module docstring)."""

    time: float | None

    def start(self, t: float) -> int: ...

    def advance(self, t: float) -> int: ...

    def linearization(self) -> Linearization: ...

    def stats(self) -> StepperStats: ...


class BlockStepper(Protocol):
    """Solves many samples per call (see the module docstring)."""

    def advance_block(self, times: np.ndarray) -> SampleBlock: ...

    def stats(self) -> StepperStats: ...


class SampleSteps:
    """A `Stepper` as a `BlockStepper`: ``advance_block`` solves ``times[0]`` only (`start`
    at the first call, `advance` after) and returns it as a block of one sample, with its
    linearization.

    Parameters
    ----------
    stepper : Stepper
    recorded : callable, optional
        ``recorded()`` after each sample: the variables the stepper computed itself for
        it (`SampleBlock.recorded`, one row each; a dynamics run's energy and drift).
    """

    def __init__(self, stepper: Stepper, recorded: Callable[[], dict] | None = None) -> None:
        self.stepper, self.recorded = stepper, recorded
        self._iterations = np.zeros(1, dtype=np.int64)

    def advance_block(self, times: np.ndarray) -> SampleBlock:
        stepper, t = self.stepper, times[0]
        self._iterations[0] = stepper.start(t) if stepper.time is None else stepper.advance(t)
        lin = stepper.linearization()
        recorded = {} if self.recorded is None else self.recorded()
        return SampleBlock(times[:1], lin.coordinates[None], lin.velocities[None], lin.accelerations[None],
                           self._iterations, recorded, lin)  # fmt: skip

    def stats(self) -> StepperStats:
        return self.stepper.stats()


class FallbackStepper:
    """A block stepper that may stop early (`primary`), then a `Stepper` (`fallback`) from
    the last sample it solved, one sample per block.

    `primary` has ``stopped`` (it solved less than asked: the sample after its last one
    needs `fallback`, which fails there again with the detailed error if it must) and
    ``handover()``: None if it solved nothing, else ``(t, q, qd, qdd)`` of its last
    sample and ``(t, q)`` of its first; `fallback` has ``start_from(t, q, qd, qdd, first)``.
    The path is the primary's, or ``"<primary>+<fallback>"`` once the fallback ran.
    """

    def __init__(self, primary, fallback) -> None:
        self.primary, self.fallback = primary, fallback
        self._steps: SampleSteps | None = None

    def advance_block(self, times: np.ndarray) -> SampleBlock:
        if self._steps is None:
            block = self.primary.advance_block(times)
            if not self.primary.stopped:
                return block
            handover = self.primary.handover()
            if handover is not None:
                last, first = handover
                self.fallback.start_from(*last, first=first)
            self._steps = SampleSteps(self.fallback)
            if block.size:
                return block
        return self._steps.advance_block(times)

    def stats(self) -> StepperStats:
        first = self.primary.stats()
        if self._steps is None:
            return first
        then = self.fallback.stats()
        return StepperStats(
            first.n_factorizations + then.n_factorizations, first.n_solves + then.n_solves,
            first.n_refactorizations + then.n_refactorizations, first.n_subdivisions + then.n_subdivisions,
            f"{first.path}+{then.path}", then.redundant_equations,
        )  # fmt: skip


class StillStepper:
    """A model with nothing to solve (no coordinate, no equation): every sample is the
    empty configuration."""

    def advance_block(self, times: np.ndarray) -> SampleBlock:
        empty = np.zeros((len(times), 0))
        return SampleBlock(times, empty, empty, empty, np.zeros(len(times), dtype=np.int64), {})

    def stats(self) -> StepperStats:
        return StepperStats()
