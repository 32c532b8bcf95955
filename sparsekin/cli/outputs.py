"""A command's output folder: locked while a run writes it, every file complete or absent,
the previous run's files cleaned, and ``run.json`` (what the folder holds) written last.

`OutputFolder` is what ``run``, ``sweep`` and ``workspace`` write through:

1. on entering, it creates the folder, takes an exclusive lock on it (`fcntl.flock` on the
   folder itself: the kernel releases it when the process ends, however it ends, so a
   killed run never leaves it stale) and checks that every file the run will write can
   be written there (not a folder in the way, the folder writable), before any solving;
2. the files are written into a staging folder inside it (``.sparsekin-staging-<pid>``);
3. `OutputFolder.commit` removes the previous ``run.json``, removes the files of the
   previous run that this run does not write again (those listed in its ``run.json``, and
   every name this command can write), renames the staged files into place (each
   rename is atomic) and writes ``run.json`` last (also by a rename).

So at any moment, even after a SIGKILL, every file in the folder is complete, and the
files there come from one run: the previous one until the first rename, then the new
one.  A folder with ``run.json`` holds exactly the files it lists, as it describes them;
a folder without it holds a run that was killed while it wrote (or older files).  A Zarr
store that a run streams (``results.zarr``) is written in place: the previous run's
files are cleaned before the store is begun (`OutputFolder.clean`), so that the store is
never beside another run's CSV files.
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import fnmatch
import glob
import hashlib
import json
import os
import shutil
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

from .common import CommandError

#: The manifest: what the folder holds, written last.
MANIFEST = "run.json"
#: The staging folders' names start with this (followed by the writing process's id).
STAGING_PREFIX = ".sparsekin-staging-"
#: What each command can write into its folder (names and `fnmatch` patterns): the files
#: of a previous run matching these and not written again are removed.
COMMAND_OUTPUTS = {
    "run": ("points.csv", "joints.csv", "forces.csv", "coordinates.npz", "energy.csv", "results.zarr", "point_*.png",
            "path_*.png", "paths.png", "mechanism.png", "actuators.png", "forces.png"),
    "sweep": ("sweep.zarr", "variants.csv", "sweep_paths_*.png", "stop_times.png"),
    "workspace": ("workspace.csv", "boundary.csv", "workspace_*.png"),
}  # fmt: skip
#: The errors of a full disk (or of a file-size limit): reported with the file and what was kept.
DISK_FULL = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


class FolderBusy(CommandError):
    """Another live run is writing the folder."""


class OutputFolder:
    """The output folder of one command (see the module docstring).

    Parameters
    ----------
    directory : Path
        The folder (created with its parents).
    command : str
        A key of `COMMAND_OUTPUTS`.
    names : sequence of str
        The files (and stores) the run will write there, to check before any solving.

    Raises
    ------
    FolderBusy
        On entering, if another live process holds the folder's lock.
    CommandError
        If a file the run writes is a folder there (or a store is a file).
    OSError
        If the folder cannot be created or written.
    """

    def __init__(self, directory: Path, command: str, names: Sequence[str] = ()) -> None:
        self.directory = Path(directory)
        self.command = command
        self.names = tuple(names)
        self.staging = self.directory / f"{STAGING_PREFIX}{os.getpid()}"
        self._lock = None
        self.placed: list[Path] = []  # the files renamed into place so far

    def __enter__(self) -> OutputFolder:
        if self.directory.exists() and not self.directory.is_dir():
            raise CommandError(f"--out {self.directory}: is a file; give a folder (it is created if needed)")
        self.directory.mkdir(parents=True, exist_ok=True)
        self._lock = _lock_folder(self.directory)
        try:
            self._check_names()
            _remove_stale_staging(self.directory)
            try:
                self.staging.mkdir()  # also the check that the folder can be written
            except PermissionError as error:  # name the folder given, not the staging folder in it
                raise CommandError(f"--out {self.directory}: {error.strerror}: the run cannot write there") from None
        except BaseException:
            self._unlock()
            raise
        return self

    def __exit__(self, *exc) -> None:
        shutil.rmtree(self.staging, ignore_errors=True)
        self._unlock()

    def _unlock(self) -> None:
        if self._lock is not None:
            os.close(self._lock)  # closing the descriptor releases the lock
            self._lock = None

    def _check_names(self) -> None:
        for name in self.names:
            path = self.directory / name
            store = name.endswith(".zarr")
            if store and path.exists() and not path.is_dir():
                raise CommandError(f"{path}: is a file where the run writes a Zarr store; move it or give another --out")
            if not store and path.is_dir():
                raise CommandError(f"{path}: is a folder where the run writes a file; move it or give another --out")

    def staged(self, name: str) -> Path:
        """Where the file `name` is written before `commit` renames it into place."""
        return self.staging / name

    def clean(self, keep: Iterable[str] = ()) -> list[str]:
        """Remove the previous ``run.json``, then every file of a previous run that is not in
        `keep`: those its ``run.json`` lists and those matching `COMMAND_OUTPUTS`; returns
        their names."""
        keep = set(keep)
        previous = _manifest_files(self.directory / MANIFEST)
        _remove(self.directory / MANIFEST)
        patterns = COMMAND_OUTPUTS[self.command]
        removed = []
        with os.scandir(self.directory) as scan:
            for entry in sorted(scan, key=lambda entry: entry.name):
                name = entry.name
                if name in keep or name.startswith("."):
                    continue
                if name in previous or any(fnmatch.fnmatchcase(name, pattern) for pattern in patterns):
                    _remove(Path(entry.path))
                    removed.append(name)
        return removed

    def commit(self, staged: Sequence[Path], in_place: Sequence[Path], manifest: dict) -> list[Path]:
        """Put the run's files into the folder and write ``run.json`` last.

        Parameters
        ----------
        staged : sequence of Path
            Files written by `staged` paths, renamed into the folder in this order.
        in_place : sequence of Path
            Files (stores) already written in the folder.
        manifest : dict
            What ``run.json`` says besides the files (`manifest`).

        Returns
        -------
        list of Path
            Every file of the run, in the folder, ``run.json`` last.
        """
        names = [path.name for path in (*in_place, *staged)]
        self.clean(keep=names)
        self.placed = list(in_place)
        for path in staged:
            target = self.directory / path.name
            if target.is_dir() and not path.name.endswith(".zarr"):
                raise CommandError(f"{target}: is a folder where the run writes a file")
            os.replace(path, target)
            self.placed.append(target)
        return [*self.placed, self.write_manifest(manifest, self.placed)]

    def write_manifest(self, manifest: dict, files: Sequence[Path]) -> Path:
        """Write ``run.json``: `manifest` and the names of `files`, by a rename."""
        record = dict(manifest, files=[path.name for path in files])
        record["written"] = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
        path = self.directory / MANIFEST
        write_atomically(path, lambda file: file.write(json.dumps(record, indent=2).encode() + b"\n"))
        return path


def manifest(command_line: Sequence[str], model: Path, status: str, exit_status: int, counts: dict) -> dict:
    """The fields of ``run.json`` besides the files: the command line, the model file and
    its SHA-256, sparsekin's version, the run's status and exit status, and `counts` (for
    ``run``: ``samples_solved`` and ``samples_requested``)."""
    return {
        "command": list(command_line),
        "model": os.fsdecode(model),
        "model_sha256": _file_hash(model),
        "sparsekin": _version(),
        "status": status,
        "exit_status": exit_status,
        **counts,
    }


def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("sparsekin")
    except metadata.PackageNotFoundError:  # run from a source tree that is not installed
        return "unknown"


@contextlib.contextmanager
def written_whole(path: Path) -> Iterator[Path]:
    """A temporary name beside `path` (ending in its suffix, which may choose a format) to
    write the file at in the block: renamed to `path` when the block ends, removed if it
    fails.  Whenever the process ends, `path` is the old file or the whole new one.  (Not
    synced to the disk: a power cut may lose what the kernel held.)"""
    path = Path(path)
    temporary = path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")
    _remove_stale_partials(path)
    try:
        yield temporary
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(temporary)
        raise


def _remove_stale_partials(path: Path) -> None:
    """Remove the temporary files of `path` that processes no longer running left (an
    ``animate`` killed while it wrote its clip, outside any locked folder)."""
    for partial in path.parent.glob(f".{glob.escape(path.stem)}.*.partial{glob.escape(path.suffix)}"):
        pid = partial.name[len(path.stem) + 2 : -len(f".partial{path.suffix}")]
        if pid.isdigit() and not _running(int(pid)):
            _remove(partial)


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: running
        return True
    return True


def write_atomically(path: Path, write) -> Path:
    """Write a file through `write(file)` (a binary file), whole or not at all (`written_whole`)."""
    with written_whole(path) as temporary, open(temporary, "wb") as file:
        write(file)
    return Path(path)


def _file_hash(path: Path) -> str | None:
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as file:
            for block in iter(lambda: file.read(2**20), b""):
                digest.update(block)
    except OSError:
        return None
    return digest.hexdigest()


def _manifest_files(path: Path) -> set[str]:
    """The files a previous ``run.json`` lists (none if it cannot be read)."""
    try:
        files = json.loads(path.read_text(encoding="utf-8")).get("files", [])
    except (OSError, ValueError, AttributeError):
        return set()
    return {name for name in files if isinstance(name, str) and name == Path(name).name and name != MANIFEST}


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        with contextlib.suppress(FileNotFoundError):
            os.remove(path)


def _remove_stale_staging(directory: Path) -> None:
    """Remove the staging folders left by killed runs (the lock is ours: no live run's)."""
    for path in directory.glob(f"{STAGING_PREFIX}*"):
        shutil.rmtree(path, ignore_errors=True)
    for path in directory.glob(".*.partial*"):
        _remove(path)


def _lock_folder(directory: Path) -> int | None:
    """An exclusive lock on `directory` (a descriptor to close to release it), or a
    `FolderBusy` if another process holds it.  None where there is no `fcntl`."""
    try:
        import fcntl
    except ImportError:  # Windows: no lock
        return None
    descriptor = os.open(directory, os.O_RDONLY)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(descriptor)
        raise FolderBusy(f"{directory}: another sparsekin run is writing this folder; wait for it to end or give "
                         "another --out") from None  # fmt: skip
    return descriptor


def disk_full(error: OSError) -> bool:
    """Whether `error` says the disk (or the file-size limit) is full."""
    return error.errno in DISK_FULL
