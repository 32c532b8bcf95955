"""Warnings outside a run (a model file's `UnjoinedPointWarning` at load) as one line each.

Inside a run the command line records warnings itself; `one_line_warnings` covers the
rest of a command, so that no warning prints Python's two-line form with a source line.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["one_line_warnings"]


@contextmanager
def one_line_warnings(program: str = "sparsekin") -> Iterator[None]:
    """Within the block, print each warning as ``<program>: warning: <message>`` on stderr."""
    previous = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        text = " ".join(str(message).splitlines())
        print(f"{program}: warning: {text}", file=sys.stderr if file is None else file)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = previous
