"""What a run keeps, and where it goes: selections, chunks and sinks.

A run keeps what its caller asks for (`Selection`): every body's coordinates and their
derivatives (the default), the motion of named points, the own coordinates of joints.
The time loop hands each solved sample (or a block of samples, from the compiled loop) to
a `Recorder`, which fills a chunk of rows and writes every full chunk to a sink:

* `MemorySink` — arrays for every sample, in memory (the default): the recorder fills
  each chunk's rows in place there;
* `ZarrSink` — a Zarr store written chunk by chunk while the run goes on, which
  ``xarray.open_zarr`` opens as a Dataset (the ``zarr`` extra: ``pip install
  "sparsekin[zarr]"``).  Peak memory is then the model plus a chunk, whatever the number
  of samples.

Store layout (one Dataset, dimension ``time`` first):

=============  ==============================  ===========================================
variable       dimensions                      content
=============  ==============================  ===========================================
``t``          (time)                          sample times, s (a coordinate)
``q``,         (time, coordinate)              x, y, angle of every body (m, rad) and their
``qd``, ``qdd``                                derivatives; labels ``c1.x``, ``c1.angle``
``points``     (time, point, component)        x, y, vx, vy, ax, ay of each recorded point
``joints``     (time, joint, derivative)       value, rate, accel of each recorded joint's
                                               own coordinate; ``joint_quantity`` (angle,
                                               stroke, slide) and ``joint_unit`` per joint
``forces``     (time, force)                   the columns of ``forces.csv`` (drivers'
                                               forces and powers, joints' reactions),
                                               labelled like them; ``force_unit`` per
                                               column (N, N·m, W)
=============  ==============================  ===========================================
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Sequence
from contextlib import contextmanager

import numpy as np

from ..engine.forces import ForceOutputs
from ..engine.pattern import build_output_pattern, build_pattern, build_point_map, limited_elements
from ..model.elements import COORDINATE_NAMES
from ..model.geometry import carried_motion
from ..model.mechanism import Mechanism

__all__ = ["Selection", "Recorder", "MemorySink", "ZarrSink", "POINT_COMPONENTS", "JOINT_DERIVATIVES",
           "dataset_labels"]

#: The components of a recorded point, in the order they are stored.
POINT_COMPONENTS = ("x", "y", "vx", "vy", "ax", "ay")
#: The derivatives of a recorded joint coordinate.
JOINT_DERIVATIVES = ("value", "rate", "accel")
#: A chunk holds at most this many bytes of samples (and at least one sample).
CHUNK_BYTES = 64 * 2**20
#: And at most this many samples.
MAX_CHUNK_SAMPLES = 4096
_EXTRA = 'writing Zarr stores needs zarr and xarray: pip install "sparsekin[zarr]"'


class Selection:
    """What a run records.

    Parameters
    ----------
    mechanism : Mechanism
    coordinates : bool
        Keep every body's coordinates, velocities and accelerations.
    points : None, "all" or sequence of str
        Named points whose motion is recorded during the run.  (With `coordinates`, any
        point can also be derived afterwards.)
    joints : None, "all" or sequence of str or int
        Joints whose own coordinate is recorded (names, ``joints[i]`` labels or indices);
        "all": every joint that has one.
    forces : "auto", None, "all" or sequence of str
        Drivers and joints whose forces are recorded (`sparsekin.engine.forces.ForceOutputs`):
        names or ``drivers[i]`` / ``joints[i]`` labels; "all": every driver and joint;
        "auto": all when the model has a mass or a load (`Mechanism.has_forces`), else none.
    pattern : ConstraintPattern, optional
        The mechanism's, to lay out the force columns (built if needed).

    Attributes
    ----------
    forces : ForceOutputs or None
        The force columns, if any.

    Raises
    ------
    ValueError
        For an unknown point, joint or driver, or a joint without an own coordinate.
    """

    def __init__(self, mechanism: Mechanism, coordinates: bool = True, points=None, joints=None, forces=None,
                 pattern=None) -> None:  # fmt: skip
        from ..engine.outputs import element_index

        self.mechanism = mechanism
        if not isinstance(coordinates, (bool, np.bool_)):  # issue 28: "no" was true
            raise ValueError(f"`coordinates` must be True or False, got {coordinates!r}.")
        self.coordinates = bool(coordinates)
        if points is None:
            names: tuple[str, ...] = ()
        elif isinstance(points, str) and points == "all":
            names = tuple(mechanism.points)
        else:
            if isinstance(points, str) or not isinstance(points, Sequence):
                raise ValueError(f'`points` must be None, "all" or a list of point names, got {points!r}.')
            if not all(isinstance(name, str) for name in points):  # issue 28: a bare TypeError
                raise ValueError(f'`points` must be None, "all" or a list of point names, got {points!r}.')
            names = tuple(dict.fromkeys(points))
            for name in names:
                if name not in mechanism.points:
                    raise ValueError(f'`points`: unknown point "{name}".')
        self.point_names = names
        if joints is None:
            indices: list[int] = []
        elif isinstance(joints, str) and joints == "all":
            indices = [k for k, joint in enumerate(mechanism.joints) if type(joint).output_names]
        else:
            if isinstance(joints, str) or not isinstance(joints, Sequence):
                raise ValueError(f'`joints` must be None, "all" or a list of joint names, got {joints!r}.')
            try:
                indices = list(dict.fromkeys(element_index(mechanism, "joints", name) for name in joints))
            except KeyError as error:
                raise ValueError(f"`joints`: {error.args[0]}") from None
            for k in indices:
                if not type(mechanism.joints[k]).output_names:
                    raise ValueError(f"`joints`: joints[{k}] is {mechanism.joints[k].type_name}, which has no "
                                     "coordinate of its own")  # fmt: skip
        self.joint_indices = tuple(indices)
        self.joint_labels = tuple(mechanism.joints[k].name or f"joints[{k}]" for k in indices)
        self.forces = None
        drivers, joints_with_forces = _force_elements(mechanism, forces)
        if drivers or joints_with_forces:
            pattern = build_pattern(mechanism) if pattern is None else pattern
            self.forces = ForceOutputs(mechanism, pattern, drivers, joints_with_forces)

    @property
    def n_force_columns(self) -> int:
        return 0 if self.forces is None else self.forces.n_columns

    def sample_shapes(self) -> dict[str, tuple[int, ...]]:
        """The shape of one sample of each recorded variable (the time ``t`` aside)."""
        shapes = {}
        if self.coordinates:
            shapes |= dict.fromkeys(("q", "qd", "qdd"), (self.mechanism.n_coordinates,))
        if self.point_names:
            shapes["points"] = (len(self.point_names), 6)
        if self.joint_indices:
            shapes["joints"] = (len(self.joint_indices), 3)
        if self.forces is not None:
            shapes["forces"] = (self.n_force_columns,)
        return shapes

    def bytes_per_sample(self) -> int:
        return 8 * (1 + sum(int(np.prod(shape)) for shape in self.sample_shapes().values()))

    def chunk_samples(self) -> int:
        """Samples per chunk: `CHUNK_BYTES` at most, one at least."""
        return int(min(MAX_CHUNK_SAMPLES, max(1, CHUNK_BYTES // self.bytes_per_sample())))


def _force_elements(mechanism: Mechanism, forces) -> tuple[list[int], list[int]]:
    """The drivers and the joints whose forces a run records (see `Selection`)."""
    from ..engine.outputs import element_index

    if isinstance(forces, str) and forces == "auto":
        forces = "all" if mechanism.has_forces else None
    if forces is None:
        return [], []
    if isinstance(forces, str) and forces == "all":
        return list(range(mechanism.n_drivers)), list(range(mechanism.n_joints))
    if isinstance(forces, str) or not isinstance(forces, Sequence):
        raise ValueError(f'`forces` must be "auto", None, "all" or a list of driver and joint names, got {forces!r}.')
    chosen: dict[str, list[int]] = {"drivers": [], "joints": []}
    for name in forces:
        found = False
        for kind in ("drivers", "joints"):
            try:
                chosen[kind].append(element_index(mechanism, kind, name))
                found = True
            except KeyError:
                pass
        if not found:
            raise ValueError(f'`forces`: no driver or joint is called "{name}" (names, or drivers[i] / joints[i])')
    return sorted(set(chosen["drivers"])), sorted(set(chosen["joints"]))


def dataset_labels(mechanism: Mechanism, coordinates: bool, point_names, joint_indices, force_labels=(),
                   force_units=()) -> dict:  # fmt: skip
    """The coordinates (labels) of the Dataset of a run that recorded these (the layout of
    the module docstring): the same for a Zarr store and `KinematicsResult.to_xarray`."""
    labels = {}
    if coordinates:
        labels["coordinate"] = [f"{name}.{c}" for name in mechanism.body_names for c in COORDINATE_NAMES]
    if point_names:
        labels |= {"point": list(point_names), "component": list(POINT_COMPONENTS)}
    if joint_indices:
        kinds = [type(mechanism.joints[k]) for k in joint_indices]
        outputs = build_output_pattern(mechanism, joints=joint_indices)
        labels |= {
            "joint": [mechanism.joints[k].name or f"joints[{k}]" for k in joint_indices],
            "derivative": list(JOINT_DERIVATIVES),
            "joint_quantity": ("joint", [kind.output_names[0] for kind in kinds]),
            "joint_unit": ("joint", ["rad" if angle else "m" for angle in outputs.row_is_angle]),
        }
    if force_labels:
        labels |= {"force": list(force_labels), "force_unit": ("force", list(force_units))}
    return labels


class Recorder:
    """Fills chunks of rows from solved samples and writes them to a sink.

    Parameters
    ----------
    selection : Selection
    sink : MemorySink or ZarrSink
    """

    def __init__(self, selection: Selection, sink) -> None:
        self.selection, self.sink = selection, sink
        mechanism = selection.mechanism
        self.size = size = selection.chunk_samples()
        self._first = 0  # the index of the chunk's first sample
        # A memory sink's arrays hold the chunk's rows themselves (filled in place, not copied
        # again: `_chunk_rows`); for a store, the rows of one chunk.
        self._held = sink.arrays if getattr(sink, "in_place", False) else {}
        # the rows filled sample by sample; the points are computed per chunk
        self._shapes = {"t": ()} | {key: shape for key, shape in selection.sample_shapes().items() if key != "points"}
        self._chunk_rows()
        # points: the frames of the bodies that carry them, and where they sit on them
        point_map = build_point_map(mechanism)
        located = [point_map.locate(name) for name in selection.point_names]
        self._point_body = np.array([body for body, _ in located], dtype=np.int64)
        self._point_local = np.array([local for _, local in located], dtype=float).reshape(-1, 2)
        self._carriers = np.unique(self._point_body[self._point_body >= 0])
        self._frames = [np.empty((size, self._carriers.size, 3)) for _ in range(3)]
        if selection.joint_indices:
            self._outputs = build_output_pattern(mechanism, joints=selection.joint_indices)
        self._rows = 0
        self.n_written = 0
        self._failed = False  # a write to the sink failed
        self._limits = _LimitWatch(mechanism)

    def _chunk_rows(self) -> None:
        """The arrays the next chunk's rows go into: views of a memory sink's arrays from
        the chunk's first sample on, or arrays of one chunk."""
        rows = {}
        for key, shape in self._shapes.items():
            held = self._held.get(key)
            rows[key] = np.empty((self.size, *shape)) if held is None else held[self._first : self._first + self.size]
        self._t = rows["t"]
        self._q = [rows[key] for key in ("q", "qd", "qdd")] if "q" in rows else None
        self._joints, self._forces = rows.get("joints"), rows.get("forces")

    @property
    def limit_crossings(self):
        """`~sparsekin.results.kinematics.LimitState` of each element that left its ``limits``, at the
        first sample outside."""
        return self._limits.crossings

    def add(self, t: float, coordinates, velocities, accelerations, forces=None) -> None:
        """One solved sample (and its force columns, when the selection has some)."""
        self.add_block(np.array([t]), coordinates[None], velocities[None], accelerations[None],
                       None if forces is None else forces[None])  # fmt: skip

    def add_block(self, times, coordinates, velocities, accelerations, forces=None) -> None:
        """Solved samples, one per row of the arrays (the compiled loop's a block at a time):
        copied by slices, the joints' own coordinates and the limits by one kernel call."""
        self._limits.watch(times, coordinates)
        done = 0
        while done < len(times):
            row = self._rows
            m = min(self.size - row, len(times) - done)
            rows, block = slice(row, row + m), slice(done, done + m)
            self._t[rows] = times[block]
            states = (coordinates[block], velocities[block], accelerations[block])
            if self._q is not None:
                for buffer, state in zip(self._q, states):
                    buffer[rows] = state
            if self._carriers.size:
                for buffer, state in zip(self._frames, states):
                    buffer[rows] = state.reshape(m, -1, 3)[:, self._carriers]
            if self.selection.joint_indices:
                from ..engine.outputs import own_coordinates

                self._joints[rows] = np.stack(own_coordinates(self._outputs, *states), axis=2)
            if self._forces is not None:
                self._forces[rows] = forces[block]
            self._rows += m
            done += m
            if self._rows == self.size:
                self.flush()

    def flush(self) -> None:
        """Write the rows filled so far.

        A Ctrl-C during the write is taken once it is done (`_interrupt_deferred`), so
        that a store never holds a chunk twice or half of one; after a write that failed
        nothing is written again.
        """
        m = self._rows
        if m == 0 or self._failed:
            return
        data = {"t": self._t[:m]}
        if self._q is not None:
            data["q"], data["qd"], data["qdd"] = (buffer[:m] for buffer in self._q)
        if self.selection.point_names:
            data["points"] = self._point_tracks(m)
        if self.selection.joint_indices:
            data["joints"] = self._joints[:m]
        if self._forces is not None:
            data["forces"] = self._forces[:m]
        with _interrupt_deferred():  # a Ctrl-C waits for the write and its bookkeeping
            try:
                self.sink.write(self._first, data)
            except BaseException:
                self._rows = 0  # the sink's state is unknown: never write these rows again
                self._failed = True
                raise
            self._first += m
            self.n_written = self._first
            self._rows = 0
            if self._held:
                self._chunk_rows()

    def _point_tracks(self, m: int) -> np.ndarray:
        out = np.empty((m, len(self.selection.point_names), 6))
        slot = {body: k for k, body in enumerate(self._carriers.tolist())}
        for p, (body, local) in enumerate(zip(self._point_body.tolist(), self._point_local)):
            if body < 0:  # a ground point
                out[:, p, :2] = local
                out[:, p, 2:] = 0.0
                continue
            frames = [buffer[:m, slot[body]] for buffer in self._frames]
            position, velocity, acceleration = carried_motion(*frames, local)
            out[:, p, 0:2], out[:, p, 2:4], out[:, p, 4:6] = position, velocity, acceleration
        return out

    def finish(self):
        """Write what is left and close the sink; returns the sink's arrays."""
        self.flush()
        return self.sink.close(self.n_written)


