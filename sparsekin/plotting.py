"""Figures of a kinematic analysis: point motion against time and a drawing of the mechanism;
of a sweep: a point's path over the variants and the stop times; of a workspace.

matplotlib is an optional dependency (``pip install "sparsekin[plot]"``): it is imported
inside the functions, so ``import sparsekin`` never needs it.  Figures are drawn on a
`matplotlib.figure.Figure` with the Agg canvas and written as PNG files; no pyplot state is
created or closed.
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import numpy as np

from .geometry import rotate, to_global, to_local
from .model import GROUND, Mechanism
from .results import KinematicsResult

__all__ = ["plot_point_motion", "plot_actuators", "plot_driver_forces", "draw_mechanism", "Canvas", "plot_sweep_paths",
           "plot_stop_times", "plot_workspace"]

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
#: Panels of the actuator figure: the quantity and its unit.
ACTUATOR_PANELS = (("stroke", "stroke (m)"), ("speed", "speed (m/s)"), ("acceleration", "acceleration (m/s²)"))


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
    labelled with its name (a body with one point is a short bar along its frame's x
    axis); each joint and driver draws itself as its kind declares (`Canvas`): revolute
    joints are small circles, pivots on the ground carry a hatched triangle,
    translational joints are a dashed line along their axis with a small square, and
    so on.  Every named point is labelled.

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
    figure, axes = _new_figure((8.0, 7.0))
    canvas = Canvas(axes, mechanism, result.coordinates[0], SYMBOL_SCALE * _extent(positions.values()))
    for element in (*mechanism.joints, *mechanism.drivers, *mechanism.loads):
        element.draw(canvas)
    obstacles = np.array([*positions.values(), *canvas.ground_marks]).reshape(-1, 2)
    for index, body in enumerate(mechanism.bodies):
        frame = result.coordinates[0, 3 * index : 3 * index + 3]
        _draw_body(axes, body, positions, frame, canvas.size, obstacles)
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


def _around_centroid(corners: np.ndarray) -> np.ndarray:
    """The corners ordered by angle about their centroid: a polygon that does not cross itself."""
    relative = corners - corners.mean(axis=0)
    return corners[np.argsort(np.arctan2(relative[:, 1], relative[:, 0]))]


def _extent(positions) -> float:
    """Largest side of the bounding box of `positions` (1 m when they all coincide)."""
    array = np.array(list(positions), dtype=float).reshape(-1, 2)
    extent = float(np.ptp(array, axis=0).max()) if len(array) else 0.0
    return extent if extent > 0.0 else 1.0


# ---------------------------------------------------------------------- the canvas of elements
class Canvas:
    """What an element kind draws with: positions at one configuration, and symbols.

    Each kind of `sparsekin.elements` declares ``draw(self, canvas)`` in terms of these
    methods, so that it never touches matplotlib.

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
        Where the hatched ground symbols are, for the bodies' labels to avoid.
    """

    def __init__(self, axes, mechanism: Mechanism, coordinates: np.ndarray, size: float) -> None:
        self.axes, self.size = axes, size
        self._mechanism = mechanism
        self._drawn = mechanism.frames()
        self._now = np.asarray(coordinates, dtype=float).reshape(-1, 3)
        self.ground_marks: list[np.ndarray] = []

    # ------------------------------------------------------------------ where things are
    def point(self, body: str, reference) -> np.ndarray:
        """Where the point of `body` that starts at `reference` (a name or (x, y)) is now."""
        start = np.asarray(self._mechanism.position(reference), dtype=float)
        if body == GROUND:
            return start
        index = self._mechanism.body_index(body)
        local = to_local(self._drawn[index : index + 1], start[None])
        return to_global(self._now[index : index + 1], local)[0]

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

    # ------------------------------------------------------------------ symbols
    def pin(self, position, grounded: bool) -> None:
        """A small circle; on the ground, also a hatched triangle below it."""
        from matplotlib.patches import Circle, Polygon

        x, y = position
        size = self.size
        if grounded:
            triangle = [(x, y), (x - 1.2 * size, y - 2.0 * size), (x + 1.2 * size, y - 2.0 * size)]
            self.axes.add_patch(Polygon(triangle, closed=True, facecolor="lightgray", edgecolor="black",
                                        hatch="///", linewidth=1.0, zorder=3))  # fmt: skip
            self.ground_marks.append(np.array([x, y - 1.5 * size]))
        self.axes.add_patch(Circle((x, y), 0.6 * size, facecolor="white", edgecolor="black", linewidth=1.2, zorder=4))

    def slider(self, start, end) -> None:
        """A dashed line along a sliding axis with a small square at its middle, turned with it.

        The square sits under the revolute circles, so a pin at the same place stays visible.
        """
        from matplotlib.patches import Rectangle

        self.axes.plot(*np.transpose([start, end]), linestyle="--", color="tab:green", linewidth=1.2, zorder=2)
        middle = 0.5 * (np.asarray(start) + np.asarray(end))
        angle = math.degrees(math.atan2(end[1] - start[1], end[0] - start[0]))
        self.axes.add_patch(Rectangle(middle - 0.9 * self.size, 1.8 * self.size, 1.8 * self.size, angle=angle,
                                      rotation_point="center", facecolor="white", edgecolor="tab:green",
                                      linewidth=1.5, zorder=3.5))  # fmt: skip

    def slot(self, centre, along, limits=None) -> None:
        """A slot: two parallel lines along `along` about `centre`, over `limits` (m) if given."""
        low, high = limits if limits is not None else (-6.0 * self.size, 6.0 * self.size)
        across = 0.8 * self.size * np.array([-along[1], along[0]])
        for side in (across, -across):
            ends = np.array([centre + low * along + side, centre + high * along + side])
            self.axes.plot(ends[:, 0], ends[:, 1], color="tab:green", linewidth=1.5, zorder=2)

    def weld(self, position) -> None:
        """A small filled square: two bodies welded together."""
        from matplotlib.patches import Rectangle

        self.axes.add_patch(Rectangle(np.asarray(position) - 0.5 * self.size, self.size, self.size,
                                      facecolor="black", zorder=4))  # fmt: skip

    def circle(self, centre, radius: float) -> None:
        """A dash-dotted circle: a gear's or a pinion's pitch circle."""
        from matplotlib.patches import Circle

        self.axes.add_patch(Circle(tuple(centre), radius, fill=False, edgecolor="tab:purple", linestyle="-.",
                                   linewidth=1.2, zorder=2))  # fmt: skip

    def line(self, start, end) -> None:
        """A dash-dotted line: a rack's pitch line."""
        self.axes.plot(*np.transpose([start, end]), linestyle="-.", color="tab:purple", linewidth=1.2, zorder=2)

    def actuator(self, start, end) -> None:
        """A linear actuator between two points: a thick cylinder from `start`, a thin rod to `end`."""
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        middle = start + 0.55 * (end - start)
        self.axes.plot(*np.transpose([start, middle]), color="dimgray", linewidth=6.0, solid_capstyle="butt", zorder=2)
        self.axes.plot(*np.transpose([start, end]), color="black", linewidth=2.0, zorder=2.5)

    def arrow(self, position, direction) -> None:
        """An arrow ending at `position` along `direction` (a force applied there); none for a
        zero direction."""
        direction = np.asarray(direction, dtype=float)
        length = float(np.hypot(*direction))
        if length == 0.0:
            return
        tail = np.asarray(position) - 5.0 * self.size * direction / length
        self.axes.annotate("", xy=tuple(position), xytext=tuple(tail), zorder=5,
                           arrowprops={"arrowstyle": "-|>", "color": "tab:red", "linewidth": 1.8})  # fmt: skip

    def turn(self, centre) -> None:
        """A curved arrow about `centre`: a torque."""
        from matplotlib.patches import FancyArrowPatch

        x, y = centre
        radius = 2.0 * self.size
        self.axes.add_patch(FancyArrowPatch((x + radius, y), (x, y + radius), connectionstyle="arc3,rad=0.5",
                                            arrowstyle="-|>", mutation_scale=12, color="tab:red", linewidth=1.5,
                                            zorder=5))  # fmt: skip

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
        self.axes.plot(line[:, 0], line[:, 1], color="tab:brown", linewidth=1.2, zorder=2)

    def target(self, position) -> None:
        """A cross in a circle: a point whose path is prescribed."""
        from matplotlib.patches import Circle

        x, y = position
        size = self.size
        self.axes.add_patch(Circle((x, y), 1.2 * size, fill=False, edgecolor="tab:red", linewidth=1.5, zorder=4))
        self.axes.plot([x - 1.6 * size, x + 1.6 * size], [y, y], color="tab:red", linewidth=1.0, zorder=4)
        self.axes.plot([x, x], [y - 1.6 * size, y + 1.6 * size], color="tab:red", linewidth=1.0, zorder=4)


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
    """Draw a `~sparsekin.workspaces.Workspace` into ``workspace_<point>.png``.

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
def _new_figure(size: tuple[float, float], rows: int = 1, columns: int = 1):
    """A figure on the Agg canvas and its axes (an array of `rows` stacked axes if rows > 1,
    of `columns` axes side by side if columns > 1)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=size, layout="constrained")
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
