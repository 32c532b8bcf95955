"""What every command shares: the program's name, exit statuses, usage errors, one-line
reports, optional dependencies and the progress bar."""

from __future__ import annotations

import sys

PROGRAM = "sparsekin"
EXIT_SUCCESS = 0
EXIT_PROBLEM = 1
EXIT_USAGE = 2
EXIT_STOPPED = 3
EXIT_INTERRUPTED = 130
#: A progress bar appears once a run has lasted this long, s.
PROGRESS_DELAY = 2.0


class CommandError(Exception):
    """A mistake in the command-line arguments: reported as one line, exit status 2."""


def report(message: str) -> None:
    """Print ``sparsekin: <message>`` to stderr as one line."""
    print(f"{PROGRAM}: {' '.join(message.splitlines())}", file=sys.stderr)


def require_zarr() -> None:
    try:
        import xarray  # noqa: F401
        import zarr  # noqa: F401
    except ImportError:
        raise CommandError('--format zarr needs zarr and xarray: pip install "sparsekin[zarr]"') from None


def require_matplotlib() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise CommandError('--plot needs matplotlib: pip install "sparsekin[plot]"') from None


class ProgressBar:
    """A progress callable ``(done, total)`` moving a tqdm bar on stderr, shown once the work
    has lasted `PROGRESS_DELAY`; no bar with `quiet`, nor when stderr is not a terminal.

    Parameters
    ----------
    total : int
        The count the bar goes up to.
    unit : str
        What is counted (``"sample"``, ``"variant"``).
    quiet : bool
        No bar.
    """

    def __init__(self, total: int, unit: str, quiet: bool) -> None:
        self._bar = None
        if quiet or not sys.stderr.isatty():
            return
        from tqdm import tqdm  # here: importing it costs a start-up that does not draw a bar

        self._bar = tqdm(total=total, unit=unit, delay=PROGRESS_DELAY, file=sys.stderr, dynamic_ncols=True,
                         leave=False)  # fmt: skip

    def __enter__(self):
        return self

    def __call__(self, done: int, total: int) -> None:
        if self._bar is not None:
            self._bar.update(done - self._bar.n)

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.close()
