"""Figures of a kinematic analysis: point motion, point paths, driver forces, the mechanism,
and its animation; of a sweep: a point's path over the variants and the stop times; of a workspace.

matplotlib is an optional dependency (``pip install "sparsekin[plot]"``): it is imported
inside the functions, so ``import sparsekin`` never needs it.  Figures are drawn on a
`matplotlib.figure.Figure` with the Agg canvas and written as PNG files; no pyplot state is
created or closed.  Animations are written as GIF (Pillow) or MP4 (imageio-ffmpeg):
``pip install "sparsekin[animate]"``.

One configuration is drawn by `draw_configuration`: the still drawing (`draw_mechanism`),
every frame of an animation (`animate`) and a single frame (`save_frame`) all call it, so
a mechanism looks the same in each.  Bodies are drawn from the points they carry; joints
and drivers draw themselves on a `Canvas` as their kinds declare
(`sparsekin.model.elements`); labels are placed last, each where it overlaps no other label
and as little of the drawing as it can (`place_labels`).

>>> import numpy as np
>>> import sparsekin as sk
>>> from sparsekin.plots import frame_times
>>> from sparsekin.testset import task5
>>> result = sk.solve_kinematics(task5(), np.linspace(0.0, 10.0, 101))
>>> times = frame_times(result, fps=20)            # a 10 s clip at 20 frames per second
>>> times.size, float(times[0]), float(times[-1])
(200, 0.0, 10.0)
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..engine.pattern import build_point_map
from ..model.geometry import rotate, to_global, to_local
from ..model.mechanism import GROUND, Mechanism
from ..results.kinematics import KinematicsResult

__all__ = [
    "plot_point_motion",
    "plot_point_paths",
    "plot_actuators",
    "plot_driver_forces",
    "draw_mechanism",
    "draw_configuration",
    "animate",
    "save_frame",
    "frame_times",
    "interpolate_coordinates",
    "place_labels",
    "Animation",
    "Label",
    "Canvas",
    "plot_sweep_paths",
    "plot_stop_times",
    "plot_workspace",
]

#: Resolution of the PNG files, dots per inch.
DPI = 120
#: Size of symbols (joints, ground marks, one-point bodies) relative to the model's extent.
SYMBOL_SCALE = 0.025
#: Background of body labels: a pale box, so that lines under the name do not hide it.
LABEL_PAD = 0.15
LABEL_BOX = {"boxstyle": f"round,pad={LABEL_PAD}", "facecolor": "white", "alpha": 0.8, "edgecolor": "none"}
#: Point labels and body labels: font size (points), weight, colour.
POINT_LABEL_STYLE = {"fontsize": 10, "color": "tab:blue"}
BODY_LABEL_STYLE = {"fontsize": 9, "fontweight": "bold", "color": "black"}
#: Directions tried for a label around its anchor, in order of preference: up-right first
#: (where a reader looks for a point's name), then the other diagonals, then the sides.
LABEL_DIRECTIONS = ((1, 1), (-1, 1), (1, -1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1))
#: Distances tried from a label's anchor, points, beyond the symbol drawn at the anchor.
LABEL_DISTANCES = (3.0, 9.0, 16.0, 26.0)
#: What a label pays for each thing it covers.  Another label is forbidden unless every
#: candidate covers one; leaving the axes is nearly so.
LABEL_COSTS = {"label": 1e4, "outside": 1e3, "segment": 3.0, "disc": 5.0, "distance": 0.25, "rank": 0.01,
               "kept": -2.0}  # fmt: skip
#: Above this many labels a drawing is too crowded to read anyway: each label takes its first
#: place without the search (draw_mechanism of task5_chain(100), 1000 bodies and 2300
#: labels: 16.1 s with the search, 8.2 s without; 11.6 s before labels were placed).
MAX_PLACED_LABELS = 200
#: Length of the cylinder and of the rod of an actuator drawn from one-point bodies, as a
#: fraction of the actuator's drawn length: they overlap by 0.4 of it at the start and part
#: only when it extends by 40 %.
CYLINDER_FRACTION = 0.7
#: Panels of a point-motion figure, top to bottom: the `PointMotion` field plotted, the word
#: for it in the panel title, and the label of the y axis.
MOTION_PANELS = (
    ("position", "position", "position (m)"),
    ("velocity", "velocity", "velocity (m/s)"),
    ("acceleration", "acceleration", "acceleration (m/s²)"),
)
#: Colour of the x and the y component in a point-motion figure.
COMPONENT_COLOURS = {"x": "tab:orange", "y": "tab:blue"}
#: Panels of the actuator figure: the quantity and its unit.
ACTUATOR_PANELS = (("stroke", "stroke (m)"), ("speed", "speed (m/s)"), ("acceleration", "acceleration (m/s²)"))
#: Time marks along a path figure: the path is split into this many equal time intervals.
PATH_TIME_MARKS = 10
#: Frames per second of an animation, by file type.  A GIF stores frame durations in
#: hundredths of a second: 20 frames per second is 5 of them exactly.
DEFAULT_FPS = {".gif": 20.0, ".mp4": 30.0}
#: Highest frame rate of a GIF: browsers show frames of 1 hundredth of a second or less
#: for 10 hundredths.
MAX_GIF_FPS = 50.0
#: How long the last frame of an animation that stopped early (a lock-up) is held, s.
STOP_HOLD = 1.0
#: Size of an animation frame, inches, and its resolution: 640 × 560 pixels (multiples of
#: 16, as the MP4 encoder wants).
FRAME_SIZE = (8.0, 7.0)
FRAME_DPI = 80
#: Colours of traced paths, in turn.
TRACE_COLOURS = ("tab:red", "tab:purple", "tab:cyan", "tab:olive", "tab:pink", "tab:brown")
#: Colour of the mark of an analysis that stopped.
STOP_COLOUR = "#d62728"


def plot_point_motion(result: KinematicsResult, point_names, directory) -> list[Path]:
    """Plot the position, velocity and acceleration of points against time, x and y.

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


def plot_point_paths(result: KinematicsResult, point_names, directory) -> list[Path]:
    """Plot the path of each point in the plane, y against x (equal scales).

    Dots split the path into `PATH_TIME_MARKS` equal intervals of time, so that the
    spacing of the dots shows the speed; the start is a circle, the end a square.

    Parameters
    ----------
    result : KinematicsResult
    point_names : sequence of str
        The points, one figure each.
    directory : str or Path
        Existing folder where the files ``path_<name>.png`` are written.

    Returns
    -------
    list of Path
        The files written, in the order of `point_names`.
    """
    return [_plot_one_path(result, name, Path(directory)) for name in point_names]


def draw_mechanism(mechanism: Mechanism, result: KinematicsResult, directory, *, bodies=None) -> Path:
    """Draw the mechanism at the first sample of `result` into ``<directory>/mechanism.png``.

    The drawing is `draw_configuration`'s: bodies as polygons or segments through their
    points, joints and drivers as their kinds draw themselves (pins, ground marks, guides,
    cylinders and rods along their axis, slots, gears), and every point and body
    labelled where the label overlaps no other.

    Parameters
    ----------
    mechanism : Mechanism
        The mechanism analysed.
    result : KinematicsResult
        Its analysis, with at least one sample.
    directory : str or Path
        Existing folder where ``mechanism.png`` is written.
    bodies : sequence of str, optional
        Draw only these bodies (`draw_configuration`).

    Returns
    -------
    Path
        The file written.
    """
    figure, axes = _new_figure((8.0, 7.0))
    _dress(axes, f"{mechanism.name} at t = {result.times[0]:g} s")
    draw_configuration(axes, mechanism, result.coordinates[0], bodies=bodies)
    return _save(figure, Path(directory) / "mechanism.png")


def _dress(axes, title: str) -> None:
    """Grid, axis labels and title of a drawing of the mechanism."""
    axes.grid(True, alpha=0.3)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)


def plot_actuators(result: KinematicsResult, directory) -> list[Path]:
    """Plot the stroke, speed and acceleration of every linear actuator against time.

    The actuators are the drivers of a stroke (translational) or of a distance; the
    figure ``actuators.png`` has one line per actuator in each of its three panels.
    Nothing is written for a mechanism without one.

    Returns
    -------
    list of Path
        The file written, or an empty list.
    """
    actuators = [
        (index, driver.name or getattr(driver, "joint", None) or f"drivers[{index}]")
        for index, driver in enumerate(result.mechanism.drivers)
        if driver.type_name in ("translational", "distance")
    ]
    if not actuators:
        return []
    figure, panels = _new_figure((7.0, 8.0), rows=3)
    for index, label in actuators:
        for axes, values in zip(panels, result.driver(index)):
            axes.plot(result.times, values, linewidth=1.5, label=label)
    for axes, (quantity, unit) in zip(panels, ACTUATOR_PANELS):
        axes.set_title(f"Actuator {quantity}")
        axes.set_ylabel(unit)
        axes.grid(True, alpha=0.4)
    panels[0].legend(loc="best", fontsize=9)
    panels[-1].set_xlabel("time t (s)")
    return [_save(figure, Path(directory) / "actuators.png")]


