"""Where a sweep's results go and what comes back: the layout of its arrays and their labels,
the output in memory or in a Zarr store written task by task, `SweepResult` and
``variants.csv``."""

from __future__ import annotations

import csv
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..results import schema
from ..results.motion import Motion
from ..results.recording import _clear_store, _partial_path
from .variants import VariantDesign, VariantSet

#: A variant's outcome: every sample solved; stopped at a singular configuration (a lock-up,
#: a dead centre); stopped because Newton failed otherwise; no mechanism could be analysed
#: with its values (a `ModelError` when it was built or at its first sample).
STATUSES = ("complete", "singular", "no_convergence", "invalid")
#: Most bytes of one chunk of the Zarr store.
CHUNK_BYTES = 64 * 2**20
#: The dtype of the statuses (as long as the longest).
STATUS_DTYPE = f"<U{max(map(len, STATUSES))}"


@dataclass(frozen=True, eq=False)
class SweepResult:
    """What a sweep computed: each variant's values, status and recorded motion.

    Attributes
    ----------
    variants : VariantSet
    columns : tuple of str
        Labels of the columns of `parameters` (the varied numbers; ``deviation.P.x`` ...
        for a tolerance study).
    parameters : ndarray, shape (n_variants, n_columns)
    status : ndarray of str, shape (n_variants,)
        One of `STATUSES` per variant.
    t_stop : ndarray, shape (n_variants,)
        Time of each variant's last solved sample, s (NaN if none was solved).
    t_failure : ndarray, shape (n_variants,)
        For a variant that stopped: the first time it could not reach, s (the lock-up lies
        between `t_stop` and it); NaN otherwise.
    messages : tuple of str
        Why each variant stopped, and any warning (limits left); empty when none.
    times : ndarray, shape (n_times,)
        Sample times, s.
    coordinates, velocities, accelerations : array, shape (n_variants, n_times, n_coordinates) or None
        q, qd, qdd of every variant (NaN after its last solved sample): numpy arrays, or
        zarr arrays read lazily from `store`.
    point_tracks : array, shape (n_variants, n_times, n_points, 6) or None
        x, y, vx, vy, ax, ay of each recorded point, m, m/s, m/s².
    recorded_points : tuple of str
    joint_tracks : array, shape (n_variants, n_times, n_joints, 3) or None
        Each recorded joint's own coordinate, rate and acceleration.
    recorded_joints : tuple of str
        Their labels (name, else ``joints[i]``).
    force_tracks : array, shape (n_variants, n_times, n_force_columns) or None
        The forces each variant recorded (`sparsekin.engine.forces`), columns `force_labels`.
    force_labels, force_units : tuple of str
    energy_tracks : array, shape (n_variants, n_times, 6) or None
        Forward dynamics: each variant's energy balance (the terms of
        `sparsekin.results.schema.ENERGY_TERMS`, J), as a run's ``energy.csv``.
    drift_tracks : array, shape (n_variants, n_times, 2) or None
        Forward dynamics: each variant's constraint drift, ‖Φ‖ and ‖Φq q̇ + Φt‖.
    analysis : str
        ``"kinematics"`` or ``"dynamics"``: what each variant's run was.
    store : str or None
        The Zarr store, when the results were written to one.
    n_tasks : int
        How many Dask tasks the variants were split into.
    wall_time : float
        Seconds from the first task submitted to the last result written.
    coordinate_labels : tuple of str
        ``c1.x``, ``c1.y``, ``c1.angle``, ...: the columns of `coordinates`.
    labels : dict
        The labels of the dimensions of `to_xarray`'s Dataset, those of a run's
        (`sparsekin.results.schema.dataset_labels`).
    motion : Motion or None
        The same recorded motion with the accessors of a run's result
        (`sparsekin.results.motion.Motion`: ``motion.point("K").velocity``,
        ``motion.driver_force("motor").force``, ``motion.joint("boom")``), every array with
        the variant first, shape (n_variants, n_times, ...), NaN after a variant's last
        solved sample.  When the sweep varies the geometry it holds the recorded points,
        joints and forces only (no one drawing to derive others from the coordinates).
    """

    variants: VariantSet
    columns: tuple[str, ...]
    parameters: np.ndarray
    status: np.ndarray
    t_stop: np.ndarray
    t_failure: np.ndarray
    messages: tuple[str, ...]
    times: np.ndarray
    coordinates: object = None
    velocities: object = None
    accelerations: object = None
    point_tracks: object = None
    recorded_points: tuple[str, ...] = ()
    joint_tracks: object = None
    recorded_joints: tuple[str, ...] = ()
    force_tracks: object = None
    force_labels: tuple[str, ...] = ()
    force_units: tuple[str, ...] = ()
    energy_tracks: object = None
    drift_tracks: object = None
    analysis: str = "kinematics"
    store: str | None = None
    n_tasks: int = 0
    wall_time: float = 0.0
    coordinate_labels: tuple[str, ...] = ()
    labels: dict = field(default_factory=dict, repr=False)
    motion: Motion | None = field(default=None, repr=False)

    @property
    def n_variants(self) -> int:
        return int(self.status.size)

    @property
    def counts(self) -> dict[str, int]:
        """How many variants ended with each status."""
        return {status: int(np.count_nonzero(self.status == status)) for status in STATUSES}

    @property
    def energy_error(self) -> np.ndarray | None:
        """Forward dynamics: each variant's largest energy error over its solved samples,
        the largest absolute value of its ``balance``, J, shape (n_variants,) (NaN when none was
        solved); None otherwise."""
        if self.energy_tracks is None:
            return None
        balance = np.abs(np.asarray(self.energy_tracks[..., schema.ENERGY_TERMS.index("balance")]))
        solved = ~np.isnan(balance)
        return np.where(solved.any(axis=1), np.max(np.where(solved, balance, -np.inf), axis=1, initial=-np.inf), np.nan)

    def point(self, name: str) -> np.ndarray:
        """Position of recorded point `name` for every variant, shape (n_variants, n_times, 2), m."""
        if name not in self.recorded_points:
            raise KeyError(
                f'point "{name}" was not recorded (recorded: {", ".join(self.recorded_points) or "none"})'
            )
        p = self.recorded_points.index(name)
        return np.asarray(self.point_tracks[..., p, :2])

    def to_xarray(self):
        """The results as an `xarray.Dataset` (the layout of the store: see `sweep`)."""
        import xarray as xr

        if self.store is not None:
            return xr.open_zarr(self.store)
        arrays = {key: np.asarray(value) for key, value in self._arrays().items()}
        shapes = {key: array.shape[2:] for key, array in arrays.items()}
        layout = _Layout(self.n_variants, self.times, self.columns, self.parameters, shapes, self.labels)
        return layout.dataset(arrays, self.status, self.t_stop, self.t_failure)

    def _arrays(self) -> dict:
        return schema.result_arrays(self)


