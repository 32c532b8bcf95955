"""Signals that stop a command: Ctrl-C (SIGINT), SIGTERM and SIGHUP, all alike.

The first of them stops the run as Ctrl-C always has (a `KeyboardInterrupt` in the main
thread: the analysis keeps every sample solved and the command writes them); any later
one is noted and ignored, so that a second Ctrl-C never aborts the writing of what the
first one kept.  While the command writes its files (`holding`), even the first one is
only noted: the files are finished, then the command exits.  The exit status is 128 plus
the signal's number: 130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP (`exit_status`).
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

#: The signals that stop a run (SIGHUP where the platform has it).
STOPPING_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
#: How the messages name them.
SIGNAL_NAMES = {signal.SIGINT: "Ctrl-C"}


class StopSignal(KeyboardInterrupt):
    """What the first stopping signal raises: a `KeyboardInterrupt` (the analysis keeps
    its samples as on Ctrl-C), of its own class because the interpreter ends a process
    in which a plain `KeyboardInterrupt` once left code run by ``PyRun_String`` (some
    compiled modules' imports) by SIGINT, whatever the exit status asked."""


class _State:
    received: int | None = None  # the first stopping signal received
    holding = 0  # writing: no signal raises


_state = _State()


#: Where Python code runs as a callback from compiled code (numba's compiler writing its
#: cache through llvmlite): an exception raised there is printed as "Exception ignored"
#: and dropped by the caller, so a signal arriving there is delivered again a moment later.
FOREIGN_CALLBACKS = (f"{os.sep}llvmlite{os.sep}",)
#: How long to wait before delivering such a signal again, s.
REDELIVERY_DELAY = 0.05


def _on_signal(signum: int, frame) -> None:
    if _state.received is not None:
        return  # a second signal: the first one is being dealt with
    if not _state.holding and _in_foreign_callback(frame):
        timer = threading.Timer(REDELIVERY_DELAY, os.kill, (os.getpid(), signum))
        timer.daemon = True
        timer.start()
        return
    _state.received = signum
    if not _state.holding:
        raise StopSignal


def _in_foreign_callback(frame) -> bool:
    """Whether `frame` or one of its callers runs in a `FOREIGN_CALLBACKS` module."""
    while frame is not None:
        if any(part in frame.f_code.co_filename for part in FOREIGN_CALLBACKS):
            return True
        frame = frame.f_back
    return False


@contextmanager
def stop_on_signals(then_ignore: bool = False) -> Iterator[None]:
    """Handle the `STOPPING_SIGNALS` as the module docstring says while the block runs (in
    the main thread only: elsewhere the block runs as it is).  After it, the handlers
    there were are restored; with `then_ignore` (the process ends with the command), the
    signals are ignored instead: the interpreter, while it shuts down, would otherwise
    end by a late second Ctrl-C (killed by SIGINT, whatever the exit status)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.getsignal(signum) for signum in STOPPING_SIGNALS}
    _state.received, _state.holding = None, 0
    for signum in STOPPING_SIGNALS:
        signal.signal(signum, _on_signal)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_IGN if then_ignore else handler)


@contextmanager
def holding() -> Iterator[None]:
    """While the block runs, a stopping signal is noted, not raised: the files being
    written are finished."""
    _state.holding += 1
    try:
        yield
    finally:
        _state.holding -= 1


def received() -> int | None:
    """The first stopping signal received, if any."""
    return _state.received


def interrupted() -> str:
    """``interrupted`` after Ctrl-C, ``interrupted by SIGTERM`` after another signal: how a
    message about a stopped run begins."""
    signum = _state.received
    return "interrupted" if signum in (None, signal.SIGINT) else f"interrupted by {signal_name(signum)}"


def signal_name(signum: int | None = None) -> str:
    """``Ctrl-C``, ``SIGTERM``, ``SIGHUP`` (of `received` by default)."""
    signum = _state.received if signum is None else signum
    if signum is None:
        return "Ctrl-C"
    return SIGNAL_NAMES.get(signum, signal.Signals(signum).name)


def exit_status(signum: int | None = None) -> int:
    """128 plus the signal's number (130 when no signal was noted: a Ctrl-C raised by other means)."""
    signum = _state.received if signum is None else signum
    return 128 + int(signal.SIGINT if signum is None else signum)
