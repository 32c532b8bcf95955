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

The store holds one Dataset, dimension ``time`` first, laid out by the table of recorded
variables (`sparsekin.results.schema`).
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Sequence
from contextlib import contextmanager

import numpy as np

from ..engine.discretization import Discretization
from ..engine.force_columns import ForceOutputs
from ..model.mechanism import Mechanism
from . import schema
from .schema import JOINT_DERIVATIVES, POINT_COMPONENTS, TIME

__all__ = ["Selection", "Recorder", "MemorySink", "ZarrSink", "open_recorder", "POINT_COMPONENTS", "JOINT_DERIVATIVES"]

#: A chunk holds at most this many bytes of samples (and at least one sample).
CHUNK_BYTES = 64 * 2**20
#: And at most this many samples.
MAX_CHUNK_SAMPLES = 4096
_EXTRA = 'writing Zarr stores needs zarr and xarray: pip install "sparsekin[zarr]"'


class Selection:
    """What a run records.

    Parameters
    ----------
    discretization : Discretization
        The mechanism's arrays (`sparsekin.engine.discretization.discretize`).
    coordinates : bool
        Keep every body's coordinates, velocities and accelerations.
    points : None, "all" or sequence of str
        Named points whose motion is recorded during the run.  (With `coordinates`, any
        point can also be derived afterwards.)
    joints : None, "all" or sequence of str or int
        Joints whose own coordinate is recorded (names, ``joints[i]`` labels or indices);
        "all": every joint that has one.
    forces : "auto", None, "all" or sequence of str
        Drivers and joints whose forces are recorded (`sparsekin.engine.force_columns.ForceOutputs`):
        names or ``drivers[i]`` / ``joints[i]`` labels; "all": every driver and joint;
        "auto": all when the model has a mass or a load (`Mechanism.has_forces`), else none.
    energy : bool
        Record the energy balance and the constraint drift of each sample (forward
        dynamics: `sparsekin.results.schema` variables ``energy`` and ``drift``).

    Attributes
    ----------
    forces : ForceOutputs or None
        The force columns, if any.
    records_energy : bool
        `energy`.

    Raises
    ------
    ValueError
        For an unknown point, joint or driver, or a joint without an own coordinate.
    """

    def __init__(self, discretization: Discretization, coordinates: bool = True, points=None, joints=None,
                 forces=None, *, energy: bool = False) -> None:  # fmt: skip
        from ..engine.outputs import element_index

        self.discretization = discretization
        self.mechanism = mechanism = discretization.mechanism
        self.coordinates = bool(coordinates)
        self.records_energy = bool(energy)
        if points is None:
            names: tuple[str, ...] = ()
        elif isinstance(points, str) and points == "all":
            names = tuple(mechanism.points)
        else:
            if isinstance(points, str) or not isinstance(points, Sequence):
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
            self.forces = ForceOutputs(discretization, drivers, joints_with_forces)

    @property
    def n_force_columns(self) -> int:
        return 0 if self.forces is None else self.forces.n_columns

    @property
    def force_labels(self) -> tuple[str, ...]:
        return () if self.forces is None else self.forces.labels

    @property
    def force_units(self) -> tuple[str, ...]:
        return () if self.forces is None else self.forces.units

    def sample_shapes(self) -> dict[str, tuple[int, ...]]:
        """The shape of one sample of each recorded variable (the time aside; `sparsekin.results.schema`)."""
        return schema.sample_shapes(self)

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