def write_variants_csv(result: SweepResult, path) -> Path:
    """Write ``variants.csv``: ``variant``, the columns of `result.parameters`, ``status``,
    ``t_stop``, ``t_failure``, for forward dynamics ``energy_error`` (J,
    `SweepResult.energy_error`), and ``message``; numbers by `repr` (the shortest decimal
    that reads back as the same double), NaN as ``nan``."""
    path = Path(path)
    energy_error = result.energy_error
    extra = [] if energy_error is None else ["energy_error"]
    with open(path, "w", encoding="utf-8", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["variant", *result.columns, "status", "t_stop", "t_failure", *extra, "message"])
        for k in range(result.n_variants):
            values = [] if energy_error is None else [repr(float(energy_error[k]))]
            writer.writerow([k, *map(repr, result.parameters[k].tolist()), result.status[k],
                             repr(float(result.t_stop[k])), repr(float(result.t_failure[k])), *values,
                             result.messages[k]])  # fmt: skip
    return path


class _MemoryOutput:
    """Every variant's arrays in this process."""

    def __init__(self, layout: _Layout) -> None:
        self.arrays = {key: np.full((layout.n_variants, layout.times.size, *shape), np.nan)
                       for key, shape in layout.shapes.items()}  # fmt: skip
        self.path = None

    def write(self, first: int, stop: int, block: dict) -> None:
        for key, array in self.arrays.items():
            array[first:stop] = block[key]

    def close(self) -> dict:
        return self.arrays


