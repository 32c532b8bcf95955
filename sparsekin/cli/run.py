"""``sparsekin run``: solve a model file and write its results."""

from __future__ import annotations

import argparse
import math
import time
import warnings
from pathlib import Path

from ..errors import AnalysisInterrupted, ConvergenceError, ModelError
from ..model.mechanism import Mechanism
from ..model.modelfile import load_model
from ..results.dynamics import DynamicsResult
from ..results import schema
from ..results.kinematics import KinematicsResult
from ..solve.dynamics import solve_dynamics
from ..solve.kinematics import solve_kinematics
from . import signals
from .common import (
    EXIT_STOPPED,
    EXIT_SUCCESS,
    CommandError,
    ProgressBar,
    report,
    require_matplotlib,
    require_zarr,
)
from .compiling import announce_compilation
from .files import count_samples, planned_files, write_outputs
from .outputs import OutputFolder, disk_full, manifest, written_whole
from .settings import (
    MAX_DEFAULT_JOINTS,
    MAX_DEFAULT_POINTS,
    MAX_DEFAULT_VALUES,
    RunSettings,
    add_folder_argument,
    add_force_arguments,
    add_label_argument,
    add_time_arguments,
    read_model,
    resolve_run_settings,
)
from .sizes import RUN_ADVICE, add_memory_argument, check_memory, limit_for, run_parts


def add_run_command(subparsers) -> None:
    """Add ``run MODEL.toml [--t-end T] [--steps N] [--points A,J] [--out DIR] [--plot]``."""
    parser = subparsers.add_parser(
        "run",
        help="analyse a model and write points.csv, joints.csv, forces.csv and coordinates.npz",
        description="Solve positions, velocities and accelerations at steps times from 0 to t_end "
        "(and, for a model with masses or loads, the forces that hold the motion) and write points.csv, "
        "joints.csv, forces.csv, coordinates.npz and, with --plot, PNG figures.",
    )
    parser.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    add_time_arguments(parser)
    parser.add_argument(
        "--points", metavar="A,J", help="output points separated by commas, or all or none (default: "
        f"[analysis].points, else every named point up to {MAX_DEFAULT_POINTS})"
    )
    parser.add_argument(
        "--joints", metavar="J1,J2", help="joints written to joints.csv, separated by commas, or all or none "
        f"(default: every joint with an own coordinate up to {MAX_DEFAULT_JOINTS})"
    )
    add_force_arguments(parser, "written to forces.csv")
    coordinates = parser.add_mutually_exclusive_group()
    coordinates.add_argument("--no-coordinates", dest="coordinates", action="store_false", default=None,
                             help="leave out every body's coordinates (coordinates.npz, or q, qd, qdd in Zarr)")
    coordinates.add_argument("--coordinates", dest="coordinates", action="store_true",
                             help=f"write them whatever their size (default: up to {MAX_DEFAULT_VALUES:.0e} values)")
    parser.add_argument("--format", choices=("csv", "zarr"), default="csv",
                        help='csv: points.csv, joints.csv, coordinates.npz; zarr: results.zarr, written while the '
                        'run goes on (needs "sparsekin[zarr]")')
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_folder_argument(parser)
    add_memory_argument(parser)
    parser.add_argument("--plot", action="store_true", help='also draw PNG figures (needs "sparsekin[plot]")')
    add_label_argument(parser)
    parser.add_argument("--abscissa", metavar="DRIVER",
                        help="plot the motion figures of --plot against the value this driver drives (a crank "
                        "angle, a stroke) instead of time")  # fmt: skip
    parser.add_argument("--save-pose", nargs=2, metavar=("T", "OUT.toml"),
                        help="also write a model drawn at the solved pose at time T (s), its laws shifted so that "
                        "it starts there: a rough drawing becomes an exact one with T = 0")  # fmt: skip
    add_dynamics_arguments(parser)
    parser.set_defaults(handler=run_command)


