"""What the commands write: ``points.csv``, ``joints.csv``, ``forces.csv``,
``coordinates.npz``, the workspace's CSV files and ``run``'s figures; every CSV file through
`write_csv`, every float by `repr`."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..model.mechanism import Mechanism
from ..results import schema
from ..results.kinematics import KinematicsResult
from ..results.schema import result_arrays
from .common import report
from .settings import RunSettings

#: ``--plot`` draws at most this many bodies (the first) in ``mechanism.png``: more make no
#: readable picture (a 1000-body chain took 8.2 s to draw: `sparsekin.plots.labels.MAX_PLACED_LABELS`).
MAX_DRAWN_BODIES = 100
#: Columns of ``points.csv`` for each output point, after the point name and a dot.
POINT_COLUMNS = ("x", "y", "vx", "vy", "ax", "ay")


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Iterable[str]]) -> Path:
    """Write a CSV file: the column names of `header`, then each row of `rows`, its cells
    already written as text."""
    with naming_errors(path), open(path, "w", encoding="utf-8", newline="") as file:
        file.write(",".join(header) + "\n")
        file.writelines(",".join(row) + "\n" for row in rows)
    return path


@contextmanager
def naming_errors(path: Path) -> Iterator[None]:
    """An `OSError` in the block (a full disk while writing, which names no file) names `path`."""
    try:
        yield
    except OSError as error:
        if error.filename is not None:
            raise
        raise OSError(error.errno, error.strerror or str(error), str(path)) from error


def _float_rows(table: np.ndarray) -> Iterator[Iterable[str]]:
    """The rows of a 2-d table, every float by `repr`: the shortest decimal that reads back
    as the same double."""
    return (map(repr, row) for row in table.tolist())


def write_workspace(space, directory: Path) -> list[Path]:
    """Write ``workspace.csv`` (``a``, ``b``, ``status``, ``P.x``, ``P.y`` per grid point, a
    the first driver's value) and ``boundary.csv`` (``a``, ``b``, ``P.x``, ``P.y``)."""
    a_label, b_label = (label.split(" ", 1)[0] for label in space.drivers)
    point = (f"{space.point}.x", f"{space.point}.y")
    grid = (
        (repr(a), repr(b), str(space.status[j, i]), *map(repr, space.positions[j, i].tolist()))
        for j, b in enumerate(space.values[1].tolist())
        for i, a in enumerate(space.values[0].tolist())
    )
    boundary = _float_rows(np.column_stack([space.boundary, space.boundary_positions]).reshape(-1, 4))
    return [
        write_csv(directory / "workspace.csv", (a_label, b_label, "status", *point), grid),
        write_csv(directory / "boundary.csv", (a_label, b_label, *point), boundary),
    ]


def write_outputs(mechanism: Mechanism, result: KinematicsResult | None, settings: RunSettings,
                  directory: Path | None = None, written: list[Path] | None = None) -> list[Path]:
    """Write ``points.csv``, ``joints.csv``, ``coordinates.npz`` and, if asked and possible, the figures.

    Parameters
    ----------
    mechanism : Mechanism
    result : KinematicsResult or None
        The samples solved; None or empty after an early failure (then the files hold no
        rows and no figure is drawn).
    settings : RunSettings
    directory : Path, optional
        Where the files are written (`OutputFolder.staging`); ``settings.directory`` by
        default.  A Zarr store is not written here: the run streamed it.
    written : list of Path, optional
        Each file is appended once it is complete (so that, when a later one fails, the
        caller knows which are whole).

    Returns
    -------
    list of Path
        The files written (`written`).
    """
    directory = settings.directory if directory is None else directory
    written = [] if written is None else written
    if settings.format == "csv":
        written.append(write_points_csv(result, settings.point_names, directory / "points.csv"))
        written.append(write_joints_csv(mechanism, result, directory / "joints.csv", settings.joint_indices))
        if settings.forces is not None:
            written.append(write_forces_csv(result, directory / "forces.csv"))
        if settings.coordinates:
            written.append(write_coordinates(result, mechanism.body_names, directory / "coordinates.npz"))
    if getattr(result, "energy", None) is not None:  # a forward-dynamics run
        written.append(write_energy_csv(result, directory / "energy.csv"))
    if settings.plot and count_samples(result) > 0:
        from ..plots import (
            draw_mechanism,
            plot_actuators,
            plot_driver_forces,
            plot_paths_together,
            plot_point_motion,
            plot_point_paths,
        )

        written += plot_point_motion(result, settings.point_names, directory, abscissa=settings.abscissa)
        written += plot_point_paths(result, settings.point_names, directory)
        if len(settings.point_names) > 1:
            written.append(plot_paths_together(result, settings.point_names, directory / "paths.png"))
        written += plot_driver_forces(result, directory)  # from the recorded forces, without the coordinates
        if result.coordinates is None:
            report("note: actuators.png and mechanism.png need every body's coordinates: give --coordinates")
            return written
        written += plot_actuators(result, directory)
        shown = None
        if mechanism.n_bodies > MAX_DRAWN_BODIES:
            shown = [mechanism.body_names[k] for k in range(MAX_DRAWN_BODIES)]
            report(f"note: mechanism.png shows the first {MAX_DRAWN_BODIES} of {mechanism.n_bodies} bodies")
        written.append(draw_mechanism(mechanism, result, directory, bodies=shown, labels=settings.labels))
    return written


def planned_files(mechanism: Mechanism, settings: RunSettings) -> list[str]:
    """The names of the files (or the store) `write_outputs` writes for `settings`, figures aside."""
    if settings.format == "zarr":
        return ["results.zarr"]
    names = ["points.csv", "joints.csv"]
    if settings.forces is not None:
        names.append("forces.csv")
    if settings.coordinates:
        names.append("coordinates.npz")
    return names


def write_points_csv(result: KinematicsResult | None, point_names: Sequence[str], path: Path) -> Path:
    """Write time, position, velocity and acceleration of each point, every float by `repr`.

    The header is ``t,A.x,A.y,A.vx,A.vy,A.ax,A.ay,J.x,...``; `repr` writes the shortest
    decimal that reads back as the same double.
    """
    header = ["t", *(f"{name}.{column}" for name in point_names for column in POINT_COLUMNS)]
    return write_csv(path, header, _float_rows(point_table(result, point_names)))


def point_table(result: KinematicsResult | None, point_names: Sequence[str]) -> np.ndarray:
    """The rows of ``points.csv``: shape (n_times, 1 + 6 * n_points), zero rows for None."""
    if result is None:
        return np.empty((0, 1 + len(POINT_COLUMNS) * len(point_names)))
    columns = [result.times[:, np.newaxis]]
    for name in point_names:
        columns.extend(result.point(name))  # position, velocity, acceleration: (n_times, 2) each
    return np.hstack(columns)


def joint_columns(mechanism: Mechanism, indices=None) -> list[tuple[int, str, tuple[str, ...]]]:
    """The joints of ``joints.csv``, in model order: (index, label, column suffixes).

    The joints of `indices`, by default every joint whose kind has an own coordinate;
    labelled by its name, else ``joints[i]``.
    """
    if indices is None:
        indices = [index for index, joint in enumerate(mechanism.joints) if type(joint).output_names]
    joints = mechanism.joints
    return [(index, joints[index].name or f"joints[{index}]", type(joints[index]).output_names) for index in indices]


def write_joints_csv(mechanism: Mechanism, result: KinematicsResult | None, path: Path, indices=None) -> Path:
    """Write time and each joint's own coordinate with its two derivatives, every float by `repr`.

    The header is ``t,pivot.angle,pivot.rate,pivot.accel,guide.stroke,...``; the joints
    of `indices` (default: every joint with an own coordinate).
    """
    joints = joint_columns(mechanism, indices)
    header = ["t", *(f"{label}.{suffix}" for _, label, suffixes in joints for suffix in suffixes)]
    if result is None:
        table = np.empty((0, 1 + 3 * len(joints)))
    else:
        table = np.column_stack([result.times, *(array for index, _, _ in joints for array in result.joint(index))])
    return write_csv(path, header, _float_rows(table))


def write_forces_csv(result: KinematicsResult | None, path: Path) -> Path:
    """Write time and the force columns the run recorded, every float by `repr`.

    The header is ``t,motor.force,motor.power,pivot.fx,pivot.fy,...``
    (`sparsekin.engine.force_columns.ForceOutputs`).  A model with masses or loads but no driver or
    joint has no force column: the column ``t`` alone, as ``joints.csv`` without joints;
    for None, the header alone.
    """
    labels = () if result is None else result.force_labels
    if result is None:
        table = np.empty((0, 1 + len(labels)))
    elif result.force_tracks is None:
        table = result.times[:, np.newaxis]
    else:
        table = np.column_stack([result.times, result.force_tracks])
    return write_csv(path, ["t", *labels], _float_rows(table))


def write_energy_csv(result, path: Path) -> Path:
    """Write time, energy and drift of a forward-dynamics run (`sparsekin.results.dynamics.Energy`)."""
    from ..results.dynamics import ENERGY_COLUMNS

    energy = result.energy
    table = np.column_stack([result.times, *(getattr(energy, name) for name, _ in ENERGY_COLUMNS)])
    return write_csv(path, ["t", *(name for name, _ in ENERGY_COLUMNS)], _float_rows(table))


def write_coordinates(result: KinematicsResult | None, body_names: Sequence[str], path: Path) -> Path:
    """Write arrays ``t``, ``q``, ``qd``, ``qdd`` (n_times × 3·n_bodies) and ``body_names``."""
    names = [v.name for v in schema.COORDINATE_VARIABLES]
    if result is None or result.coordinates is None:
        arrays = {schema.TIME: np.empty(0)} | dict.fromkeys(names, np.empty((0, 3 * len(body_names))))
    else:
        arrays = {schema.TIME: result.times} | {name: result_arrays(result)[name] for name in names}
    with naming_errors(path), open(path, "wb") as file:
        np.savez(file, **arrays, body_names=np.array(body_names, dtype=str))
    return path


def count_samples(result: KinematicsResult | None) -> int:
    """The samples of `result`; 0 for None."""
    return 0 if result is None else result.n_times
