"""The first run after an install compiles the numerical kernels: it says so, once.

numba compiles the kernels on their first call and keeps them in its cache (``cache=True``,
`sparsekin._jit`); every later run loads them.  That first compilation takes about 15 s
(``benchmarks/measure_startup.py``, cold; docs/design-notes.md, "Start-up"): a silent wait
that looks like a hang.  ``sparsekin run`` calls `announce_compilation` before it solves.
"""

from __future__ import annotations

import sys
from typing import TextIO

__all__ = ["COMPILING_NOTE", "kernels_cached", "announce_compilation"]

#: The line of the first run.  The figure: a cold ``sparsekin run examples/task5.toml``
#: took 8.4–12 s of wall time on this project's machines when they were quiet, 17.8 s with
#: ``--plot`` in a fresh venv (issue 21); docs/design-notes.md, "Issue 21".
COMPILING_NOTE = "note: compiling numerical kernels, once, about 15 s (later runs load them from numba's cache)"


def kernels_cached() -> bool:
    """Whether numba's cache holds the compiled time loop for the installed source.

    False on the first run after an install (or after the source changed, or with
    ``NUMBA_CACHE_DIR`` pointing at an empty folder).  The index is read through numba's
    private cache objects; if they change shape, this says True (nothing is announced)
    rather than fail.
    """
    from ..solve._compiled import _run_time_loop

    try:
        return bool(_run_time_loop._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba's private layout: never stop a run for a note
        return True


def announce_compilation(quiet: bool, stream: TextIO | None = None) -> bool:
    """Print `COMPILING_NOTE` on `stream` (default stderr) if the kernels are not cached;
    not with `quiet`, nor when `stream` is not a terminal (as the progress bar).  Returns
    whether it printed."""
    stream = sys.stderr if stream is None else stream
    if quiet or not stream.isatty() or kernels_cached():
        return False
    print(f"sparsekin: {COMPILING_NOTE}", file=stream, flush=True)
    return True