def add_dynamics_arguments(parser, writes: str = "; also writes energy.csv") -> None:
    """``--dynamics``, ``--max-step`` and ``--rtol``: integrate the equations of motion
    (forward dynamics); `writes` ends the help of ``--dynamics`` (what the command writes
    besides)."""
    parser.add_argument("--dynamics", action="store_true", default=None,
                        help='integrate the equations of motion under the masses, gravity and loads (as [analysis] '
                        f'type = "dynamics"){writes}')
    parser.add_argument("--max-step", type=float, metavar="H",
                        help="largest integration step of --dynamics, s (default: [analysis].max_step, else the "
                        "output interval)")
    parser.add_argument("--rtol", type=float, metavar="R",
                        help="error-controlled steps of --dynamics: the local error of one step relative to the model "
                        "size (angles: rad), in [1e-12, 0.1]; steps never above --max-step (default: [analysis].rtol, "
                        "else fixed steps of --max-step)")


def is_dynamics(arguments: argparse.Namespace, mechanism: Mechanism) -> bool:
    """Whether the command integrates the equations of motion: ``--dynamics`` or the model's
    ``[analysis] type``; ``--max-step`` or ``--rtol`` alone is a mistake."""
    from ..solve.options import RTOL_RANGE

    dynamics = bool(getattr(arguments, "dynamics", None)) or mechanism.analysis.type == "dynamics"
    for option in ("max_step", "rtol"):
        if getattr(arguments, option, None) is not None and not dynamics:
            raise CommandError(f'--{option.replace("_", "-")} is for forward dynamics: give --dynamics (or [analysis] '
                               'type = "dynamics")')  # fmt: skip
    max_step, rtol = getattr(arguments, "max_step", None), getattr(arguments, "rtol", None)
    if max_step is not None and not max_step > 0.0:
        raise CommandError(f"--max-step must be a positive number of seconds, got {max_step!r}")
    if rtol is not None and not RTOL_RANGE[0] <= rtol <= RTOL_RANGE[1]:
        raise CommandError(f"--rtol must be a number in [{RTOL_RANGE[0]:g}, {RTOL_RANGE[1]:g}], got {rtol!r}")
    return dynamics