class _ZarrOutput:
    """A Zarr store laid out in full first (metadata only), then written task by task: a
    task's variants are whole chunks, so each write replaces chunks and a task run twice
    (after a lost worker) writes the same values again."""

    def __init__(self, path, layout: _Layout, variants_per_task: int, attrs: dict) -> None:
        import dask.array as da
        import zarr

        self.path = os.fspath(path)
        lazy, encoding = {}, {}
        n_times = layout.times.size
        for key, shape in layout.shapes.items():
            inner = tuple(min(size, 2**20) for size in shape)
            per_sample = 8 * max(1, int(np.prod(inner)))
            time_chunk = int(min(n_times, max(1, CHUNK_BYTES // (variants_per_task * per_sample))))
            chunks = (variants_per_task, time_chunk, *inner)
            lazy[key] = da.full((layout.n_variants, n_times, *shape), np.nan, chunks=chunks)
            encoding[key] = {"chunks": chunks}
        n = layout.n_variants
        dataset = layout.dataset(
            lazy, np.full(n, "", dtype=STATUS_DTYPE), np.full(n, np.nan), np.full(n, np.nan)
        )
        dataset.attrs.update(attrs)
        for key in ("status", "t_stop", "t_failure"):
            encoding[key] = {"chunks": (variants_per_task,)}
        # built at a temporary name and renamed into place (issue 28): a sweep killed at any
        # moment leaves no store, or one with every variable
        _clear_store(self.path)  # a file, or a folder that is no store, is refused before any work
        target = _partial_path(self.path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            dataset.to_zarr(target, mode="w", compute=False, zarr_format=2, encoding=encoding)
        group = zarr.open_group(target, mode="r+", zarr_format=2)
        group["status"][:] = np.full(n, "", dtype=STATUS_DTYPE)  # not written with compute=False
        os.replace(target, self.path)  # onto the emptied folder, or a new name
        self.group = zarr.open_group(self.path, mode="r+", zarr_format=2)

    def write(self, first: int, stop: int, block: dict) -> None:
        for key in (*(v.name for v in schema.VARIABLES), "status", "t_stop", "t_failure"):
            if key in self.group and key in block:
                self.group[key][first:stop] = block[key]

    def close(self) -> dict:
        import zarr

        group = zarr.open_group(self.path, mode="r", zarr_format=2)
        return {v.name: group[v.name] for v in schema.VARIABLES if v.name in group}


@dataclass(frozen=True, eq=False)
class _Layout:
    """The shape and labels of a sweep's results."""

    n_variants: int
    times: np.ndarray
    columns: tuple[str, ...]
    parameters: np.ndarray
    shapes: dict
    labels: dict

    def dataset(self, arrays: dict, status, t_stop, t_failure):
        """The sweep's `xarray.Dataset` (see `sweep`)."""
        import xarray as xr

        coords = {"variant": np.arange(self.n_variants), schema.TIME: ("time", self.times),
                  "parameter": list(self.columns), **self.labels}  # fmt: skip
        variables = schema.dataset_variables(arrays, leading=("variant", "time"))
        variables |= {
            "parameters": (("variant", "parameter"), self.parameters),
            "status": ("variant", status),
            "t_stop": ("variant", t_stop),
            "t_failure": ("variant", t_failure),
        }
        return xr.Dataset(variables, coords=coords)


def _layout(design: VariantDesign, times: np.ndarray, selection) -> _Layout:
    """The arrays and labels of the sweep's results: the labels of one run's
    (`sparsekin.results.schema.dataset_labels`), with the variant and parameter dimensions in front."""
    columns, parameters = design.table()
    labels = schema.dataset_labels(selection)
    return _Layout(design.n_variants, times, columns, parameters, selection.sample_shapes(), labels)
