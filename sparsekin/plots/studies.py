"""Figures of the studies: a point's path over a sweep's variants, the stop times, a workspace."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .common import _file_safe, _new_figure, _save

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