#: The signals a chunk's write holds until it is done (issue 28: the command line stops on
#: SIGTERM and SIGHUP as on Ctrl-C).
_DEFERRED_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


@contextmanager
def _interrupt_deferred():
    """Hold a SIGINT (Ctrl-C), SIGTERM or SIGHUP that arrives in the block until the block
    is done, then hand it to the handler there was (which raises `KeyboardInterrupt` for
    Ctrl-C).

    Only the main thread receives signals, and only a Python handler can be called
    later: elsewhere, or for a signal under another handler, the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.getsignal(signum) for signum in _DEFERRED_SIGNALS}
    previous = {signum: handler for signum, handler in previous.items() if callable(handler)}
    received = []
    for signum in previous:
        signal.signal(signum, lambda signum, frame: received.append((signum, frame)))
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum, frame in received:
            previous[signum](signum, frame)


class _LimitWatch:
    """The elements with ``limits``: their own coordinates checked at every sample recorded."""

    def __init__(self, mechanism: Mechanism) -> None:
        self.crossings: list = []
        self.active = any(getattr(e, "limits", None) is not None
                           for kind in ("joints", "drivers") for e in mechanism.declared(kind))  # fmt: skip
        if not self.active:
            return
        self._mechanism = mechanism
        limited = limited_elements(mechanism)
        self._outputs = build_output_pattern(mechanism, joints=limited["joints"], drivers=limited["drivers"])
        self._elements = [(kind, k) for kind in ("joints", "drivers") for k in limited[kind]]
        limits = np.array([getattr(mechanism, kind)[k].limits for kind, k in self._elements], dtype=float)
        self._low, self._high = limits[:, 0], limits[:, 1]
        self._open = np.ones(len(self._elements), dtype=bool)  # not yet outside

    def watch(self, times, coordinates) -> None:
        """Samples at `times` (s) with `coordinates` (one row each): each element still
        within its limits that leaves them is recorded at its first sample outside."""
        if not self.active or not self._open.any():
            return
        from ..engine.outputs import LimitState, own_coordinates

        rest = np.zeros_like(coordinates)
        values = own_coordinates(self._outputs, coordinates, rest, rest)[0]
        outside = self._open & ((values < self._low) | (values > self._high))
        crossed = np.flatnonzero(outside.any(axis=0))
        first = outside[:, crossed].argmax(axis=0)
        for e, k in sorted(zip(crossed.tolist(), first.tolist()), key=lambda pair: pair[1]):  # in time order
            kind, index = self._elements[e]
            element = getattr(self._mechanism, kind)[index]
            quantity = type(element).output_names[0] if kind == "joints" else element.type_name
            unit = "rad" if self._outputs.row_is_angle[e] else "m"
            self.crossings.append(LimitState(self._mechanism.element_label(kind, index), quantity, unit,
                                             float(values[k, e]), element.limits, float(times[k]), False))  # fmt: skip
        self._open[crossed] = False


#: What the top of a Zarr store holds: a format 2 group or array (and its consolidated
#: metadata), or format 3's metadata.
_ZARR_MARKERS = (".zgroup", ".zarray", ".zmetadata", "zarr.json")


def _clear_store(path: str) -> None:
    """Empty the Zarr store at `path`, if there is one; refuse to touch anything else."""
    if not os.path.lexists(path):
        return
    if not os.path.isdir(path):
        raise ValueError(f"`store` {path!r} is a file, not a Zarr store; give a new path or a Zarr store to "
                         "replace.")  # fmt: skip
    with os.scandir(path) as scan:
        entries = list(scan)
    if entries and not any(entry.name in _ZARR_MARKERS for entry in entries):
        raise ValueError(f"`store` {path!r} is a folder that is not a Zarr store and not empty; give a new "
                         "path, an empty folder or a Zarr store to replace.")  # fmt: skip
    import shutil

    for entry in entries:
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(entry.path)
        else:
            os.remove(entry.path)


def _partial_path(path: str) -> str:
    """Where a store is built before it is renamed to `path`: a hidden name beside it."""
    head, name = os.path.split(os.path.normpath(path))
    return os.path.join(head, f".{name}.{os.getpid()}.partial")


def _resize_time(path: str, n_times: int) -> None:
    """Lay the variables of the store at `path` over `n_times` samples (their first
    dimension, ``time``) and consolidate its metadata again."""
    import zarr

    group = zarr.open_group(path, mode="r+", zarr_format=2)
    for _, array in group.arrays():
        if array.attrs.get("_ARRAY_DIMENSIONS", [None])[0] == "time" and array.shape[0] != n_times:
            array.resize((n_times, *array.shape[1:]))
    zarr.consolidate_metadata(path, zarr_format=2)


class MemorySink:
    """Arrays for every sample of a run, in memory: a `Recorder` fills them in place (the
    rows it hands to `write` that are views of them are not copied again)."""

    #: A `Recorder` fills the rows of `arrays` in place.
    in_place = True

    def __init__(self, selection: Selection, n_times: int) -> None:
        self.arrays = {"t": np.empty(n_times)} | {
            key: np.empty((n_times, *shape)) for key, shape in selection.sample_shapes().items()
        }

    def write(self, first: int, data: dict) -> None:
        for key, values in data.items():
            array = self.arrays[key]
            if values.base is not array:  # else the recorder has filled these rows in place
                array[first : first + len(values)] = values

    def close(self, n_written: int) -> dict:
        return {key: array[:n_written] for key, array in self.arrays.items()}


class ZarrSink:
    """A Zarr store at `path`, written chunk by chunk (see the module docstring).

    With `n_times`, the store holds every sample's row from its first write on, so that
    a run killed at any moment (even by SIGKILL) leaves a store that opens, with ``t`` and
    every variable and the same number of samples in each: the store is built at a
    temporary name with the first chunk, its variables laid out over the `n_times`
    samples (metadata only; the rows not yet written read as NaN, ``t`` too), and renamed
    into place; each later chunk fills its rows, ``t`` last, so that a sample whose time
    is written is whole.  `close` cuts the variables to the samples written.  Without
    `n_times`, each chunk is appended (a kill between two variables' appends leaves them
    of different lengths).

    Parameters
    ----------
    path : str or path-like
        The store (a folder).  A Zarr store there is replaced: cleared here, before the
        run, so that no old sample outlives it; a file or a folder holding anything else
        is refused.
    selection : Selection
    n_times : int, optional
        The samples of the run.

    Raises
    ------
    ValueError
        If `path` is a file, or a non-empty folder that is not a Zarr store.
    """

    def __init__(self, path, selection: Selection, n_times: int | None = None) -> None:
        try:
            import xarray  # noqa: F401
            import zarr  # noqa: F401
        except ImportError:
            raise ImportError(_EXTRA) from None
        self.path = os.fspath(path)
        self.selection = selection
        self.n_times = n_times
        self._written = False
        _clear_store(self.path)
        if n_times is not None and os.path.isdir(self.path):  # emptied: the store is renamed there whole
            os.rmdir(self.path)

    def _dataset(self, data: dict, with_labels: bool):
        import xarray as xr

        dims = {"q": ("time", "coordinate"), "qd": ("time", "coordinate"), "qdd": ("time", "coordinate"),
                "points": ("time", "point", "component"), "joints": ("time", "joint", "derivative"),
                "forces": ("time", "force")}  # fmt: skip
        variables = {key: (dims[key], values) for key, values in data.items() if key != "t"}
        coords = {"t": ("time", data["t"])}
        if with_labels:
            selection = self.selection
            forces = selection.forces
            coords |= dataset_labels(selection.mechanism, selection.coordinates, selection.point_names,
                                     selection.joint_indices, () if forces is None else forces.labels,
                                     () if forces is None else forces.units)  # fmt: skip
        return xr.Dataset(variables, coords=coords)

    def write(self, first: int, data: dict) -> None:
        import warnings

        if not self._written:
            self._create(data, self.n_times)
            self._written = True
            return
        if self.n_times is None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", FutureWarning)
                self._dataset(data, with_labels=False).to_zarr(self.path, append_dim="time", zarr_format=2)
            return
        import zarr

        group = zarr.open_group(self.path, mode="r+", zarr_format=2)
        for key in (*(key for key in data if key != "t"), "t"):  # the time last: its sample is whole
            group[key][first : first + len(data[key])] = data[key]

    def _create(self, data: dict, n_times: int | None) -> None:
        """Write the store with the first chunk and the labels: at a temporary name, laid out
        over `n_times` samples, then renamed into place (see the class docstring)."""
        import warnings

        n = self.selection.mechanism.n_coordinates
        rows = max(1, len(data["t"]))
        encoding = {key: {"chunks": (rows, *(min(size, 2**20) for size in values.shape[1:]))}
                    for key, values in data.items()}  # fmt: skip
        encoding |= {key: {"chunks": (rows, min(n, 2**20))} for key in ("q", "qd", "qdd") if key in data}
        target = self.path if n_times is None else _partial_path(self.path)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", FutureWarning)
                self._dataset(data, with_labels=True).to_zarr(target, mode="w", zarr_format=2, encoding=encoding)
            if n_times is not None:
                _resize_time(target, n_times)
                os.replace(target, self.path)  # onto a new name: the store appears whole
        except BaseException:
            if target != self.path:
                import shutil

                shutil.rmtree(target, ignore_errors=True)
            raise

    def close(self, n_written: int) -> dict:
        """The store's arrays, read lazily (zarr arrays), cut to the `n_written` samples."""
        import zarr

        if not self._written:  # nothing solved: an empty store with the labels
            self._create({"t": np.empty(0), **self._empty()}, None)
            self._written = True
        elif self.n_times is not None and n_written < self.n_times:
            _resize_time(self.path, n_written)
        group = zarr.open_group(self.path, mode="r")
        return {key: group[key] for key in ("t", "q", "qd", "qdd", "points", "joints", "forces") if key in group}

    def _empty(self) -> dict:
        selection = self.selection
        n = selection.mechanism.n_coordinates
        data = {}
        if selection.coordinates:
            data |= {key: np.empty((0, n)) for key in ("q", "qd", "qdd")}
        if selection.point_names:
            data["points"] = np.empty((0, len(selection.point_names), 6))
        if selection.joint_indices:
            data["joints"] = np.empty((0, len(selection.joint_indices), 3))
        if selection.forces is not None:
            data["forces"] = np.empty((0, selection.n_force_columns))
        return data
