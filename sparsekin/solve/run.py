"""The run driver: a block stepper over the sample times, for every analysis.

`run` asks the stepper (`sparsekin.solve.steppers.BlockStepper`) for the samples from the
first not yet solved, at most `chunk` at a time, hands each block to `record` (which turns
it into what the run keeps and stores it), reports the progress, and counts the Newton
corrections of each sample.  It owns what every analysis needs around its loop:

* on any error the samples recorded before it are kept: ``finish()`` builds the result
  of what was recorded, which a `SparsekinError` carries as ``error.result``;
* a Ctrl-C (`KeyboardInterrupt`) becomes `AnalysisInterrupted` with that result;
* non-finite values are checked by the steppers, so numpy's floating-point warnings are
  off while they run.

It knows nothing of numba, chunks of a store, forces or what the analysis is.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import AnalysisInterrupted, SparsekinError
from .steppers import BlockStepper, SampleBlock

__all__ = ["Run", "run"]


class Run:
    """The state of one run: samples done and their Newton corrections.

    Parameters
    ----------
    stepper : BlockStepper
    times : ndarray, shape (n_times,)
        Checked sample times, s.
    record : callable
        ``record(block)`` for each `SampleBlock` solved.
    progress : callable, optional
        ``progress(samples_done, n_times)`` after each block.
    chunk : int
        Most samples asked of the stepper at a time.
    """

    def __init__(self, stepper: BlockStepper, times: np.ndarray, record: Callable[[SampleBlock], None],
                 progress: Callable | None = None, chunk: int = 1) -> None:  # fmt: skip
        self.stepper, self.times, self.record, self.progress = stepper, times, record, progress
        self.chunk = max(1, int(chunk))
        self.done = 0
        self.iterations = np.zeros(times.size, dtype=np.int64)

    def solve(self) -> None:
        """Every sample, block after block."""
        times = self.times
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # non-finite values are checked
            while self.done < times.size:
                block = self.stepper.advance_block(times[self.done : self.done + self.chunk])
                self.iterations[self.done : self.done + block.size] = block.iterations
                self.record(block)
                self.done += block.size
                if self.progress is not None:
                    self.progress(self.done, times.size)


def run(stepper: BlockStepper, times: np.ndarray, record: Callable[[SampleBlock], None], finish: Callable[[Run], object],
        *, progress: Callable | None = None, chunk: int = 1):  # fmt: skip
    """Solve every sample of `times` with `stepper`; returns ``finish(run)``, the result.

    ``finish(run)`` builds the result from what `record` kept (``run.done`` samples,
    ``run.iterations``); it is called once, also after an error, whose ``result`` it
    becomes (see the module docstring).  The result has ``n_times`` (a `Motion` has), which
    the message of `AnalysisInterrupted` names.
    """
    state = Run(stepper, times, record, progress, chunk)
    try:
        state.solve()
    except BaseException as error:
        result = _result_after(error, finish, state)
        if isinstance(error, KeyboardInterrupt) and result is not None:
            raise AnalysisInterrupted(result) from None
        if isinstance(error, SparsekinError):
            error.result = result
        raise
    return finish(state)


def _result_after(error: BaseException, finish, state: Run):
    """The result of the samples recorded before `error`, or None (with a note on `error`)
    if they cannot be kept: the error that stopped the run is the one raised."""
    try:
        return finish(state)
    except Exception as failure:  # best effort: `error` is the one raised
        error.add_note(f"the samples solved before this error could not be kept: {failure!r}")
        return None
