"""Figures of a kinematic analysis: point motion, point paths, actuators, driver forces and
the mechanism drawn at a few times."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..engine.outputs import element_index
from ..engine.pattern import build_output_pattern
from ..model.mechanism import Mechanism
from ..results.kinematics import KinematicsResult
from .common import _dress, _file_safe, _new_figure, _save
from .configuration import draw_configuration

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
#: Paths in one figure up to this many have a legend.
LEGEND_ENTRIES = 12
#: Time marks along a path figure: the path is split into this many equal time intervals.
PATH_TIME_MARKS = 10


def plot_point_motion(result: KinematicsResult, point_names, directory, *, abscissa: str | None = None) -> list[Path]:
    """Plot the position, velocity and acceleration of points against time, x and y.

    Parameters
    ----------
    result : KinematicsResult
        The analysis to plot.
    point_names : sequence of str
        The points, one figure each.
    directory : str or Path
        Existing folder where the files ``point_<name>.png`` are written.
    abscissa : str, optional
        A driver (its name or ``"drivers[i]"``): plot against the value it drives (a crank
        angle, in degrees for an angle; a stroke, m) instead of time.

    Returns
    -------
    list of Path
        The files written, in the order of `point_names`.
    """
    axis = _abscissa(result, abscissa)
    return [_plot_one_point(result, name, Path(directory), axis) for name in point_names]


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


def plot_paths_together(result: KinematicsResult, point_names, path) -> Path:
    """Plot the paths of several points in one figure, y against x (equal scales): a
    coupler curve beside the others, every foot of a walking machine.

    Each path has its colour, its start marked by a circle; written to `path` (PNG).

    Returns
    -------
    Path
        The file written.
    """
    figure, axes = _new_figure((7.0, 6.0))
    for k, name in enumerate(point_names):
        position = result.point(name).position
        colour = f"C{k % 10}"
        axes.plot(position[:, 0], position[:, 1], color=colour, linewidth=1.3, label=name)
        axes.plot(*position[0], "o", color=colour, markersize=5)
    axes.set_aspect("equal", adjustable="datalim")
    axes.margins(0.1)
    axes.grid(True, alpha=0.4)
    if len(point_names) <= LEGEND_ENTRIES:
        axes.legend(loc="best", fontsize=8)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(f"paths of {len(point_names)} points (circles: t = {result.times[0]:g} s)")
    return _save(figure, Path(path))


def draw_mechanism(mechanism: Mechanism, result: KinematicsResult, directory, *, bodies=None,
                   labels: bool | str = True) -> Path:  # fmt: skip
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
    labels : {"all", "joints", "none"} or bool
        What is labelled (`draw_configuration`).

    Returns
    -------
    Path
        The file written.
    """
    figure, axes = _new_figure((8.0, 7.0))
    _dress(axes, f"{mechanism.name} at t = {result.times[0]:g} s")
    draw_configuration(axes, mechanism, result.coordinates[0], bodies=bodies, labels=labels)
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


def _abscissa(result: KinematicsResult, driver: str | None) -> tuple[np.ndarray, str]:
    """The values along the x axis of a motion figure and their label: time, or a driver's value."""
    if driver is None:
        return result.times, "time t (s)"
    index = element_index(result.mechanism, "drivers", driver)
    value = result.driver(index).value
    if build_output_pattern(result.mechanism, drivers=[index]).row_is_angle[0]:
        return np.degrees(value), f"{driver} (degrees)"
    return value, f"{driver} (m)"


def _plot_one_point(result: KinematicsResult, name: str, directory: Path, abscissa=None) -> Path:
    motion = result.point(name)
    along, along_label = abscissa if abscissa is not None else (result.times, "time t (s)")
    figure, panels = _new_figure((7.0, 8.0), rows=3)
    for axes, (field_name, quantity, label) in zip(panels, MOTION_PANELS):
        values = getattr(motion, field_name)
        for column, component in enumerate(COMPONENT_COLOURS):
            axes.plot(along, values[:, column], color=COMPONENT_COLOURS[component], linewidth=1.5,
                      label=component)  # fmt: skip
        axes.set_title(f"Point {name}: {quantity}")
        axes.set_ylabel(label)
        axes.grid(True, alpha=0.4)
    panels[0].legend(loc="best", fontsize=9)
    panels[-1].set_xlabel(along_label)
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
