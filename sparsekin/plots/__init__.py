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

The modules: `~sparsekin.plots.canvas` (the canvas the elements draw on),
`~sparsekin.plots.labels` (label placement), `~sparsekin.plots.configuration` (one
configuration), `~sparsekin.plots.figures` (the figures of a run),
`~sparsekin.plots.animation` (animations and frames), `~sparsekin.plots.studies` (sweeps and
workspaces), `~sparsekin.plots.metamaterials` (a lattice's size against its opening angle) and
`~sparsekin.plots.common` (the figure, its file, the optional dependencies).

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

from .animation import Animation, animate, frame_times, interpolate_coordinates, save_frame
from .canvas import Canvas
from .configuration import draw_configuration
from .figures import (
    draw_mechanism,
    plot_actuators,
    plot_driver_forces,
    plot_paths_together,
    plot_point_motion,
    plot_point_paths,
)
from .labels import Label, place_labels
from .metamaterials import LatticeSize, lattice_size, plot_lattice_size
from .studies import plot_stop_times, plot_sweep_paths, plot_workspace

__all__ = [
    "plot_point_motion",
    "plot_point_paths",
    "plot_paths_together",
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
    "LatticeSize",
    "lattice_size",
    "plot_lattice_size",
]