def plot_driver_forces(result: KinematicsResult, directory) -> list[Path]:
    """Plot the force (or torque) and the power of every driver the run has forces of.

    One figure, ``forces.png``: forces in newtons in the top panel (a path driver's two
    components as two lines), torques in newton-metres in the middle one (if any driver
    drives an angle), powers in watts at the bottom.  Nothing is written without forces.

    Returns
    -------
    list of Path
        The file written, or an empty list.
    """
    mechanism = result.mechanism
    labels = set(result.force_labels)
    drivers = [(index, driver.name or f"drivers[{index}]") for index, driver in enumerate(mechanism.drivers)
               if f"{driver.name or f'drivers[{index}]'}.power" in labels]  # fmt: skip
    if not drivers:
        return []
    units = dict(zip(result.force_labels, result.force_units))
    kinds = {"N": "Force", "N·m": "Torque"}
    present = [unit for unit in kinds if any(units.get(f"{label}.{name}") == unit for index, label in drivers
                                             for name in type(mechanism.drivers[index]).force_names)]  # fmt: skip
    figure, panels = _new_figure((7.0, 3.0 + 2.6 * len(present)), rows=len(present) + 1)
    panels = list(np.atleast_1d(panels))
    for index, label in drivers:
        force = result.driver_force(index)
        names = type(mechanism.drivers[index]).force_names
        values = force.force.reshape(result.n_times, -1)
        for column, name in enumerate(names):
            unit = units[f"{label}.{name}"]
            shown = label if len(names) == 1 else f"{label}.{name}"
            panels[present.index(unit)].plot(result.times, values[:, column], linewidth=1.5, label=shown)
        panels[-1].plot(result.times, force.power, linewidth=1.5, label=label)
    for axes, unit in zip(panels, present):
        axes.set_title(f"{kinds[unit]} of each driver" + (" (quasi-static)" if result.quasi_static else ""))
        axes.set_ylabel(unit)
    panels[-1].set_title("Power of each driver")
    panels[-1].set_ylabel("W")
    for axes in panels:
        axes.grid(True, alpha=0.4)
        axes.legend(loc="best", fontsize=9)
    panels[-1].set_xlabel("time t (s)")
    return [_save(figure, Path(directory) / "forces.png")]


# ---------------------------------------------------------------------- one configuration
def draw_configuration(axes, mechanism: Mechanism, coordinates, *, size: float | None = None,
                       labels: bool = True, bodies=None) -> list:  # fmt: skip
    """Draw `mechanism` at `coordinates` on matplotlib `axes`: bodies, elements, labels.

    If the axes scale themselves (matplotlib's default), their limits are first set to
    fit the drawing at equal scales and then kept, so that the labels are placed in the
    final picture.  Axes with fixed limits (an animation's) keep them.

    Parameters
    ----------
    axes : matplotlib.axes.Axes
    mechanism : Mechanism
    coordinates : array_like, shape (3 * n_bodies,)
        ``(x, y, angle)`` of every body frame, as in `KinematicsResult.coordinates`.
    size : float, optional
        Size of the symbols, m (default: `SYMBOL_SCALE` times the extent of the points).
    labels : bool
        Label every named point and every body (default True).
    bodies : sequence of str, optional
        Draw only these bodies, their points, and the joints and drivers between them
        and the ground: a part of a large mechanism (default: all).

    Returns
    -------
    list of matplotlib.artist.Artist
        Everything drawn, to be removed before the next frame of an animation.
    """
    drawer = _Drawer(mechanism, bodies)
    coordinates = np.asarray(coordinates, dtype=float)
    if size is None:
        size = SYMBOL_SCALE * _extent(drawer.positions(coordinates[None])[0])
    return drawer.draw(axes, coordinates, size, labels=labels)


class _Drawer:
    """Draws one mechanism at any number of configurations, and remembers the label places
    of the last one (an animation keeps a label where it was while it fits there)."""

    def __init__(self, mechanism: Mechanism, bodies=None) -> None:
        self.mechanism = mechanism
        self.point_map = build_point_map(mechanism)
        names = list(self.point_map.names)
        point_body, point_local = self.point_map.arrays()
        elements = (*mechanism.joints, *mechanism.drivers, *mechanism.loads)
        if bodies is None:
            self.body_indices = list(range(mechanism.n_bodies))
            self.elements = elements
            shown = np.ones(len(names), dtype=bool)
        else:  # a part of the mechanism: these bodies, and the elements between them and the ground
            self.body_indices = [self._index(name) for name in bodies]
            allowed = {*bodies, GROUND}
            self.elements = [element for element in elements if _element_bodies(element) <= allowed]
            shown = np.isin(point_body, self.body_indices)
        self.names = [name for name, keep in zip(names, shown) if keep]
        self.point_body, self.point_local = point_body[shown], point_local[shown]
        self.kept_places: dict[tuple[str, str], int] = {}
        self.texts: dict | None = None  # label artists kept from frame to frame (animations)

    def _index(self, name: str) -> int:
        try:
            index = self.mechanism.body_index(name)
        except KeyError:
            index = -1
        if index < 0:
            raise KeyError(f'unknown body "{name}" to draw (the ground is always drawn)')
        return index

    def origins(self, coordinates: np.ndarray) -> np.ndarray:
        """Frame origins of the bodies drawn, shape (n_configurations, n_drawn, 2)."""
        coordinates = np.asarray(coordinates, dtype=float)
        return coordinates.reshape(coordinates.shape[0], -1, 3)[:, self.body_indices, :2]

    def traced(self, names, coordinates: np.ndarray) -> np.ndarray:
        """Positions of the points `names` (any of the model), shape (n_configurations, len(names), 2)."""
        located = []
        for name in names:
            try:
                located.append(self.point_map.locate(name))
            except KeyError:
                raise KeyError(f'unknown point "{name}" to trace') from None
        body = np.array([b for b, _ in located], dtype=np.int64)
        local = np.array([p for _, p in located], dtype=float).reshape(-1, 2)
        return _point_positions(body, local, coordinates)

    def positions(self, coordinates: np.ndarray) -> np.ndarray:
        """Global positions of the named points, shape (n_configurations, n_points, 2)."""
        return _point_positions(self.point_body, self.point_local, coordinates)

    def draw(self, axes, coordinates: np.ndarray, size: float, labels: bool = True, extra_obstacles=()) -> list:
        before = set(axes.get_children())
        positions = dict(zip(self.names, self.positions(coordinates[None])[0]))
        canvas = Canvas(axes, self.mechanism, coordinates, size)
        for element in self.elements:
            element.draw(canvas)
        bodies = self.mechanism.bodies
        for index in self.body_indices:
            body = bodies[index]
            if body.name not in canvas.drawn_bodies:
                _draw_body(canvas, body, positions, coordinates[3 * index : 3 * index + 3])
        if labels:
            if axes.get_autoscale_on():
                _fit_limits(axes)
            for segment in extra_obstacles:
                canvas.segments.append(segment)
            wanted = [Label(name, position, 0.6 * size, "point") for name, position in positions.items()]
            wanted += [Label(name, anchor, 0.0, "body", along) for name, (anchor, along) in canvas.body_labels.items()]
            placed = place_labels(axes, wanted, canvas.segments, canvas.discs, kept=self.kept_places,
                                  texts=self.texts)  # fmt: skip
            self.kept_places = {(label.kind, label.text): choice for label, choice in placed}
        kept = set(self.texts.values()) if self.texts else set()
        return [artist for artist in axes.get_children() if artist not in before and artist not in kept]


def _element_bodies(element) -> set[str]:
    """The bodies a joint or driver names, from its kind's ``body_fields``."""
    names = set()
    for field_name in type(element).body_fields:
        value = getattr(element, field_name)
        names |= {value} if isinstance(value, str) else set(value)
    return names


