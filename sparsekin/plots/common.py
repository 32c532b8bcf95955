"""What every figure shares: a figure on the Agg canvas, its PNG file, its file name, and
the optional dependencies named in one line."""

from __future__ import annotations

import re
from pathlib import Path

#: Resolution of the PNG files, dots per inch.
DPI = 120


def _require(module: str, package: str, extra: str) -> None:
    """Import `module`, or say in one line which extra installs it."""
    try:
        __import__(module)
    except ImportError:
        raise ImportError(f'{package} is needed here: pip install "sparsekin[{extra}]"') from None


def _new_figure(size: tuple[float, float], rows: int = 1, columns: int = 1):
    """A figure on the Agg canvas and its axes (an array of `rows` stacked axes if rows > 1,
    of `columns` axes side by side if columns > 1)."""
    _require("matplotlib", "matplotlib", "plot")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=size, dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    if columns > 1:
        return figure, figure.subplots(1, columns)
    axes = figure.subplots(rows, 1, sharex=True) if rows > 1 else figure.subplots()
    return figure, axes


def _save(figure, path: Path) -> Path:
    figure.savefig(path, dpi=DPI)
    return path


def _file_safe(name: str) -> str:
    """`name` with every character other than letters, digits, ``-``, ``_``, ``.`` replaced by ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def _dress(axes, title: str) -> None:
    """Grid, axis labels and title of a drawing of the mechanism."""
    axes.grid(True, alpha=0.3)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)