class Recorder:
    """Stores solved samples: fills chunks of rows and writes every full chunk to a sink.

    It only stores: what a sample holds (the variables of `sparsekin.results.schema` the
    selection records) is computed before (`sparsekin.solve.observers`).

    Parameters
    ----------
    selection : Selection
    sink : MemorySink or ZarrSink
    chunk_samples : int, optional
        Samples per chunk (default: `Selection.chunk_samples`).
    """

    def __init__(self, selection: Selection, sink, chunk_samples: int | None = None) -> None:
        self.selection, self.sink = selection, sink
        self.size = selection.chunk_samples() if chunk_samples is None else int(chunk_samples)
        self._first = 0  # the index of the chunk's first sample
        # A memory sink's arrays hold the chunk's rows themselves (filled in place, not copied
        # again: `_chunk_rows`); for a store, the rows of one chunk.
        self._held = sink.arrays if getattr(sink, "in_place", False) else {}
        self._shapes = {TIME: ()} | selection.sample_shapes()
        self._chunk_rows()
        self._rows = 0
        self.n_written = 0
        self._failed = False  # a write to the sink failed

    def _chunk_rows(self) -> None:
        """The arrays the next chunk's rows go into: views of a memory sink's arrays from
        the chunk's first sample on, or arrays of one chunk."""
        self._buffers = {}
        for name, shape in self._shapes.items():
            held = self._held.get(name)
            self._buffers[name] = np.empty((self.size, *shape)) if held is None else held[self._first : self._first + self.size]

    def add_block(self, times, arrays: dict) -> None:
        """Solved samples at `times` (s): `arrays` holds, by name, one row per sample of
        every variable the selection records."""
        if len(times) == 1 and self._rows + 1 < self.size:  # one sample of the Python loop, the chunk not full
            row = self._rows
            for name, buffer in self._buffers.items():
                buffer[row] = times[0] if name == TIME else arrays[name][0]
            self._rows += 1
            return
        done = 0
        while done < len(times):
            row = self._rows
            m = min(self.size - row, len(times) - done)
            rows, block = slice(row, row + m), slice(done, done + m)
            self._buffers[TIME][rows] = times[block]
            for name, buffer in self._buffers.items():
                if name != TIME:
                    buffer[rows] = arrays[name][block]
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
        data = {name: buffer[:m] for name, buffer in self._buffers.items()}
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

    def finish(self):
        """Write what is left and close the sink; returns the sink's arrays."""
        self.flush()
        return self.sink.close(self.n_written)


#: The signals a chunk's write holds until it is done (issue 28: the command line stops on
#: SIGTERM and SIGHUP as on Ctrl-C).
_DEFERRED_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


def open_recorder(selection: Selection, store, n_times: int, chunk_samples: int | None = None) -> Recorder:
    """A `Recorder` of a run of `n_times` samples: streaming to the Zarr `store`, or in
    memory when `store` is None."""
    sink = ZarrSink(store, selection, n_times) if store is not None else MemorySink(selection, n_times)
    return Recorder(selection, sink, chunk_samples)


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
        self.arrays = {TIME: np.empty(n_times)} | {
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

        coords = {TIME: ("time", data[TIME])}
        if with_labels:
            coords |= schema.dataset_labels(self.selection)
        return xr.Dataset(schema.dataset_variables(data), coords=coords)

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
        for key in (*(key for key in data if key != TIME), TIME):  # the time last: its sample is whole
            group[key][first : first + len(data[key])] = data[key]

    def _create(self, data: dict, n_times: int | None) -> None:
        """Write the store with the first chunk and the labels: at a temporary name, laid out
        over `n_times` samples, then renamed into place (see the class docstring)."""
        import warnings

        n = self.selection.mechanism.n_coordinates
        rows = max(1, len(data[TIME]))
        encoding = {key: {"chunks": (rows, *(min(size, 2**20) for size in values.shape[1:]))}
                    for key, values in data.items()}  # fmt: skip
        encoding |= {v.name: {"chunks": (rows, min(n, 2**20))} for v in schema.COORDINATE_VARIABLES if v.name in data}
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
            empty = {name: np.empty((0, *shape)) for name, shape in self.selection.sample_shapes().items()}
            self._create({TIME: np.empty(0), **empty}, None)
            self._written = True
        elif self.n_times is not None and n_written < self.n_times:
            _resize_time(self.path, n_written)
        group = zarr.open_group(self.path, mode="r")
        return {name: group[name] for name in (TIME, *(v.name for v in schema.VARIABLES)) if name in group}