def _fit_limits(axes) -> None:
    """Set the limits to the drawing with margins at equal scales, run the figure's layout
    once, and keep both: the labels are placed in the picture as it will be saved."""
    axes.set_aspect("equal", adjustable="datalim")
    axes.margins(0.08)
    axes.autoscale_view()
    figure = axes.get_figure()
    engine = figure.get_layout_engine()
    if engine is not None:
        engine.execute(figure)
        figure.set_layout_engine("none")
    _freeze_limits(axes)


def _freeze_limits(axes) -> None:
    """Keep the limits that equal scales give in the axes' present box."""
    axes.apply_aspect()
    axes.set_xlim(axes.get_xlim())
    axes.set_ylim(axes.get_ylim())
    axes.set_autoscale_on(False)
    axes.set_aspect("equal", adjustable="box")


def _point_positions(body: np.ndarray, local: np.ndarray, coordinates: np.ndarray) -> np.ndarray:
    """Global positions of points on `body` (-1: the ground) at `local` positions in its
    frame, at each configuration `coordinates` (n_configurations, 3 · n_bodies); shape
    (n_configurations, n_points, 2)."""
    coordinates = np.asarray(coordinates, dtype=float)
    frames = coordinates.reshape(coordinates.shape[0], -1, 3)
    positions = np.empty((coordinates.shape[0], len(body), 2))
    on_ground = body < 0
    positions[:, on_ground] = local[on_ground]
    if (~on_ground).any():
        carried = frames[:, body[~on_ground]]  # (n, k, 3)
        positions[:, ~on_ground] = carried[..., :2] + rotate(local[~on_ground], carried[..., 2])
    return positions


# ---------------------------------------------------------------------- bodies
def _draw_body(canvas: Canvas, body, positions, frame) -> None:
    """A body that no element drew: a polygon through its points, a segment, or a short bar
    from its one point along its frame's x axis (to the side with more room)."""
    from matplotlib.patches import Polygon

    corners = np.array([positions[name] for name in dict.fromkeys(body.points)]).reshape(-1, 2)
    if len(corners) >= 3:
        corners = _around_centroid(corners)
        canvas.add_patch(Polygon(corners, closed=True, facecolor="tab:orange", alpha=0.25, edgecolor="none"))
        canvas.add_patch(Polygon(corners, closed=True, fill=False, edgecolor="black", linewidth=1.5))
        canvas.segments.extend(np.stack([corners, np.roll(corners, -1, axis=0)], axis=1))
        canvas.body_labels[body.name] = (corners.mean(axis=0), None)
        return
    if len(corners) == 2:
        canvas.bar(body.name, corners[0], corners[1])
        return
    origin = corners[0] if len(corners) else frame[:2]
    obstacles = np.array([*positions.values(), *canvas.ground_marks]).reshape(-1, 2)
    along = _roomier_direction(origin, frame[2], 4.0 * canvas.size, obstacles)
    canvas.cylinder(body.name, origin, origin + 4.0 * canvas.size * along)


def _roomier_direction(origin, angle: float, length: float, obstacles: np.ndarray) -> np.ndarray:
    """Of ±(cos angle, sin angle), the one whose end at `length` is farther from `obstacles`."""
    along = np.array([math.cos(angle), math.sin(angle)])
    others = obstacles[np.hypot(*(obstacles - origin).T) > 1e-9 * length]

    def clearance(direction: np.ndarray) -> float:
        return float(np.min(np.hypot(*(others - (origin + length * direction)).T), initial=np.inf))

    return along if clearance(along) >= clearance(-along) else -along


def _around_centroid(corners: np.ndarray) -> np.ndarray:
    """The corners ordered by angle about their centroid: a polygon that does not cross itself."""
    relative = corners - corners.mean(axis=0)
    return corners[np.argsort(np.arctan2(relative[:, 1], relative[:, 0]))]


def _extent(positions) -> float:
    """Largest side of the bounding box of `positions` (1 m when they all coincide)."""
    array = np.array(list(positions), dtype=float).reshape(-1, 2)
    extent = float(np.ptp(array, axis=0).max()) if len(array) else 0.0
    return extent if extent > 0.0 else 1.0


# ---------------------------------------------------------------------- labels
class Label(NamedTuple):
    """A label to place: its text, its anchor (data coordinates), the radius of the symbol
    drawn at the anchor (m), ``"point"`` or ``"body"``, and for a body drawn as a segment
    the segment's direction (its label goes beside it, not along it)."""

    text: str
    anchor: np.ndarray
    clearance: float
    kind: str
    along: np.ndarray | None = None


def place_labels(axes, labels, segments=(), discs=(), *, kept=None, texts=None) -> list[tuple[Label, int]]:
    """Place `labels` one after the other, each where it covers no label placed before it
    and as little of the drawing as it can, and draw them.

    Each label tries `LABEL_DIRECTIONS` at `LABEL_DISTANCES` beyond the symbol at its
    anchor (a body label first tries its anchor itself), in display pixels, and takes the
    candidate of least cost (`LABEL_COSTS`) (with more than `MAX_PLACED_LABELS` labels,
    each takes its first candidate): a box over a label placed before it is
    forbidden unless every candidate has one, a box leaving the axes nearly so; each
    segment of the drawing it crosses and each disc it touches cost a little; farther
    candidates cost a little more.  This is greedy: a label placed early is never moved
    for a later one.

    Parameters
    ----------
    axes : matplotlib.axes.Axes
        Axes whose limits and position are final.
    labels : sequence of Label
    segments : sequence of array_like, shape (2, 2)
        Lines of the drawing, data coordinates.
    discs : sequence of (x, y, radius)
        Round symbols of the drawing, data coordinates.
    kept : dict, optional
        ``{(kind, text): candidate}`` of a previous frame: such a candidate gets a bonus
        when it is still free, so that labels do not jump between frames of an animation.
    texts : dict, optional
        ``{(kind, text): matplotlib Text}``: labels drawn before, moved instead of drawn
        anew (new ones are added to it).

    Returns
    -------
    list of (Label, int)
        Each label and the candidate it took.
    """
    kept = kept or {}
    texts = {} if texts is None else texts
    crowded = len(labels) > MAX_PLACED_LABELS
    figure = axes.get_figure()
    renderer = figure.canvas.get_renderer()
    to_pixels = axes.transData.transform
    points_to_pixels = figure.dpi / 72.0
    window = axes.get_window_extent()
    segments_px = to_pixels(np.asarray(segments, dtype=float).reshape(-1, 2)).reshape(-1, 4)
    disc_array = np.asarray(discs, dtype=float).reshape(-1, 3)
    discs_px = np.column_stack([to_pixels(disc_array[:, :2]), disc_array[:, 2] * _pixels_per_metre(axes)])
    scale = _pixels_per_metre(axes)
    boxes = np.empty((0, 4))
    placed = []
    for label in labels:
        style = POINT_LABEL_STYLE if label.kind == "point" else BODY_LABEL_STYLE
        key = (label.kind, label.text)
        text = texts.get(key)
        if text is None:  # measured as matplotlib lays it out (line height, not glyph height)
            text = axes.text(*label.anchor, label.text, ha="center", va="center", zorder=6,
                             bbox=LABEL_BOX if label.kind == "body" else None, **style)  # fmt: skip
            extent = text.get_window_extent(renderer)
            pad = 2 * LABEL_PAD * style["fontsize"] * points_to_pixels if label.kind == "body" else 0.0
            text._sparsekin_size = (extent.width + pad, extent.height + pad)
            texts[key] = text
        width, height = text._sparsekin_size
        anchor = to_pixels(np.asarray(label.anchor, dtype=float)[None])[0]
        candidates, offsets = _label_candidates(label, anchor, width, height, label.clearance * scale,
                                                points_to_pixels)  # fmt: skip
        if crowded:
            text.set_position(axes.transData.inverted().transform([candidates[0, :2] + (width / 2, height / 2)])[0])
            placed.append((label, 0))
            continue
        cost = LABEL_COSTS["distance"] * np.hypot(*offsets.T) / points_to_pixels
        cost += LABEL_COSTS["rank"] * np.arange(len(candidates))
        cost += LABEL_COSTS["label"] * _overlaps(candidates, boxes)
        outside = ((candidates[:, 0] < window.x0) | (candidates[:, 1] < window.y0)
                   | (candidates[:, 2] > window.x1) | (candidates[:, 3] > window.y1))  # fmt: skip
        cost += LABEL_COSTS["outside"] * outside
        cost += LABEL_COSTS["segment"] * _segments_crossing(candidates, segments_px)
        cost += LABEL_COSTS["disc"] * _discs_touching(candidates, discs_px, exclude=anchor)
        previous = kept.get((label.kind, label.text))
        if previous is not None and previous < len(cost) and cost[previous] < LABEL_COSTS["outside"]:
            cost[previous] += LABEL_COSTS["kept"]
        choice = int(np.argmin(cost))
        box = candidates[choice]
        boxes = np.vstack([boxes, box])
        centre = axes.transData.inverted().transform([[(box[0] + box[2]) / 2, (box[1] + box[3]) / 2]])[0]
        text.set_position(centre)
        placed.append((label, choice))
    return placed