def run_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin run``; returns the exit status.

    Raises
    ------
    CommandError, ModelError, OSError
        For a bad argument, a bad model file or an output folder that cannot be written;
        `main` reports them.
    """
    timeline = _Timeline()
    _pose_time(arguments)  # --save-pose checked before any solving
    mechanism = read_model(arguments)
    timeline.read = time.perf_counter()
    settings = resolve_run_settings(arguments, mechanism)
    if settings.plot:
        require_matplotlib()
    if settings.format == "zarr":
        require_zarr()
    arguments.memory_parts = run_parts(mechanism, settings)
    arguments.memory_estimate = check_memory(arguments.memory_parts, limit_for(arguments), RUN_ADVICE)
    with OutputFolder(settings.directory, "run", planned_files(mechanism, settings)) as folder:
        for note in settings.notes:
            report(f"note: {note}")
        if settings.format == "zarr":  # the store is written in place from the first sample on
            folder.clean(keep=["results.zarr"])
        dynamics = is_dynamics(arguments, mechanism)
        stop = None
        try:
            with _Progress(settings, timeline) as progress:
                result = solve_for_command(mechanism, settings, arguments.model, progress, dynamics=dynamics,
                                           max_step=getattr(arguments, "max_step", None),
                                           rtol=getattr(arguments, "rtol", None))  # fmt: skip
            timeline.solved = time.perf_counter()
        except ConvergenceError as error:
            result, stop = error.result, error
        except AnalysisInterrupted as interrupt:
            result, stop = interrupt.result, interrupt
        except OSError as error:
            if settings.format != "zarr" or not disk_full(error):
                raise
            result, stop = None, error
        with signals.holding():  # a signal now waits for the files to be finished
            return _write_run(mechanism, result, stop, settings, folder, arguments, timeline)


def _write_run(mechanism: Mechanism, result, stop, settings: RunSettings, folder: OutputFolder, arguments,
               timeline: _Timeline) -> int:  # fmt: skip
    """Write the samples of `result` (all of them, or those before `stop`: the error or
    interrupt that stopped the run) and say what was written; returns the exit status."""
    directory, requested = settings.directory, settings.times.size
    store = [directory / "results.zarr"] if settings.format == "zarr" else []
    if isinstance(stop, OSError):  # the disk filled while the store was written
        kept = stored_samples(store[0])
        where = f"in {store[0]}" if store[0].exists() else f"({store[0].name} not written)"
        folder.commit([], [path for path in store if path.exists()],
                      _manifest(arguments, "disk_full", EXIT_STOPPED, kept, requested))  # fmt: skip
        report(f"error: {stop.filename or store[0]}: {stop.strerror}: kept the first {kept} of {requested} samples "
               f"{where}")  # fmt: skip
        return EXIT_STOPPED
    solved = count_samples(result)
    if isinstance(stop, ConvergenceError):
        status, exit_status = "stopped", EXIT_STOPPED
        report(f"analysis stopped: {stop}")
    elif isinstance(stop, AnalysisInterrupted):
        status, exit_status = "interrupted", signals.exit_status()
    else:
        status, exit_status = "complete", EXIT_SUCCESS
    staged: list[Path] = []
    try:
        write_outputs(mechanism, result, settings, folder.staging, staged)
    except OSError as error:
        if not disk_full(error):
            raise
        whole = [path.name for path in staged]
        files = folder.commit(staged, store, _manifest(arguments, "disk_full", EXIT_STOPPED, solved, requested))
        report(f"error: {directory / Path(error.filename or '?').name}: {error.strerror}: {solved} of {requested} "
               f"samples solved; kept {', '.join(whole) or 'no file'} in {directory}")  # fmt: skip
        return EXIT_STOPPED
    if signals.received() is not None and stop is None:  # a signal came while the files were written
        status, exit_status = "complete", signals.exit_status()
    files = folder.commit(staged, store, _manifest(arguments, status, exit_status, solved, requested))
    names = ", ".join(path.name for path in files)
    if status == "interrupted":
        report(f"{signals.interrupted()}: wrote {solved} of {requested} samples to {directory}: {names}")
    elif status == "stopped":
        report(f"wrote {solved} of {requested} samples to {directory}: {names}")
    else:
        if exit_status != EXIT_SUCCESS:
            report(f"{signals.signal_name()} while writing: finished first; wrote all {solved} samples to "
                   f"{directory}: {names}")  # fmt: skip
        _note_heavy_fill(mechanism, result)
        pose_time = _pose_time(arguments)
        if pose_time is not None:
            files.append(_save_pose(result, pose_time, Path(arguments.save_pose[1]), arguments.model))
        print(_summary(mechanism, result, timeline, files))
    return exit_status


def _manifest(arguments, status: str, exit_status: int, solved: int, requested: int) -> dict:
    return manifest(arguments.command_line, arguments.model, status, exit_status,
                    {"samples_solved": solved, "samples_requested": requested,
                     "memory_estimate_bytes": getattr(arguments, "memory_estimate", None),
                     "memory_estimate_parts": getattr(arguments, "memory_parts", None)})  # fmt: skip


def stored_samples(store: Path) -> int:
    """The samples a Zarr store of a run holds (0 if it cannot be read)."""
    try:
        import zarr

        return int(zarr.open_group(store, mode="r")[schema.TIME].shape[0])
    except Exception:  # noqa: BLE001 - a store the disk left unreadable holds nothing that can be counted
        return 0


def _note_heavy_fill(mechanism: Mechanism, result: KinematicsResult) -> None:
    """One note when a hub (a body many others are attached to) left the factors heavy: the
    run then reused its factorization across samples (path "reuse")."""
    if result.linear_solver != "reuse" or not mechanism.copies:
        return
    from ..engine.ordering import hub_coordinates
    from ..engine.pattern import build_pattern

    hub = hub_coordinates(build_pattern(mechanism))
    if hub.size:
        names = ", ".join(sorted({mechanism.body_name(int(b)) for b in hub[:12] // 3}))
        report(f"note: the factors filled in heavily around {names}, which many bodies are attached to (the run "
               "reused its factorization across samples): attach the copies one to the next (a chain), and see "
               "sparsekin check")


def _pose_time(arguments: argparse.Namespace) -> float | None:
    """The T of ``--save-pose T OUT.toml``, checked; None without it."""
    if arguments.save_pose is None:
        return None
    try:
        value = float(arguments.save_pose[0])
    except ValueError:
        raise CommandError(f"--save-pose: expected a time T (s), got {arguments.save_pose[0]!r}") from None
    if not math.isfinite(value):
        raise CommandError(f"--save-pose: expected a finite time T (s), got {arguments.save_pose[0]!r}")
    return value


def _save_pose(result: KinematicsResult, pose_time: float, path: Path, model_path: Path) -> Path:
    """Write the model drawn at the pose at `pose_time` (`sparsekin.solve.poses.pose_model`)."""
    from ..model.modelfile import save_model
    from ..solve.poses import pose_model

    try:
        model = pose_model(result, pose_time)
    except ValueError as error:
        raise CommandError(f"--save-pose: {error}") from None
    except ModelError as error:
        raise (error if error.file else error.in_file(str(model_path))) from None
    with written_whole(path) as partial:
        save_model(model, partial)
    return path


class _Timeline:
    """When ``run`` started, read its model, solved its first sample and its last."""

    def __init__(self) -> None:
        self.start = time.perf_counter()
        self.read = self.first = self.solved = None
        self.first_done = 0  # samples solved at `first` (a chunk of the compiled loop, or one)


class _Progress(ProgressBar):
    """The run's progress: the bar of `ProgressBar`, and the time of the first sample."""

    def __init__(self, settings: RunSettings, timeline: _Timeline) -> None:
        super().__init__(settings.times.size, "sample", settings.quiet)
        self._timeline = timeline

    def __call__(self, done: int, total: int) -> None:
        if self._timeline.first is None:
            self._timeline.first, self._timeline.first_done = time.perf_counter(), done
        super().__call__(done, total)


