"""Figures of a kinematic analysis: point motion against time and a drawing of the mechanism.

matplotlib is an optional dependency (``pip install "sparsekin[plot]"``): it is imported
inside the functions, so ``import sparsekin`` never needs it.  Figures are drawn on a
`matplotlib.figure.Figure` with the Agg canvas and written as PNG files; no pyplot state is
created or closed.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from .model import GROUND, Mechanism, Revolute, Translational
from .solvers import KinematicsResult

__all__ = ["plot_point_motion", "draw_mechanism"]

#: Resolution of the PNG files, dots per inch.
DPI = 120
#: Size of symbols (joints, ground marks, one-point bodies) relative to the model's extent.
SYMBOL_SCALE = 0.025
#: Background of body labels: a pale box, so that lines under the name do not hide it.
LABEL_BOX = {"boxstyle": "round,pad=0.15", "facecolor": "white", "alpha": 0.8, "edgecolor": "none"}
#: Panels of a point-motion figure, top to bottom: the `PointMotion` field plotted, the word
#: for it in the panel title, and the label of the y axis.
MOTION_PANELS = (
    ("position", "displacement", "y (m)"),
    ("velocity", "velocity", "$v_y$ (m/s)"),
    ("acceleration", "acceleration", "$a_y$ (m/s²)"),
)


def plot_point_motion(result: KinematicsResult, point_names, directory) -> list[Path]:
    """Plot the vertical displacement, velocity and acceleration of points against time.

    Parameters
    ----------
    result : KinematicsResult
        The analysis to plot.
    point_names : sequence of str
        The points, one figure each.
    directory : str or Path
        Existing folder where the files ``point_<name>.png`` are written.

    Returns
    -------
    list of Path
        The files written, in the order of `point_names`.
    """
    return [_plot_one_point(result, name, Path(directory)) for name in point_names]


def draw_mechanism(mechanism: Mechanism, result: KinematicsResult, directory) -> Path:
    """Draw the mechanism at the first sample of `result` into ``<directory>/mechanism.png``.

    Each body is a closed polygon (or a segment) through the points it carries and is
    labelled with its name (a body with one point is a short bar along its frame's x axis);
    revolute joints are small circles, pivots on the ground carry a hatched triangle,
    translational joints are a dashed line along their axis with a small square, and every
    named point is labelled.

    Parameters
    ----------
    mechanism : Mechanism
        The mechanism analysed.
    result : KinematicsResult
        Its analysis, with at least one sample.
    directory : str or Path
        Existing folder where ``mechanism.png`` is written.

    Returns
    -------
    Path
        The file written.
    """
    positions = {name: result.point(name).position[0] for name in mechanism.points}
    size = SYMBOL_SCALE * _extent(positions.values())
    pivots = [
        (_joint_position(mechanism, result, joint, joint.at), GROUND in joint.bodies)
        for joint in mechanism.joints
        if isinstance(joint, Revolute)
    ]
    ground_marks = [position - (0.0, 1.5 * size) for position, on_ground in pivots if on_ground]
    obstacles = np.array([*positions.values(), *ground_marks]).reshape(-1, 2)
    figure, axes = _new_figure((8.0, 7.0))
    for index, body in enumerate(mechanism.bodies):
        _draw_body(axes, body, positions, result.coordinates[0, 3 * index : 3 * index + 3], size, obstacles)
    for position, on_ground in pivots:
        _draw_revolute(axes, position, size, on_ground)
    for joint in mechanism.joints:
        if isinstance(joint, Translational):
            _draw_translational(axes, _translational_axis(mechanism, result, joint, size), size)
    for name, (x, y) in positions.items():
        axes.annotate(name, (x, y), xytext=(7, 6), textcoords="offset points", fontsize=10, color="tab:blue",
                      zorder=6)
    axes.set_aspect("equal", adjustable="datalim")
    axes.margins(0.08)
    axes.grid(True, alpha=0.3)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(f"{mechanism.name} at t = {result.times[0]:g} s")
    return _save(figure, Path(directory) / "mechanism.png")


# ---------------------------------------------------------------------- point motion
def _plot_one_point(result: KinematicsResult, name: str, directory: Path) -> Path:
    motion = result.point(name)
    figure, panels = _new_figure((7.0, 8.0), rows=3)
    for axes, (field_name, quantity, label) in zip(panels, MOTION_PANELS):
        axes.plot(result.times, getattr(motion, field_name)[:, 1], color="tab:blue", linewidth=1.5)
        axes.set_title(f"Point {name}: vertical {quantity}")
        axes.set_ylabel(label)
        axes.grid(True, alpha=0.4)
    panels[-1].set_xlabel("time t (s)")
    return _save(figure, directory / f"point_{_file_safe(name)}.png")


# ---------------------------------------------------------------------- mechanism
def _draw_body(axes, body, positions, frame, size, obstacles) -> None:
    """A body: polygon, segment, or a short bar from its one point along its frame's x axis.

    The bar of a one-point body (and its label) goes to the side of the point, +x or -x,
    with more room: farther from the other points and from the ground marks in `obstacles`.
    """
    from matplotlib.patches import Polygon

    corners = np.array([positions[name] for name in dict.fromkeys(body.points)]).reshape(-1, 2)
    if len(corners) >= 3:
        corners = _around_centroid(corners)
        axes.add_patch(Polygon(corners, closed=True, facecolor="tab:orange", alpha=0.25, edgecolor="none"))
        axes.add_patch(Polygon(corners, closed=True, fill=False, edgecolor="black", linewidth=1.5))
        _label_body(axes, body.name, corners.mean(axis=0), (0.0, 0.0))
        return
    if len(corners) == 2:
        axes.plot(corners[:, 0], corners[:, 1], color="black", linewidth=2.0)
        along = corners[1] - corners[0]
        _label_body(axes, body.name, corners.mean(axis=0), (-along[1], along[0]))
        return
    origin = corners[0] if len(corners) else frame[:2]
    along = _roomier_direction(origin, frame[2], 4.0 * size, obstacles)
    bar = np.array([origin, origin + 4.0 * size * along])
    axes.plot(bar[:, 0], bar[:, 1], color="dimgray", linewidth=5.0, solid_capstyle="butt")
    _label_body(axes, body.name, origin + 5.5 * size * along, (0.0, 0.0))


def _roomier_direction(origin, angle: float, length: float, obstacles: np.ndarray) -> np.ndarray:
    """Of ±(cos angle, sin angle), the one whose end at `length` is farther from `obstacles`."""
    along = np.array([math.cos(angle), math.sin(angle)])
    others = obstacles[np.hypot(*(obstacles - origin).T) > 1e-9 * length]

    def clearance(direction: np.ndarray) -> float:
        return float(np.min(np.hypot(*(others - (origin + length * direction)).T), initial=np.inf))

    return along if clearance(along) >= clearance(-along) else -along


def _label_body(axes, name: str, position, direction) -> None:
    """The name of a body at `position`, moved 12 points along `direction` (if non-zero)."""
    length = float(np.hypot(*direction))
    offset = (0.0, 0.0) if length == 0.0 else tuple(12.0 * np.asarray(direction) / length)
    axes.annotate(name, position, xytext=offset, textcoords="offset points", ha="center", va="center",
                  fontsize=9, fontweight="bold", zorder=5, bbox=LABEL_BOX)


def _draw_revolute(axes, position, size, on_ground: bool) -> None:
    """A small circle; on the ground, also a hatched triangle below it."""
    from matplotlib.patches import Circle, Polygon

    x, y = position
    if on_ground:
        triangle = [(x, y), (x - 1.2 * size, y - 2.0 * size), (x + 1.2 * size, y - 2.0 * size)]
        axes.add_patch(Polygon(triangle, closed=True, facecolor="lightgray", edgecolor="black", hatch="///",
                               linewidth=1.0, zorder=3))
    axes.add_patch(Circle((x, y), 0.6 * size, facecolor="white", edgecolor="black", linewidth=1.2, zorder=4))


def _draw_translational(axes, ends, size) -> None:
    """A dashed line along the axis with a small square at its middle, turned with it.

    The square sits under the revolute circles, so a pin at the same place stays visible.
    """
    from matplotlib.patches import Rectangle

    start, end = ends
    axes.plot(*np.transpose([start, end]), linestyle="--", color="tab:green", linewidth=1.2, zorder=2)
    middle = 0.5 * (start + end)
    angle = math.degrees(math.atan2(end[1] - start[1], end[0] - start[0]))
    axes.add_patch(Rectangle(middle - 0.9 * size, 1.8 * size, 1.8 * size, angle=angle,
                             rotation_point="center", facecolor="white", edgecolor="tab:green",
                             linewidth=1.5, zorder=3.5))


def _joint_position(mechanism: Mechanism, result: KinematicsResult, joint, reference) -> np.ndarray:
    """Global position at the first sample of a point reference of `joint` (on its first body)."""
    if isinstance(reference, str):
        return result.point(reference).position[0]
    return _carried(mechanism, result, joint.bodies[0], np.asarray(reference, dtype=float))


def _translational_axis(mechanism, result, joint: Translational, size) -> tuple[np.ndarray, np.ndarray]:
    """The two ends of the line drawn for a translational joint."""
    if joint.axis is not None:
        return tuple(_joint_position(mechanism, result, joint, reference) for reference in joint.axis)
    start = _joint_position(mechanism, result, joint, joint.at)
    tip = _carried(mechanism, result, joint.bodies[0], np.add(mechanism.position(joint.at), joint.direction))
    direction = (tip - start) / np.linalg.norm(tip - start)
    return start - 8.0 * size * direction, start + 8.0 * size * direction


def _carried(mechanism: Mechanism, result: KinematicsResult, body: str, initial: np.ndarray) -> np.ndarray:
    """Where a point fixed on `body`, at `initial` in the initial configuration, is at sample 0."""
    if body == GROUND:
        return initial
    x0, y0, angle0 = mechanism.frame(body)
    index = mechanism.body_index(body)
    x, y, angle = result.coordinates[0, 3 * index : 3 * index + 3]
    turn = angle - angle0
    offset = initial - (x0, y0)
    cosine, sine = math.cos(turn), math.sin(turn)
    return np.array([x + cosine * offset[0] - sine * offset[1], y + sine * offset[0] + cosine * offset[1]])


def _around_centroid(corners: np.ndarray) -> np.ndarray:
    """The corners ordered by angle about their centroid: a polygon that does not cross itself."""
    relative = corners - corners.mean(axis=0)
    return corners[np.argsort(np.arctan2(relative[:, 1], relative[:, 0]))]


def _extent(positions) -> float:
    """Largest side of the bounding box of `positions` (1 m when they all coincide)."""
    array = np.array(list(positions), dtype=float).reshape(-1, 2)
    extent = float(np.ptp(array, axis=0).max()) if len(array) else 0.0
    return extent if extent > 0.0 else 1.0


# ---------------------------------------------------------------------- files
def _new_figure(size: tuple[float, float], rows: int = 1):
    """A figure on the Agg canvas and its axes (an array of `rows` stacked axes if rows > 1)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(rows, 1, sharex=True) if rows > 1 else figure.subplots()
    return figure, axes


def _save(figure, path: Path) -> Path:
    figure.savefig(path, dpi=DPI)
    return path


def _file_safe(name: str) -> str:
    """`name` with every character other than letters, digits, ``-``, ``_``, ``.`` replaced by ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)