def _pixels_per_metre(axes) -> float:
    (x0, _), (x1, _) = axes.transData.transform([[0.0, 0.0], [1.0, 0.0]])
    return abs(x1 - x0)


def _label_candidates(label: Label, anchor, width, height, clearance, points_to_pixels):
    """Boxes ``(x0, y0, x1, y1)`` in pixels of every candidate place, and their offsets."""
    directions = np.array(LABEL_DIRECTIONS, dtype=float)
    if label.along is not None:  # a body drawn as a segment: its name beside it, on either side
        across = np.array([-label.along[1], label.along[0]]) / max(np.hypot(*label.along), 1e-300)
        directions = np.vstack([across, -across, directions])
    directions /= np.hypot(*directions.T)[:, None]
    offsets = [np.zeros((1, 2))] if label.kind == "body" and label.along is None else []  # inside a polygon
    for distance in LABEL_DISTANCES:
        offsets.append(directions * (clearance + distance * points_to_pixels))
    offsets = np.vstack(offsets)
    # the box touches the candidate point on the side facing the anchor
    shift_x = np.where(offsets[:, 0] > 1e-9, 0.0, np.where(offsets[:, 0] < -1e-9, -width, -width / 2))
    shift_y = np.where(offsets[:, 1] > 1e-9, 0.0, np.where(offsets[:, 1] < -1e-9, -height, -height / 2))
    x0 = anchor[0] + offsets[:, 0] + shift_x
    y0 = anchor[1] + offsets[:, 1] + shift_y
    return np.column_stack([x0, y0, x0 + width, y0 + height]), offsets