def solve_for_command(mechanism: Mechanism, settings: RunSettings, model_path: Path, progress, *, dynamics: bool = False,
                      max_step: float | None = None, rtol: float | None = None) -> KinematicsResult | DynamicsResult:  # fmt: skip
    """`solve_kinematics` (or with `dynamics`, `solve_dynamics` with `max_step` and `rtol`) recording what
    `settings` asks for, with its argument and model errors reported against the file.

    Warnings (redundant equations left out, limits left) are printed as one line each.  On
    the first run after an install, says that the kernels compile (`announce_compilation`).
    """
    announce_compilation(settings.quiet)
    store = settings.directory / "results.zarr" if settings.format == "zarr" else None
    # With the coordinates in memory, points and joints are derived after the run; a store,
    # or a run without the coordinates, records them while it goes on.
    record = store is not None or not settings.coordinates
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                kept = {"coordinates": settings.coordinates, "points": settings.point_names if record else None,
                        "joints": settings.joint_indices if record else None, "forces": settings.forces,
                        "store": store, "progress": progress}  # fmt: skip
                if dynamics:
                    return solve_dynamics(mechanism, settings.times, max_step, rtol=rtol, **kept)
                return solve_kinematics(mechanism, settings.times, quasi_static=settings.quasi_static, **kept)
            finally:
                for warning in caught:
                    report(f"warning: {warning.message}")
    except ModelError as error:
        raise (error if error.file else error.in_file(str(model_path))) from None
    except ValueError as error:  # e.g. the times leave the range of a spline law
        raise CommandError(str(error)) from None


def _summary(mechanism: Mechanism, result: KinematicsResult, timeline: _Timeline, written: list[Path]) -> str:
    """A few lines: samples, Newton corrections per step, factorizations, times, files."""
    corrections = result.newton_iterations
    if timeline.first is None:  # nothing to solve (a model without bodies): no progress was reported
        timeline.first, timeline.first_done = timeline.solved, result.n_times
    first = timeline.first - timeline.start
    later = result.n_times - timeline.first_done
    per_sample = (timeline.solved - timeline.first) / later if later else (timeline.solved - timeline.read) / result.n_times
    which = "first sample" if timeline.first_done == 1 else f"first {timeline.first_done} samples"
    lines = [
        f"{mechanism.name}: {mechanism.n_bodies} bodies, {result.n_times} samples, t = 0 … {result.times[-1]:g} s",
        f"Newton corrections per step: mean {corrections.mean():.2f}, max {corrections.max()}",
        f"linear solver: {result.linear_solver}; factorizations: {result.n_factorizations}"
        + (f" (+ {result.n_refactorizations} refactorizations)" if result.n_refactorizations else "")
        + f", linear solves: {result.n_solves}, wall time: {timeline.solved - timeline.read:.3g} s",
        f"times: model read in {timeline.read - timeline.start:.3g} s, {which} solved {first:.3g} s after the "
        f"start, {per_sample:.3g} s a sample",
        "wrote:",
        *(f"  {path}" for path in written),
    ]
    return "\n".join(lines)