def _overlaps(candidates: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Number of `boxes` each candidate box overlaps (touching edges do not count)."""
    if not len(boxes):
        return np.zeros(len(candidates))
    c, b = candidates[:, None, :], boxes[None, :, :]
    overlap = (c[..., 0] < b[..., 2]) & (b[..., 0] < c[..., 2]) & (c[..., 1] < b[..., 3]) & (b[..., 1] < c[..., 3])
    return overlap.sum(axis=1)


def _segments_crossing(boxes: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Number of segments ``(x0, y0, x1, y1)`` that meet each box (Liang–Barsky clipping)."""
    if not len(segments):
        return np.zeros(len(boxes))
    start, delta = segments[None, :, :2], segments[None, :, 2:] - segments[None, :, :2]
    low, high = boxes[:, None, :2], boxes[:, None, 2:]
    shape = (len(boxes), len(segments))
    enter, leave, meets = np.zeros(shape), np.ones(shape), np.ones(shape, dtype=bool)
    for axis in (0, 1):
        d = delta[..., axis]
        parallel = np.abs(d) < 1e-12
        meets &= ~parallel | ((start[..., axis] >= low[..., axis]) & (start[..., axis] <= high[..., axis]))
        with np.errstate(divide="ignore", invalid="ignore"):
            t_low = (low[..., axis] - start[..., axis]) / d
            t_high = (high[..., axis] - start[..., axis]) / d
        first, second = np.minimum(t_low, t_high), np.maximum(t_low, t_high)
        enter = np.where(parallel, enter, np.maximum(enter, first))
        leave = np.where(parallel, leave, np.minimum(leave, second))
    return (meets & (enter <= leave)).sum(axis=1)


def _discs_touching(boxes: np.ndarray, discs: np.ndarray, exclude) -> np.ndarray:
    """Number of discs ``(x, y, radius)`` each box touches, leaving out a disc at `exclude`."""
    if not len(discs):
        return np.zeros(len(boxes))
    discs = discs[np.hypot(*(discs[:, :2] - exclude).T) > 0.5]
    nearest = np.clip(discs[None, :, :2], boxes[:, None, :2], boxes[:, None, 2:])
    return (np.hypot(*(nearest - discs[None, :, :2]).transpose(2, 0, 1)) < discs[None, :, 2]).sum(axis=1)


# ---------------------------------------------------------------------- point motion and paths
def _plot_one_point(result: KinematicsResult, name: str, directory: Path) -> Path:
    motion = result.point(name)
    figure, panels = _new_figure((7.0, 8.0), rows=3)
    for axes, (field_name, quantity, label) in zip(panels, MOTION_PANELS):
        values = getattr(motion, field_name)
        for column, component in enumerate(COMPONENT_COLOURS):
            axes.plot(result.times, values[:, column], color=COMPONENT_COLOURS[component], linewidth=1.5,
                      label=component)  # fmt: skip
        axes.set_title(f"Point {name}: {quantity}")
        axes.set_ylabel(label)
        axes.grid(True, alpha=0.4)
    panels[0].legend(loc="best", fontsize=9)
    panels[-1].set_xlabel("time t (s)")
    return _save(figure, directory / f"point_{_file_safe(name)}.png")


def _plot_one_path(result: KinematicsResult, name: str, directory: Path) -> Path:
    position = result.point(name).position
    figure, axes = _new_figure((7.0, 6.0))
    axes.plot(position[:, 0], position[:, 1], color="tab:blue", linewidth=1.5, zorder=2)
    marks = np.linspace(result.times[0], result.times[-1], PATH_TIME_MARKS + 1)
    marked = np.column_stack([np.interp(marks, result.times, position[:, k]) for k in (0, 1)])
    axes.plot(marked[1:-1, 0], marked[1:-1, 1], "o", color="tab:blue", markersize=3.5, zorder=3,
              label=f"every {(marks[1] - marks[0]):.3g} s")  # fmt: skip
    axes.plot(*position[0], "o", color="tab:green", markersize=8, zorder=4, label=f"t = {result.times[0]:g} s")
    axes.plot(*position[-1], "s", color="tab:red", markersize=7, zorder=4, label=f"t = {result.times[-1]:g} s")
    axes.set_aspect("equal", adjustable="datalim")
    axes.margins(0.1)
    axes.grid(True, alpha=0.4)
    axes.legend(loc="best", fontsize=9)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(f"Point {name}: path")
    return _save(figure, directory / f"path_{_file_safe(name)}.png")


# ---------------------------------------------------------------------- animation
@dataclass(frozen=True)
class Animation:
    """What `animate` wrote.

    Attributes
    ----------
    path : Path
        The file.
    times : ndarray, shape (n_frames,)
        The time shown by each frame, s.  (An MP4 of an analysis that stopped repeats its
        last frame for `STOP_HOLD` seconds; a GIF shows it longer.)
    fps : float
        Frames per second.
    duration : float
        Length of the clip, s, including `STOP_HOLD` when the analysis stopped.
    limits : tuple of float
        ``(x_min, x_max, y_min, y_max)`` of the axes, m, the same in every frame.
    stopped : bool
        The analysis stopped before its end; the last frame marks it.
    """

    path: Path
    times: np.ndarray
    fps: float
    duration: float
    limits: tuple[float, float, float, float]
    stopped: bool

    @property
    def n_frames(self) -> int:
        return self.times.size


def frame_times(result: KinematicsResult, fps: float, duration: float | None = None) -> np.ndarray:
    """The time shown by each frame of a clip of `result`, s.

    A clip of `duration` seconds (default: as long as the analysis, so that it plays in
    real time) at `fps` frames per second has ``round(duration * fps)`` frames (at least
    one); they show equally spaced times from the first sample to the last, both
    included, whatever the number and spacing of the samples.
    """
    start, end = float(result.times[0]), float(result.times[-1])
    if duration is None:
        duration = end - start
    n_frames = max(1, round(duration * fps))
    return np.linspace(start, end, n_frames) if n_frames > 1 else np.array([start])


def interpolate_coordinates(result: KinematicsResult, times) -> np.ndarray:
    """Body coordinates at any `times` within the analysis, by cubic Hermite interpolation.

    Between two samples each coordinate is the cubic that matches its values and its
    velocities (both solved) at the two samples: the error is of order h⁴ in the sample
    spacing h, and a sample time gives the sample exactly.

    Parameters
    ----------
    result : KinematicsResult
    times : array_like, shape (n,)
        Within ``[result.times[0], result.times[-1]]``, s.

    Returns
    -------
    ndarray, shape (n, 3 * n_bodies)
    """
    times = np.asarray(times, dtype=float)
    samples = result.times
    if samples.size == 1:
        return np.repeat(result.coordinates[:1], times.size, axis=0)
    if times.size and (times.min() < samples[0] or times.max() > samples[-1]):
        raise ValueError(f"`times` must lie within the analysis, [{samples[0]:g}, {samples[-1]:g}] s")
    k = np.clip(np.searchsorted(samples, times, side="right") - 1, 0, samples.size - 2)
    h = (samples[k + 1] - samples[k])[:, None]
    s = (times[:, None] - samples[k][:, None]) / h
    q0, q1 = result.coordinates[k], result.coordinates[k + 1]
    v0, v1 = result.velocities[k], result.velocities[k + 1]
    return ((2 * s**3 - 3 * s**2 + 1) * q0 + (s**3 - 2 * s**2 + s) * h * v0
            + (-2 * s**3 + 3 * s**2) * q1 + (s**3 - s**2) * h * v1)  # fmt: skip


def animate(result: KinematicsResult, path, *, trace=(), fps: float | None = None, duration: float | None = None,
            labels: bool = True, stopped: str | None = None, bodies=None) -> Animation:  # fmt: skip
    """Write an animation of `result`: a GIF (Pillow) or an MP4 (imageio-ffmpeg), by suffix.

    Each frame is `draw_configuration` at the frame's time, with the paths of the traced
    points so far and a time stamp, on axes whose limits hold every point at every sample
    (they do not move during the clip).  The frames show equally spaced times
    (`frame_times`); the body coordinates there are interpolated between the samples by
    cubic Hermite interpolation on the solved positions and velocities
    (`interpolate_coordinates`), so that the motion is smooth whether the analysis has
    fewer samples than the clip has frames or many more.  When the analysis stopped before
    its end (``result.complete`` is False, e.g. a lock-up), the clip runs up to the last
    solved sample, whose frame is marked in red and held for `STOP_HOLD` seconds.

    Parameters
    ----------
    result : KinematicsResult
        The analysis, with at least one sample.
    path : str or Path
        ``*.gif`` or ``*.mp4``; its folder must exist.
    trace : sequence of str
        Points whose paths are drawn.
    fps : float, optional
        Frames per second (default 20 for a GIF, 30 for an MP4; at most 50 for a GIF).
    duration : float, optional
        Length of the clip, s (default: the time span of the analysis, real time).
    labels : bool
        Label the points and the bodies (default True).
    stopped : str, optional
        The mark of an analysis that stopped, written on the last frame (default
        "analysis stopped after t = … s" when ``result.complete`` is False).
    bodies : sequence of str, optional
        Draw only these bodies (`draw_configuration`); the axes hold them and the traced
        paths.

    Returns
    -------
    Animation
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in DEFAULT_FPS:
        raise ValueError(f"`path` must end in .gif or .mp4, got {path.name!r}")
    fps = DEFAULT_FPS[suffix] if fps is None else float(fps)
    if not (math.isfinite(fps) and fps > 0.0) or (suffix == ".gif" and fps > MAX_GIF_FPS):
        limit = f" and at most {MAX_GIF_FPS:g} for a GIF" if suffix == ".gif" else ""
        raise ValueError(f"`fps` must be a number > 0{limit}, got {fps!r}")
    if duration is not None and not (math.isfinite(duration) and duration > 0.0):
        raise ValueError(f"`duration` must be a number of seconds > 0, got {duration!r}")
    if result.n_times == 0:
        raise ValueError("`result` has no sample to animate")
    _require("matplotlib", "matplotlib", "animate")
    _require(*(("PIL", "Pillow") if suffix == ".gif" else ("imageio_ffmpeg", "imageio-ffmpeg")), "animate")
    if stopped is None and not result.complete:
        stopped = f"analysis stopped after t = {result.times[-1]:.6g} s"
    times = frame_times(result, fps, duration)
    scene = _Scene(result, trace, times, labels, stopped, bodies)
    frames = (scene.frame(k) for k in range(times.size))
    hold = STOP_HOLD if stopped else 0.0
    if suffix == ".gif":
        _write_gif(path, frames, times.size, fps, hold)
    else:
        _write_mp4(path, frames, fps, hold)
    return Animation(path, times, fps, times.size / fps + hold, scene.limits, bool(stopped))


def save_frame(result: KinematicsResult, path, time: float | None = None, *, trace=(), labels: bool = True,
               stopped: str | None = None, bodies=None) -> Path:  # fmt: skip
    """Write one frame of the animation of `result` as a PNG file.

    The frame at `time` (default: the last sample) is drawn as in `animate`, with the
    traced paths up to that time, on the axes of the whole clip.

    Returns
    -------
    Path
        The file written.
    """
    end = float(result.times[-1])
    time = end if time is None else float(time)
    if not result.times[0] <= time <= end:
        raise ValueError(f"`time` must lie within the analysis, [{result.times[0]:g}, {end:g}] s, got {time!r}")
    if stopped is None and not result.complete and time == end:
        stopped = f"analysis stopped after t = {end:.6g} s"
    times = np.union1d(frame_times(result, DEFAULT_FPS[".gif"]), [time])
    scene = _Scene(result, trace, times, labels, stopped if time == end else None, bodies)
    scene.draw(int(np.searchsorted(times, time)))
    path = Path(path)
    scene.figure.savefig(path, dpi=FRAME_DPI)
    return path


class _Scene:
    """The figure of an animation: fixed axes, and what changes from frame to frame."""

    def __init__(self, result: KinematicsResult, trace, times: np.ndarray, labels: bool, stopped: str | None,
                 bodies=None):  # fmt: skip
        if result.coordinates is None:
            raise ValueError("`result` has no coordinates to draw: solve with coordinates=True (the default)")
        mechanism = result.mechanism
        self.times, self.labels, self.stopped = times, labels, stopped
        self.drawer = _Drawer(mechanism, bodies)
        self.coordinates = interpolate_coordinates(result, times)
        self.trace_names = tuple(trace)
        self.traces = self.drawer.traced(self.trace_names, self.coordinates)  # (n_frames, n_traced, 2)
        extent_points = np.vstack([self.drawer.positions(result.coordinates).reshape(-1, 2),
                                   self.drawer.origins(result.coordinates).reshape(-1, 2),
                                   self.traces.reshape(-1, 2)])  # fmt: skip
        self.size = SYMBOL_SCALE * _extent(extent_points)
        self.figure, self.axes = _new_figure(FRAME_SIZE)
        self.figure.set_dpi(FRAME_DPI)
        axes = self.axes
        low, high = extent_points.min(axis=0), extent_points.max(axis=0)
        margin = 0.06 * float((high - low).max()) + 3.0 * self.size
        axes.update_datalim([low - margin, high + margin])
        axes.margins(0.0)
        axes.autoscale_view()
        axes.set_aspect("equal", adjustable="datalim")
        _dress(axes, mechanism.name)
        self.figure.get_layout_engine().execute(self.figure)
        self.figure.set_layout_engine("none")
        _freeze_limits(axes)
        self.limits = (*axes.get_xlim(), *axes.get_ylim())
        self.stamp = axes.text(0.02, 0.98, "", transform=axes.transAxes, ha="left", va="top", fontsize=11,
                               family="monospace", zorder=7, bbox=LABEL_BOX)  # fmt: skip
        self.trace_lines = []
        for k, name in enumerate(self.trace_names):
            colour = TRACE_COLOURS[k % len(TRACE_COLOURS)]
            axes.plot(self.traces[:, k, 0], self.traces[:, k, 1], color=colour, linewidth=0.8, alpha=0.25, zorder=1)
            (line,) = axes.plot([], [], color=colour, linewidth=1.8, zorder=1.5, label=f"path of {name}")
            self.trace_lines.append(line)
        if self.trace_names:
            axes.legend(loc="upper right", fontsize=9)
        self.changing: list = []
        self.drawer.texts = {}
        self.figure.canvas.draw()  # what no frame changes, drawn once
        self.background = self.figure.canvas.copy_from_bbox(self.figure.bbox)

    def draw(self, k: int) -> None:
        """Draw frame `k` on the figure."""
        for artist in self.changing:
            artist.remove()
        paths = []
        for line, trace in zip(self.trace_lines, np.moveaxis(self.traces[: k + 1], 1, 0)):
            line.set_data(trace[:, 0], trace[:, 1])
            paths.extend(np.stack([trace[:-1], trace[1:]], axis=1))
        self.changing = self.drawer.draw(self.axes, self.coordinates[k], self.size, labels=self.labels,
                                         extra_obstacles=paths)  # fmt: skip
        stop = self.stopped is not None and k == self.times.size - 1
        self.stamp.set_text(f"t = {self.times[k]:7.3f} s")
        self.stamp.set_color(STOP_COLOUR if stop else "black")
        if stop:
            self.changing.append(self.axes.text(
                0.5, 0.04, self.stopped, transform=self.axes.transAxes,
                ha="center", va="bottom", fontsize=12, fontweight="bold", color=STOP_COLOUR, zorder=8,
                bbox={"boxstyle": "round,pad=0.3", "facecolor": "white", "edgecolor": STOP_COLOUR, "linewidth": 2},
            ))  # fmt: skip
            for spine in self.axes.spines.values():
                spine.set_edgecolor(STOP_COLOUR)
                spine.set_linewidth(3.0)

    def frame(self, k: int) -> np.ndarray:
        """Frame `k` as an RGB array, shape (height, width, 3): the background drawn once,
        and over it only what changes (matplotlib's blitting)."""
        self.draw(k)
        canvas = self.figure.canvas
        canvas.restore_region(self.background)
        moving = [*self.changing, *self.drawer.texts.values(), *self.trace_lines, self.stamp]
        if self.stopped is not None and k == self.times.size - 1:
            moving += self.axes.spines.values()
        for artist in sorted(moving, key=lambda artist: artist.get_zorder()):
            self.axes.draw_artist(artist)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _write_gif(path: Path, frames, n_frames: int, fps: float, hold: float) -> None:
    """Frames on one palette (made from the first and the last frame, which between them
    hold every colour the clip uses); durations in whole hundredths of a second that add
    up to the clip's length."""
    from PIL import Image

    frames = list(frames)
    first, last = frames[0], frames[-1]
    palette = Image.fromarray(np.vstack([first, last])).quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    images = [Image.fromarray(frame).quantize(palette=palette, dither=Image.Dither.NONE) for frame in frames]
    ends = np.round(100.0 * np.arange(1, n_frames + 1) / fps).astype(int)
    centiseconds = np.diff(ends, prepend=0)
    centiseconds[-1] += round(100.0 * hold)
    images[0].save(path, save_all=True, append_images=images[1:], duration=[10 * int(c) for c in centiseconds],
                   loop=0, disposal=1, optimize=False)  # fmt: skip


def _write_mp4(path: Path, frames, fps: float, hold: float) -> None:
    """H.264 frames through imageio-ffmpeg (yuv420p, which every player reads)."""
    import imageio_ffmpeg

    writer = None
    frame = None
    for frame in frames:
        if writer is None:
            height, width, _ = frame.shape
            writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264",
                                                 pix_fmt_out="yuv420p", quality=7, macro_block_size=16,
                                                 ffmpeg_log_level="error")  # fmt: skip
            writer.send(None)
        writer.send(np.ascontiguousarray(frame))
    for _ in range(round(hold * fps)):
        writer.send(np.ascontiguousarray(frame))
    writer.close()


# ---------------------------------------------------------------------- the canvas of elements
class Canvas:
    """What an element kind draws with: positions at one configuration, and symbols.

    Each kind of `sparsekin.model.elements` declares ``draw(self, canvas)`` in terms of these
    methods, so that it never touches matplotlib.  The canvas also records what is drawn
    where (`segments`, `discs`), for the labels to avoid, and which bodies the elements
    drew themselves (`drawn_bodies`: a cylinder and its rod, a slider block), which are
    then not drawn again from their points.

    Parameters
    ----------
    axes : matplotlib Axes
    mechanism : Mechanism
    coordinates : ndarray, shape (n_coordinates,)
        The configuration drawn.
    size : float
        Size of symbols, m.

    Attributes
    ----------
    size : float
    ground_marks : list of ndarray
        Where the hatched ground symbols are.
    segments : list of ndarray, shape (2, 2)
        Lines drawn, global.
    discs : list of (x, y, radius)
        Round symbols drawn, global.
    drawn_bodies : set of str
        Bodies drawn by an element.
    body_labels : dict
        Body name -> (label anchor, direction of the body's segment or None).
    """

    def __init__(self, axes, mechanism: Mechanism, coordinates: np.ndarray, size: float) -> None:
        self.axes, self.size = axes, size
        self._mechanism = mechanism
        self._drawn = mechanism.frames()
        self._now = np.asarray(coordinates, dtype=float).reshape(-1, 3)
        self.ground_marks: list[np.ndarray] = []
        self.segments: list[np.ndarray] = []
        self.discs: list[tuple[float, float, float]] = []
        self.drawn_bodies: set[str] = set()
        self.body_labels: dict[str, tuple[np.ndarray, np.ndarray | None]] = {}
        self._fixed = not axes.get_autoscale_on()

    # ------------------------------------------------------------------ where things are
    def point(self, body: str, reference) -> np.ndarray:
        """Where the point of `body` that starts at `reference` (a name or (x, y)) is now."""
        start = np.asarray(self._mechanism.position(reference), dtype=float)
        if body == GROUND:
            return start
        index = self._mechanism.body_index(body)
        local = to_local(self._drawn[index : index + 1], start[None])
        return to_global(self._now[index : index + 1], local)[0]

    def drawn_point(self, reference) -> np.ndarray:
        """Where the point `reference` is in the model's drawing (the initial configuration)."""
        return np.asarray(self._mechanism.position(reference), dtype=float)

    def direction(self, body: str, vector) -> np.ndarray:
        """The unit vector fixed in `body` that was `vector` in the drawing, now."""
        vector = np.asarray(vector, dtype=float) / np.hypot(*vector)
        if body == GROUND:
            return vector
        index = self._mechanism.body_index(body)
        return rotate(vector, self._now[index, 2] - self._drawn[index, 2])

    def origin(self, body: str) -> np.ndarray:
        """The frame origin of `body` now."""
        return np.zeros(2) if body == GROUND else self._now[self._mechanism.body_index(body), :2].copy()

    def pivot(self, body: str, other: str) -> np.ndarray:
        """Where a revolute joins `body` to `other` now; the frame origin of `body` if none does."""
        for joint in self._mechanism.joints:
            if joint.type_name == "revolute" and set(joint.bodies) == {body, other}:
                return self.point(body, joint.at)
        return self.origin(body)

    def single_point(self, body: str) -> bool:
        """Whether `body` is a moving body that carries at most one named point (a cylinder,
        a rod, a slider block), which an element may draw."""
        if body == GROUND:
            return False
        return len(set(self._mechanism.bodies[self._mechanism.body_index(body)].points)) <= 1

    # ------------------------------------------------------------------ symbols
    def pin(self, position, grounded: bool) -> None:
        """A small circle; on the ground, also a hatched triangle below it."""
        from matplotlib.patches import Circle, Polygon

        x, y = position
        size = self.size
        if grounded:
            triangle = [(x, y), (x - 1.2 * size, y - 2.0 * size), (x + 1.2 * size, y - 2.0 * size)]
            self.add_patch(Polygon(triangle, closed=True, facecolor="lightgray", edgecolor="black",
                                        hatch="///", linewidth=1.0, zorder=3))  # fmt: skip
            self.ground_marks.append(np.array([x, y - 1.5 * size]))
            self.discs.append((x, y - 1.4 * size, 1.1 * size))
        self.add_patch(Circle((x, y), 0.6 * size, facecolor="white", edgecolor="black", linewidth=1.2, zorder=4))
        self.discs.append((x, y, 0.6 * size))

    def slide(self, guide: str, slider: str, start, end, direction=None, limits=None) -> None:
        """A translational joint: `slider` slides along a line fixed in `guide`.

        `start` is the reference of the point of `guide` the line goes through, `end` the
        point of `slider` on it; the line runs along `direction` (drawn, global) or, when
        it is None, from `start` to `end` as drawn.  The slider's point is then at
        ``start + stroke · direction``.  One-point bodies are drawn here, with lengths fixed
        in them: a one-point guide is a cylinder from `start` towards `end`, and a
        one-point slider on it the rod from `end` back into it.  On any other guide the
        line is dashed, over the stroke's `limits` when given, and the slider is a block
        (a square) at its point.
        """
        drawn_start, drawn_end = self.drawn_point(start), self.drawn_point(end)
        length = float(np.hypot(*(drawn_end - drawn_start)))
        along = self.direction(guide, direction if direction is not None else drawn_end - drawn_start)
        here, there = self.point(guide, start), self.point(slider, end)
        if self.single_point(guide):
            reach = CYLINDER_FRACTION * length if length > 0.0 else 6.0 * self.size
            centred = 0.5 if length == 0.0 else 0.0  # an `at`/`direction` joint: drawn about its point
            self.cylinder(guide, here - centred * reach * along, here + (1.0 - centred) * reach * along)
            if self.single_point(slider):
                self.rod(slider, there + centred * reach * along, there - (1.0 - centred) * reach * along)
            return
        if limits is not None:
            low, high = limits
        elif length > 0.0:
            low, high = -0.15 * length, 1.15 * length
        else:
            low, high = -6.0 * self.size, 6.0 * self.size
        self._dashed(here + low * along, here + high * along)
        if self.single_point(slider):
            self.block(slider, there, along)
        else:
            self._square(there, along, zorder=3.5)

    def slider(self, start, end) -> None:
        """A dashed line from `start` to `end` with a small square at its middle, turned with it."""
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        self._dashed(start, end)
        self._square((start + end) / 2, end - start, zorder=3.5)

    def cylinder(self, body: str, start, end) -> None:
        """`body` drawn as a thick grey bar from `start` to `end` (a hydraulic cylinder)."""
        self._body_segment(body, start, end, color="dimgray", linewidth=6.0)

    def rod(self, body: str, start, end) -> None:
        """`body` drawn as a thin dark bar from `start` to `end` (a piston rod)."""
        self._body_segment(body, start, end, color="#303030", linewidth=2.5)

    def bar(self, body: str, start, end) -> None:
        """`body` drawn as a black line from `start` to `end` (a two-point link)."""
        self._body_segment(body, start, end, color="black", linewidth=2.0, claim=False)

    def block(self, body: str, position, along) -> None:
        """`body` drawn as a slider block at `position`, turned along `along`."""
        self._square(position, along, zorder=3.5, scale=1.4)
        self.drawn_bodies.add(body)
        self.body_labels[body] = (np.asarray(position, dtype=float), None)

    def slot(self, centre, along, limits=None) -> None:
        """A slot: two parallel lines along `along` about `centre`, over `limits` (m) if given."""
        low, high = limits if limits is not None else (-6.0 * self.size, 6.0 * self.size)
        across = 0.8 * self.size * np.array([-along[1], along[0]])
        for side in (across, -across):
            ends = np.array([centre + low * along + side, centre + high * along + side])
            self.add_line(ends[:, 0], ends[:, 1], color="tab:green", linewidth=1.5, zorder=2)
            self.segments.append(ends)

    def weld(self, position) -> None:
        """A small filled square: two bodies welded together."""
        from matplotlib.patches import Rectangle

        self.add_patch(Rectangle(np.asarray(position) - 0.5 * self.size, self.size, self.size,
                                      facecolor="black", zorder=4))  # fmt: skip
        self.discs.append((*np.asarray(position, dtype=float), 0.7 * self.size))

    def circle(self, centre, radius: float) -> None:
        """A dash-dotted circle: a gear's or a pinion's pitch circle."""
        from matplotlib.patches import Circle

        self.add_patch(Circle(tuple(centre), radius, fill=False, edgecolor="tab:purple", linestyle="-.",
                                   linewidth=1.2, zorder=2))  # fmt: skip

    def line(self, start, end) -> None:
        """A dash-dotted line: a rack's pitch line."""
        self.add_line(*np.transpose([start, end]), linestyle="-.", color="tab:purple", linewidth=1.2, zorder=2)
        self.segments.append(np.array([start, end], dtype=float))

    def actuator(self, start, end, drawn_length: float | None = None) -> None:
        """A linear actuator between two points: a thick cylinder from `start`, a thin rod to `end`.

        With its `drawn_length` (the distance in the model's drawing), the cylinder and the
        rod keep their lengths as the actuator extends; without, the cylinder covers 55 %
        of the present length.
        """
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        length = float(np.hypot(*(end - start)))
        along = (end - start) / length if length > 0.0 else np.zeros(2)
        reach = CYLINDER_FRACTION * drawn_length if drawn_length else 0.55 * length
        self.add_line(*np.transpose([start, start + reach * along]), color="dimgray", linewidth=6.0,
                      solid_capstyle="butt", zorder=2)  # fmt: skip
        rod_start = end - reach * along if drawn_length else start
        self.add_line(*np.transpose([rod_start, end]), color="#303030", linewidth=2.5, zorder=2.5)
        self.segments.append(np.array([start, end]))

    def arrow(self, position, direction) -> None:
        """An arrow ending at `position` along `direction` (a force applied there); none for a
        zero direction."""
        from matplotlib.patches import FancyArrowPatch

        direction = np.asarray(direction, dtype=float)
        length = float(np.hypot(*direction))
        if length == 0.0:
            return
        head = np.asarray(position, dtype=float)
        tail = head - 5.0 * self.size * direction / length
        self.add_patch(FancyArrowPatch(tuple(tail), tuple(head), arrowstyle="-|>", mutation_scale=12, color="tab:red",
                                       linewidth=1.8, zorder=5))  # fmt: skip
        self.segments.append(np.array([tail, head]))

    def turn(self, centre) -> None:
        """A curved arrow about `centre`: a torque."""
        from matplotlib.patches import FancyArrowPatch

        x, y = centre
        radius = 2.0 * self.size
        self.add_patch(FancyArrowPatch((x + radius, y), (x, y + radius), connectionstyle="arc3,rad=0.5",
                                       arrowstyle="-|>", mutation_scale=12, color="tab:red", linewidth=1.5,
                                       zorder=5))  # fmt: skip
        self.discs.append((x, y, radius))

    def spring(self, start, end) -> None:
        """A zigzag between two points: a spring-damper."""
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        along = end - start
        length = float(np.hypot(*along))
        if length == 0.0:
            return
        across = 0.8 * self.size * np.array([-along[1], along[0]]) / length
        fractions = np.linspace(0.2, 0.8, 13)
        zigzag = start + fractions[:, None] * along + np.where(np.arange(13) % 2, 1.0, -1.0)[:, None] * across
        zigzag[[0, -1]] = start + fractions[[0, -1], None] * along
        line = np.vstack([start, zigzag, end])
        self.add_line(line[:, 0], line[:, 1], color="tab:brown", linewidth=1.2, zorder=2)
        self.segments.append(np.array([start, end]))

    def target(self, position) -> None:
        """A cross in a circle: a point whose path is prescribed."""
        from matplotlib.patches import Circle

        x, y = position
        size = self.size
        self.add_patch(Circle((x, y), 1.2 * size, fill=False, edgecolor="tab:red", linewidth=1.5, zorder=4))
        self.add_line([x - 1.6 * size, x + 1.6 * size], [y, y], color="tab:red", linewidth=1.0, zorder=4)
        self.add_line([x, x], [y - 1.6 * size, y + 1.6 * size], color="tab:red", linewidth=1.0, zorder=4)
        self.discs.append((x, y, 1.6 * size))

    # ------------------------------------------------------------------ matplotlib
    def add_patch(self, patch) -> None:
        """Add a matplotlib patch; on axes with fixed limits, without updating the data limits
        (a third of the time of an animation frame went there)."""
        if self._fixed:
            self.axes.add_artist(patch)
        else:
            self.axes.add_patch(patch)

    def add_line(self, xs, ys, **style) -> None:
        """Add a line through `xs`, `ys` with matplotlib `style` (``Line2D`` keywords)."""
        from matplotlib.lines import Line2D

        if self._fixed:
            self.axes.add_artist(Line2D(xs, ys, **style))
        else:
            self.axes.add_line(Line2D(xs, ys, **style))

    # ------------------------------------------------------------------ helpers
    def _body_segment(self, body: str, start, end, *, color: str, linewidth: float, claim: bool = True) -> None:
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        self.add_line(*np.transpose([start, end]), color=color, linewidth=linewidth, solid_capstyle="butt",
                       zorder=2.2 if linewidth > 3 else 2.4)  # fmt: skip
        self.segments.append(np.array([start, end]))
        if claim:
            self.drawn_bodies.add(body)
        self.body_labels[body] = ((start + end) / 2, end - start)

    def _dashed(self, start, end) -> None:
        self.add_line(*np.transpose([start, end]), linestyle="--", color="tab:green", linewidth=1.2, zorder=2)
        self.segments.append(np.array([start, end], dtype=float))

    def _square(self, centre, along, zorder: float, scale: float = 1.0) -> None:
        """A square turned along `along`; under the revolute circles, so a pin there stays visible."""
        from matplotlib.patches import Rectangle

        half = 0.9 * scale * self.size
        angle = math.degrees(math.atan2(along[1], along[0]))
        self.add_patch(Rectangle(np.asarray(centre) - half, 2 * half, 2 * half, angle=angle,
                                      rotation_point="center", facecolor="white", edgecolor="tab:green",
                                      linewidth=1.5, zorder=zorder))  # fmt: skip
        self.discs.append((*np.asarray(centre, dtype=float), 1.2 * half))


# ---------------------------------------------------------------------- sweeps and workspaces
#: Colours of the variants' statuses and of the workspace's grid points.
STATUS_COLOURS = {"complete": "tab:green", "singular": "tab:red", "no_convergence": "tab:orange",
                  "invalid": "tab:gray", "reachable": "tab:green", "outside_limits": "tab:orange",
                  "beyond_singular": "0.85", "no_convergence_ws": "tab:purple"}  # fmt: skip


def plot_sweep_paths(result, point: str, directory) -> Path:
    """Draw the path of `point` in every variant of a sweep into ``sweep_paths_<point>.png``.

    A grid sweep draws one line per variant, coloured by the first varied number (a
    variant that stopped ends with a cross).  A tolerance study (random deviations of the
    points) draws every path thinly with their mean, and beside it the band of the
    distance from the mean path against time: the 5–95 % range and the largest.

    Parameters
    ----------
    result : SweepResult
    point : str
        A recorded point.
    directory : str or Path
        Existing folder.

    Returns
    -------
    Path
    """
    positions = result.point(point)  # (n_variants, n_times, 2)
    tolerance_study = result.variants.perturb_points is not None
    figure, axes = _new_figure((12.0, 5.5), columns=2) if tolerance_study else _new_figure((7.5, 6.5))
    path_axes = axes[0] if tolerance_study else axes
    if tolerance_study:
        for path in positions:
            path_axes.plot(path[:, 0], path[:, 1], color="tab:blue", linewidth=0.5, alpha=0.25)
        with np.errstate(invalid="ignore"), warnings.catch_warnings():  # variants that stopped: NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(positions, axis=0)
            distance = np.linalg.norm(positions - mean, axis=2)
            low, high = np.nanpercentile(distance, 5, axis=0), np.nanpercentile(distance, 95, axis=0)
            largest = np.nanmax(distance, axis=0)
        path_axes.plot(mean[:, 0], mean[:, 1], color="black", linewidth=1.5, label="mean path")
        path_axes.legend(loc="best", fontsize=9)
        band = axes[1]
        band.fill_between(result.times, low * 1e3, high * 1e3, color="tab:blue", alpha=0.3, label="5–95 %")
        band.plot(result.times, largest * 1e3, color="tab:red", linewidth=1.0, label="largest")
        band.set_xlabel("time t (s)")
        band.set_ylabel(f"distance of {point} from the mean path (mm)")
        band.set_title(f"{result.n_variants} samples, σ = {result.variants.perturb_points * 1e3:g} mm on every point")
        band.grid(True, alpha=0.4)
        band.legend(loc="best", fontsize=9)
    else:
        from matplotlib import colormaps
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import Normalize

        key = result.parameters[:, 0] if result.parameters.shape[1] else np.arange(result.n_variants, dtype=float)
        norm = Normalize(float(np.min(key)), float(np.max(key)) if np.max(key) > np.min(key) else float(np.min(key)) + 1)
        cmap = colormaps["viridis"]
        for k in np.argsort(-key, kind="stable"):  # the largest first: a shorter path shows on a longer one
            path, colour = positions[k], cmap(norm(key[k]))
            path_axes.plot(path[:, 0], path[:, 1], color=colour, linewidth=1.0)
            if result.status[k] != "complete":
                last = np.flatnonzero(np.isfinite(path[:, 0]))
                if last.size:
                    path_axes.plot(*path[last[-1]], marker="x", color="tab:red", markersize=7)
        label = result.columns[0] if result.columns else "variant"
        figure.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=path_axes, label=label)
    path_axes.set_aspect("equal", adjustable="datalim")
    path_axes.grid(True, alpha=0.3)
    path_axes.set_xlabel("x (m)")
    path_axes.set_ylabel("y (m)")
    path_axes.set_title(f"Path of {point} in {result.n_variants} variants" + ("" if tolerance_study else
                        " (×: stopped)"))  # fmt: skip
    return _save(figure, Path(directory) / f"sweep_paths_{_file_safe(point)}.png")


def plot_stop_times(result, directory) -> Path:
    """Draw each variant's stop time against the first varied number into ``stop_times.png``.

    Markers are coloured by status; a tolerance study without a grid draws the stop
    times against the variant number.

    Returns
    -------
    Path
    """
    figure, axes = _new_figure((7.5, 4.5))
    grid_columns = len(result.variants.columns)
    x = result.parameters[:, 0] if grid_columns else np.arange(result.n_variants, dtype=float)
    for status in dict.fromkeys(result.status.tolist()):
        mask = result.status == status
        axes.plot(x[mask], result.t_stop[mask], linestyle="none", marker="o", markersize=5,
                  color=STATUS_COLOURS.get(status, "black"), label=status)  # fmt: skip
    axes.set_xlabel(result.columns[0] if grid_columns else "variant")
    axes.set_ylabel("time of the last solved sample (s)")
    axes.set_title(f"Stop time of {result.n_variants} variants")
    axes.grid(True, alpha=0.4)
    axes.legend(loc="best", fontsize=9)
    return _save(figure, Path(directory) / "stop_times.png")


def plot_workspace(space, directory) -> Path:
    """Draw a `~sparsekin.studies.workspaces.Workspace` into ``workspace_<point>.png``.

    Left, the grid of the two drivers' values coloured by status, the singular boundary
    (crosses) and the start; right, the point's positions over the reachable grid points
    (coloured by the first driver's value), those outside limits in orange, and the
    positions where the continuation met the singular boundary.

    Returns
    -------
    Path
    """
    from matplotlib.colors import ListedColormap

    figure, (grid_axes, plane) = _new_figure((13.0, 5.8), columns=2)
    statuses = ("reachable", "outside_limits", "beyond_singular", "no_convergence")
    codes = np.full(space.status.shape, np.nan)
    for c, status in enumerate(statuses):
        codes[space.status == status] = c
    colours = [STATUS_COLOURS[s] if s != "no_convergence" else STATUS_COLOURS["no_convergence_ws"] for s in statuses]
    grid_axes.pcolormesh(space.values[0], space.values[1], codes, cmap=ListedColormap(colours), vmin=-0.5,
                         vmax=len(statuses) - 0.5, shading="nearest")  # fmt: skip
    if len(space.boundary):
        grid_axes.plot(space.boundary[:, 0], space.boundary[:, 1], "kx", markersize=5, label="singular boundary")
    grid_axes.plot(*space.start, marker="*", color="black", markersize=12, linestyle="none", label="t = 0")
    from matplotlib.patches import Patch

    handles = [Patch(color=colour, label=status.replace("_", " ")) for status, colour in zip(statuses, colours)
               if (space.status == status).any()]  # fmt: skip
    grid_axes.legend(handles=handles + grid_axes.get_legend_handles_labels()[0], loc="best", fontsize=8)
    grid_axes.set_xlabel(space.drivers[0])
    grid_axes.set_ylabel(space.drivers[1])
    grid_axes.set_title("Driver values")
    reachable, outside = space.status == "reachable", space.status == "outside_limits"
    a_values = np.broadcast_to(space.values[0][None, :], space.status.shape)
    scatter = plane.scatter(space.positions[reachable][:, 0], space.positions[reachable][:, 1], c=a_values[reachable],
                            s=6, cmap="viridis", label="reachable")  # fmt: skip
    if outside.any():
        plane.scatter(space.positions[outside][:, 0], space.positions[outside][:, 1], s=6,
                      color=STATUS_COLOURS["outside_limits"], label="outside limits")  # fmt: skip
    if len(space.boundary_positions):
        plane.plot(space.boundary_positions[:, 0], space.boundary_positions[:, 1], "rx", markersize=5,
                   label="at the singular boundary")  # fmt: skip
    figure.colorbar(scatter, ax=plane, label=space.drivers[0].split(" ", 1)[0])
    plane.set_aspect("equal", adjustable="datalim")
    plane.grid(True, alpha=0.3)
    plane.legend(loc="best", fontsize=8)
    plane.set_xlabel("x (m)")
    plane.set_ylabel("y (m)")
    plane.set_title(f"Reachable positions of {space.point}")
    return _save(figure, Path(directory) / f"workspace_{_file_safe(space.point)}.png")


# ---------------------------------------------------------------------- files
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
