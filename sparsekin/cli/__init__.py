"""The ``sparsekin`` command line.

``sparsekin run MODEL.toml`` reads a model file, runs the kinematic analysis and writes
``points.csv``, ``joints.csv`` and ``coordinates.npz`` (``--format zarr``: one Zarr store;
with ``--plot``, also PNG figures) as described in ``docs/model-format.md``.  On a large
model it writes what a person can use by default (`DEFAULT_RULE`).  A progress bar shows
on stderr for runs longer than two seconds.  Exit status: 0 on success, 2 on a bad model
or bad arguments (one line on stderr, no traceback), 3 when the analysis stops and 130 on
Ctrl-C (in both cases the samples solved so far are still written).

``sparsekin animate MODEL.toml`` runs the same analysis and writes an animation (GIF or
MP4, `sparsekin.plots.animate`) or one frame of it (PNG).  Exit status as for ``run``;
when the analysis stops, the clip runs up to the stop and marks it.

``sparsekin check MODEL.toml`` assembles the model and prints its degrees of freedom, the
rank of its Jacobian, its redundant equations and its free motions
(`sparsekin.analysis.check.check_model`).  Exit status: 0 for a sound model, 1 when it has
a problem (redundant equations, free motions, an element outside its limits, or it
cannot be assembled), 2 on a bad model file or bad arguments.

``sparsekin sweep MODEL.toml --vary PATH=START:STOP:N ...`` solves many variants on Dask
(`sparsekin.studies.sweeps`) and writes ``sweep.zarr`` and ``variants.csv``; exit status 0 once
every variant is written, whatever its status, 2 on a bad argument, 3 when a task failed.
``sparsekin workspace MODEL.toml --point K`` maps the point over two drivers' values
(`sparsekin.studies.workspaces`).

Each subcommand is a pair of functions: one adds its parser to the subparsers, the other
runs it and returns the exit status.  `SUBCOMMANDS` lists the first of each pair, so a
new subcommand only needs its two functions and one entry there.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import AnalysisInterrupted, ConvergenceError, ModelError, SingularConfigurationError
from ..model import _validate
from ..model.mechanism import Mechanism
from ..model.modelfile import load_model
from ..results.kinematics import KinematicsResult
from ..solve.kinematics import solve_kinematics
from .compiling import announce_compilation
from .warning_lines import one_line_warnings

__all__ = ["main", "build_parser"]

PROGRAM = "sparsekin"
EXIT_SUCCESS = 0
EXIT_PROBLEM = 1
EXIT_USAGE = 2
EXIT_STOPPED = 3
EXIT_INTERRUPTED = 130
#: What ``run`` writes when neither the options nor ``[analysis]`` say (docs/model-format.md):
#: every named point up to `MAX_DEFAULT_POINTS` (else none), every joint with an own
#: coordinate up to `MAX_DEFAULT_JOINTS` (else none), and the coordinates of every body
#: while the run holds at most `MAX_DEFAULT_VALUES` values of each of q, qd and qdd (else
#: none: ``--format zarr`` streams them); a one-line note says what was left out and how
#: to ask for it.
DEFAULT_RULE = "points ≤ 100, joints ≤ 100, coordinates ≤ 2e7 values, forces of ≤ 100 drivers and joints"
MAX_DEFAULT_POINTS = 100
MAX_DEFAULT_JOINTS = 100
MAX_DEFAULT_VALUES = 20_000_000
MAX_DEFAULT_FORCE_ELEMENTS = 100
#: ``--plot`` draws at most this many bodies (the first) in ``mechanism.png``: more make no
#: readable picture (a 1000-body chain took 8.2 s to draw: `sparsekin.plots.MAX_PLACED_LABELS`).
MAX_DRAWN_BODIES = 100
#: A progress bar appears once a run has lasted this long, s.
PROGRESS_DELAY = 2.0
#: Samples of ``sparsekin run`` when neither ``--steps`` nor ``[analysis].steps`` is given.
DEFAULT_STEPS = 101
#: Parent of the default output folder, ``./sparsekin-out/<model name>``.
DEFAULT_OUTPUT_ROOT = Path("sparsekin-out")
#: Columns of ``points.csv`` for each output point, after the point name and a dot.
POINT_COLUMNS = ("x", "y", "vx", "vy", "ax", "ay")
#: Most point names listed in the message about an unknown point.
LISTED_POINTS = 20


class CommandError(Exception):
    """A mistake in the command-line arguments: reported as one line, exit status 2."""


@dataclass(frozen=True)
class RunSettings:
    """What ``sparsekin run`` computes and where it writes.

    Attributes
    ----------
    times : ndarray, shape (steps,)
        Sample times, s, from 0 to the end time.
    point_names : tuple of str
        Output points, in the order of the columns of ``points.csv``.
    directory : Path
        Output folder.
    plot : bool
        Whether to write the PNG figures.
    joint_indices : tuple of int
        Joints written to ``joints.csv`` (or the store).
    coordinates : bool
        Whether every body's coordinates are written.
    format : {"csv", "zarr"}
    quiet : bool
        No progress bar.
    notes : tuple of str
        What the default rule left out, in words.
    forces : None, "all" or tuple of str
        The drivers and joints whose forces are written to ``forces.csv`` (or the store).
    quasi_static : bool
        Forces without the inertial forces.
    """

    times: np.ndarray
    point_names: tuple[str, ...]
    directory: Path
    plot: bool
    joint_indices: tuple[int, ...] = ()
    coordinates: bool = True
    format: str = "csv"
    quiet: bool = False
    notes: tuple[str, ...] = ()
    forces: str | tuple[str, ...] | None = None
    quasi_static: bool = False


# ---------------------------------------------------------------------- entry point
def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``sparsekin`` command line.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after the program name; ``sys.argv[1:]`` when omitted.

    Returns
    -------
    int
        Exit status: 0 on success, 1 when ``check`` finds a problem in the model, 2 on a bad
        model or bad arguments, 3 when the analysis stopped, 130 on Ctrl-C (a command
        that has solved samples writes them first).
    """
    parser = build_parser()
    try:
        arguments = parser.parse_args(argv)
    except SystemExit as exit_request:  # usage errors and --help: argparse has printed
        return int(exit_request.code or 0)
    try:
        with one_line_warnings(PROGRAM):
            return arguments.handler(arguments)
    except (CommandError, ModelError) as error:
        _report(f"error: {error}")
    except OSError as error:  # an output folder or file that cannot be written
        _report(f"error: {error.filename}: {error.strerror}" if error.filename else f"error: {error}")
    except KeyboardInterrupt:  # before any sample was solved (the commands handle it after)
        _report("interrupted: nothing solved yet, nothing written")
        return EXIT_INTERRUPTED
    return EXIT_USAGE


def build_parser() -> argparse.ArgumentParser:
    """The argument parser, with one subparser per entry of `SUBCOMMANDS`."""
    parser = argparse.ArgumentParser(
        prog=PROGRAM, description="Kinematic analysis of planar linkages described in a TOML model file."
    )
    subparsers = parser.add_subparsers(title="commands", dest="command", required=True, metavar="COMMAND")
    for add_subcommand in SUBCOMMANDS:
        add_subcommand(subparsers)
    return parser


def _report(message: str) -> None:
    """Print ``sparsekin: <message>`` to stderr as one line."""
    print(f"{PROGRAM}: {' '.join(message.splitlines())}", file=sys.stderr)


# ---------------------------------------------------------------------- run
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
    parser.add_argument("--t-end", type=float, metavar="T", help="end time, s (default: [analysis].t_end)")
    parser.add_argument(
        "--steps", type=int, metavar="N", help=f"number of samples, t = 0 included (default: "
        f"[analysis].steps, else {DEFAULT_STEPS})"
    )
    parser.add_argument(
        "--points", metavar="A,J", help="output points separated by commas, or all or none (default: "
        f"[analysis].points, else every named point up to {MAX_DEFAULT_POINTS})"
    )
    parser.add_argument(
        "--joints", metavar="J1,J2", help="joints written to joints.csv, separated by commas, or all or none "
        f"(default: every joint with an own coordinate up to {MAX_DEFAULT_JOINTS})"
    )
    _add_force_arguments(parser, "written to forces.csv")
    coordinates = parser.add_mutually_exclusive_group()
    coordinates.add_argument("--no-coordinates", dest="coordinates", action="store_false", default=None,
                             help="leave out every body's coordinates (coordinates.npz, or q, qd, qdd in Zarr)")
    coordinates.add_argument("--coordinates", dest="coordinates", action="store_true",
                             help=f"write them whatever their size (default: up to {MAX_DEFAULT_VALUES:.0e} values)")
    parser.add_argument("--format", choices=("csv", "zarr"), default="csv",
                        help='csv: points.csv, joints.csv, coordinates.npz; zarr: results.zarr, written while the '
                        'run goes on (needs "sparsekin[zarr]")')
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument(
        "--out", type=Path, metavar="DIR",
        help=f"output folder (default: ./{DEFAULT_OUTPUT_ROOT}/<model name>)",
    )
    parser.add_argument("--plot", action="store_true", help='also draw PNG figures (needs "sparsekin[plot]")')
    parser.set_defaults(handler=run_command)


def _add_force_arguments(parser, where: str) -> None:
    """``--forces`` and ``--quasi-static`` (of ``run`` and ``sweep``)."""
    parser.add_argument(
        "--forces", metavar="D1,J2", help=f"drivers and joints whose forces are {where}, separated by commas, or all "
        f"or none (default, for a model with a mass or a load: all of them if there are at most "
        f"{MAX_DEFAULT_FORCE_ELEMENTS})"
    )
    parser.add_argument("--quasi-static", action="store_true",
                        help="forces without the inertial forces: what holds the mechanism still in each position")


def run_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin run``; returns the exit status.

    Raises
    ------
    CommandError, ModelError, OSError
        For a bad argument, a bad model file or an output folder that cannot be written;
        `main` reports them.
    """
    timeline = _Timeline()
    mechanism = load_model(arguments.model)
    timeline.read = time.perf_counter()
    settings = resolve_run_settings(arguments, mechanism)
    if settings.plot:
        _require_matplotlib()
    if settings.format == "zarr":
        _require_zarr()
    settings.directory.mkdir(parents=True, exist_ok=True)
    for note in settings.notes:
        _report(f"note: {note}")
    announce_compilation(settings.quiet)
    try:
        with _Progress(settings, timeline) as progress:
            result = _solve(mechanism, settings, arguments.model, progress)
    except ConvergenceError as error:
        written = write_outputs(mechanism, error.result, settings)
        _report(f"analysis stopped: {error}")
        _report(f"wrote {_count_samples(error.result)} of {settings.times.size} samples to "
                f"{settings.directory}: {', '.join(path.name for path in written)}")
        return EXIT_STOPPED
    except AnalysisInterrupted as interrupt:
        written = write_outputs(mechanism, interrupt.result, settings)
        _report(f"interrupted: wrote {_count_samples(interrupt.result)} of {settings.times.size} samples to "
                f"{settings.directory}: {', '.join(path.name for path in written)}")
        return EXIT_INTERRUPTED
    timeline.solved = time.perf_counter()
    written = write_outputs(mechanism, result, settings)
    print(_summary(mechanism, result, timeline, written))
    return EXIT_SUCCESS


def resolve_run_settings(arguments: argparse.Namespace, mechanism: Mechanism) -> RunSettings:
    """Combine the options with the model's ``[analysis]`` defaults and check them.

    Raises
    ------
    CommandError
        If no end time is given, a number is out of range, a point is unknown, or
        ``--quasi-static`` is given for a run that computes no forces.
    """
    analysis = mechanism.analysis
    times = resolve_times(arguments, mechanism)
    steps = times.size
    notes = []
    if getattr(arguments, "points", None) is not None:
        point_names = parse_point_names(arguments.points, mechanism)
    elif analysis.points is not None:
        point_names = analysis.points
    elif len(mechanism.points) <= MAX_DEFAULT_POINTS:
        point_names = tuple(mechanism.points)
    else:
        point_names = ()
        notes.append(f"{len(mechanism.points)} named points: none written (give --points A,B or [analysis].points)")
    joint_text = getattr(arguments, "joints", None)
    if joint_text is not None:
        joint_indices = parse_joint_names(joint_text, mechanism)
    elif mechanism.n_joints <= MAX_DEFAULT_JOINTS:
        joint_indices = tuple(k for k, joint in enumerate(mechanism.joints) if type(joint).output_names)
    else:
        joint_indices = ()
        notes.append(f"{mechanism.n_joints} joints: none written to joints.csv (give --joints J1,J2 or all)")
    coordinates = getattr(arguments, "coordinates", None)
    if coordinates is None:
        coordinates = steps * mechanism.n_coordinates <= MAX_DEFAULT_VALUES
        if not coordinates:
            notes.append(f"{steps} samples of {mechanism.n_coordinates} coordinates: not written (give "
                         "--coordinates, or --format zarr --coordinates to stream them)")  # fmt: skip
    force_text = getattr(arguments, "forces", None)
    n_elements = mechanism.n_drivers + mechanism.n_joints
    if force_text is not None:
        forces = parse_force_elements(force_text, mechanism)
    elif not mechanism.has_forces:
        forces = None
    elif n_elements <= MAX_DEFAULT_FORCE_ELEMENTS:
        forces = "all"
    else:
        forces = None
        notes.append(f"{n_elements} drivers and joints: no forces written (give --forces D1,J2 or all)")
    quasi_static = bool(getattr(arguments, "quasi_static", False))
    if quasi_static and forces is None:
        if force_text is not None:
            why = "--forces none leaves every force out"
        elif not mechanism.has_forces:
            why = "the model has no mass or load, so no forces are computed (give --forces D1,J2 or all)"
        else:
            why = f"{n_elements} drivers and joints: no forces are computed by default (give --forces D1,J2 or all)"
        raise CommandError(f"--quasi-static changes the forces, but {why}")
    directory = arguments.out if arguments.out is not None else DEFAULT_OUTPUT_ROOT / mechanism.name
    return RunSettings(
        times, tuple(point_names), directory, arguments.plot, joint_indices, coordinates,
        getattr(arguments, "format", "csv"), getattr(arguments, "quiet", False), tuple(notes), forces, quasi_static,
    )  # fmt: skip


def resolve_times(arguments: argparse.Namespace, mechanism: Mechanism) -> np.ndarray:
    """The sample times from ``--t-end`` and ``--steps``, else the model's ``[analysis]``.

    Raises
    ------
    CommandError
        If no end time is given or a number is out of range.
    """
    analysis = mechanism.analysis
    t_end = arguments.t_end if arguments.t_end is not None else analysis.t_end
    if t_end is None:
        raise CommandError("no end time: give --t-end T or [analysis].t_end in the model file")
    steps = arguments.steps if arguments.steps is not None else (analysis.steps or DEFAULT_STEPS)
    _check_times(t_end, steps)
    return np.linspace(0.0, t_end, steps)


def _check_times(t_end: float, steps: int) -> None:
    """Values out of range can only come from the options: ``[analysis]`` is checked on loading."""
    if not (math.isfinite(t_end) and t_end >= 0.0):
        raise CommandError(f"--t-end must be a finite number >= 0 (s), got {t_end!r}")
    if steps < 1:
        raise CommandError(f"--steps must be a whole number >= 1, got {steps}")
    if t_end == 0.0 and steps > 1:
        raise CommandError(f"t_end = 0 s gives one sample, not {steps}: give --t-end > 0 or --steps 1")


def parse_point_names(text: str, mechanism: Mechanism, option: str = "--points") -> tuple[str, ...]:
    """The point names in the comma-separated `text`, each checked against the model.

    Examples
    --------
    >>> from sparsekin import Body, Mechanism
    >>> model = Mechanism(points={"A": (0, 0), "J": (1, 0)}, bodies=[Body("c1", origin="A")])
    >>> parse_point_names("J, A", model)
    ('J', 'A')
    >>> parse_point_names("A,Q", model)
    Traceback (most recent call last):
    ...
    sparsekin.cli.CommandError: --points: unknown point "Q" (known: A, J)
    """
    if text.strip() in ("none", "all"):
        return () if text.strip() == "none" else tuple(mechanism.points)
    names = tuple(dict.fromkeys(name.strip() for name in text.split(",")))
    for name in names:
        if not name:
            raise CommandError(f"{option}: empty name in {text!r}: expected names separated by commas")
        if name not in mechanism.points:
            known = _validate.known_list(list(mechanism.points), limit=LISTED_POINTS)
            raise CommandError(f'{option}: unknown point "{name}" (known: {known})')
    return names


def parse_joint_names(text: str, mechanism: Mechanism) -> tuple[int, ...]:
    """The indices of the joints named in the comma-separated `text` (``all``, ``none``)."""
    from ..engine.outputs import element_index

    if text.strip() == "none":
        return ()
    if text.strip() == "all":
        return tuple(k for k, joint in enumerate(mechanism.joints) if type(joint).output_names)
    indices = []
    for name in dict.fromkeys(name.strip() for name in text.split(",")):
        try:
            k = element_index(mechanism, "joints", name)
        except KeyError as error:
            raise CommandError(f"--joints: {error.args[0]}") from None
        if not type(mechanism.joints[k]).output_names:
            raise CommandError(f'--joints: "{name}" is a {mechanism.joints[k].type_name} joint, which has no '
                               "coordinate of its own")  # fmt: skip
        indices.append(k)
    return tuple(indices)


def parse_force_elements(text: str, mechanism: Mechanism) -> str | tuple[str, ...] | None:
    """``--forces``: None for ``none``, ``"all"``, or the driver and joint names, each checked."""
    from ..engine.outputs import element_index

    if text.strip() in ("none", "all"):
        return None if text.strip() == "none" else "all"
    names = tuple(dict.fromkeys(name.strip() for name in text.split(",")))
    for name in names:
        if not name:
            raise CommandError(f"--forces: empty name in {text!r}: expected names separated by commas")
        found = False
        for kind in ("drivers", "joints"):
            try:
                element_index(mechanism, kind, name)
                found = True
            except KeyError:
                pass
        if not found:
            raise CommandError(f'--forces: no driver or joint is called "{name}" (expected names, drivers[i] or '
                               "joints[i], all or none)")  # fmt: skip
    return names


def _require_zarr() -> None:
    try:
        import xarray  # noqa: F401
        import zarr  # noqa: F401
    except ImportError:
        raise CommandError('--format zarr needs zarr and xarray: pip install "sparsekin[zarr]"') from None


class _Timeline:
    """When ``run`` started, read its model, solved its first sample and its last."""

    def __init__(self) -> None:
        self.start = time.perf_counter()
        self.read = self.first = self.solved = None
        self.first_done = 0  # samples solved at `first` (a chunk of the compiled loop, or one)


class _Progress:
    """The run's progress callable: notes the first sample's time and moves a tqdm bar on
    stderr, shown once a run has lasted `PROGRESS_DELAY` (not with --quiet, nor when stderr
    is not a terminal)."""

    def __init__(self, settings: RunSettings, timeline: _Timeline) -> None:
        self._timeline, self._bar = timeline, None
        if settings.quiet or not sys.stderr.isatty():
            return
        from tqdm import tqdm  # here: importing it costs a start-up that does not draw a bar

        self._bar = tqdm(total=settings.times.size, unit="sample", delay=PROGRESS_DELAY, file=sys.stderr,
                         dynamic_ncols=True, leave=False)  # fmt: skip

    def __enter__(self):
        return self

    def __call__(self, done: int, total: int) -> None:
        if self._timeline.first is None:
            self._timeline.first, self._timeline.first_done = time.perf_counter(), done
        if self._bar is not None:
            self._bar.update(done - self._bar.n)

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.close()


def _require_matplotlib() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise CommandError('--plot needs matplotlib: pip install "sparsekin[plot]"') from None


def _solve(mechanism: Mechanism, settings: RunSettings, model_path: Path, progress) -> KinematicsResult:
    """`solve_kinematics` recording what `settings` asks for, with its argument and model
    errors reported against the file.

    Warnings (redundant equations left out, limits left) are printed as one line each.
    """
    store = settings.directory / "results.zarr" if settings.format == "zarr" else None
    # With the coordinates in memory, points and joints are derived after the run; a store,
    # or a run without the coordinates, records them while it goes on.
    record = store is not None or not settings.coordinates
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                return solve_kinematics(
                    mechanism, settings.times, coordinates=settings.coordinates,
                    points=settings.point_names if record else None, joints=settings.joint_indices if record else None,
                    forces=settings.forces, quasi_static=settings.quasi_static, store=store, progress=progress,
                )  # fmt: skip
            finally:
                for warning in caught:
                    _report(f"warning: {warning.message}")
    except ModelError as error:
        raise (error if error.file else error.in_file(str(model_path))) from None
    except ValueError as error:  # e.g. the times leave the range of a spline law
        raise CommandError(str(error)) from None


# ---------------------------------------------------------------------- check
def add_check_command(subparsers) -> None:
    """Add ``check MODEL.toml [--time T]``."""
    parser = subparsers.add_parser(
        "check",
        help="report degrees of freedom, redundant equations and free motions of a model",
        description="Assemble the model and report its degrees of freedom (by count and by the rank of "
        "the Jacobian), its redundant equations and its free motions. Exit status 0 when the model is "
        "sound, 1 when it has a problem, 2 on a bad file.",
    )
    parser.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    parser.add_argument("--time", type=float, default=0.0, metavar="T",
                        help="time of the analysis, s (default 0): the drivers take their values then")  # fmt: skip
    parser.set_defaults(handler=check_command)


def check_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin check``: print the report; 0 if the model is sound, else 1.

    Raises
    ------
    CommandError, ModelError
        For a bad time or a bad model file; `main` reports them.
    """
    from ..analysis.check import check_model

    mechanism = load_model(arguments.model)
    if not math.isfinite(arguments.time):
        raise CommandError(f"--time must be a finite number (s), got {arguments.time!r}")
    report = check_model(mechanism, time=arguments.time)
    print(report)
    return EXIT_SUCCESS if report.sound else EXIT_PROBLEM


# ---------------------------------------------------------------------- sweep
#: Variants' values of q, qd and qdd that ``sweep`` writes by default, all variants together.
MAX_DEFAULT_SWEEP_VALUES = MAX_DEFAULT_VALUES


def add_sweep_command(subparsers) -> None:
    """Add ``sweep MODEL.toml --vary PATH=START:STOP:N [...] [--workers N] [--scheduler ADDRESS]``."""
    parser = subparsers.add_parser(
        "sweep",
        help="solve many variants of a model on Dask and write sweep.zarr and variants.csv",
        description="Solve every variant of the model (a grid of parameter values, random samples of a "
        "tolerance study, or both) as an independent analysis on Dask, and write DIR/sweep.zarr (the "
        "recorded motion of every variant) and DIR/variants.csv (each variant's values, status and stop "
        'time). Needs "sparsekin[distributed]".',
    )
    parser.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    parser.add_argument("--vary", action="append", default=[], metavar="PATH=START:STOP:N",
                        help="N values of a parameter from START to STOP; paths joined by commas take the same "
                        "values; several --vary make a grid of every combination")  # fmt: skip
    parser.add_argument("--samples", type=int, metavar="N", help="random variants (at each grid point), with --perturb")
    parser.add_argument("--perturb", action="append", default=[], metavar="points=SIGMA",
                        help="move every point's drawn position by a normal deviation of SIGMA m")  # fmt: skip
    parser.add_argument("--seed", type=int, metavar="S", help="seed of the random deviations (default: fresh, "
                        "written to the store)")  # fmt: skip
    parser.add_argument("--t-end", type=float, metavar="T", help="end time, s (default: [analysis].t_end)")
    parser.add_argument("--steps", type=int, metavar="N", help=f"samples per variant, t = 0 included (default: "
                        f"[analysis].steps, else {DEFAULT_STEPS})")  # fmt: skip
    parser.add_argument("--points", metavar="A,J", help="points recorded, or all or none (default: "
                        f"[analysis].points, else every named point up to {MAX_DEFAULT_POINTS})")  # fmt: skip
    parser.add_argument("--joints", metavar="J1,J2", help="joints recorded, or all or none (default: every joint "
                        f"with an own coordinate up to {MAX_DEFAULT_JOINTS})")  # fmt: skip
    _add_force_arguments(parser, "recorded")
    coordinates = parser.add_mutually_exclusive_group()
    coordinates.add_argument("--no-coordinates", dest="coordinates", action="store_false", default=None,
                             help="leave out every body's coordinates (q, qd, qdd)")
    coordinates.add_argument("--coordinates", dest="coordinates", action="store_true",
                             help=f"write them whatever their size (default: up to {MAX_DEFAULT_SWEEP_VALUES:.0e} "
                             "values over all variants)")  # fmt: skip
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument("--workers", type=int, metavar="N", help="worker processes of the local cluster "
                         "(default: one per core)")  # fmt: skip
    cluster.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler (tcp://host:8786) "
                         "instead of a local cluster")  # fmt: skip
    parser.add_argument("--variants-per-task", type=int, metavar="N", help="variants per Dask task (default: "
                        "four tasks per worker)")  # fmt: skip
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--out", type=Path, metavar="DIR", help=f"output folder (default: ./{DEFAULT_OUTPUT_ROOT}/"
                        "<model name>)")  # fmt: skip
    parser.add_argument("--plot", action="store_true", dest="plot_figures", help="also draw the paths of a point over the variants and "
                        'the stop times against the varied parameter (needs "sparsekin[plot]")')  # fmt: skip
    parser.add_argument("--plot-point", metavar="P", help="with --plot, the point whose paths are drawn (default: "
                        "the first point recorded)")  # fmt: skip
    parser.set_defaults(handler=sweep_command)


def sweep_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin sweep``: 0 once every variant is written (whatever its status),
    2 on a bad argument, 3 if a task failed (the sweep is incomplete), 130 on Ctrl-C.

    Raises
    ------
    CommandError, ModelError, OSError
        For a bad argument, a bad model file or an output folder that cannot be written.
    """
    _require_distributed()
    from ..solve.kinematics import _checked_times
    from ..studies.sweeps import VariantSet, default_worker_count, sweep, write_variants_csv

    mechanism = load_model(arguments.model)
    try:
        variants = VariantSet.from_arguments(arguments.vary, arguments.samples, arguments.perturb, arguments.seed)
        design = variants.bind(mechanism)
    except ValueError as error:  # a ModelError too: the path and what was expected
        raise CommandError(str(error)) from None
    arguments.plot, arguments.format = False, "zarr"
    settings = resolve_run_settings(arguments, mechanism)
    notes = list(settings.notes)
    coordinates = arguments.coordinates
    if coordinates is None:
        values = design.n_variants * settings.times.size * mechanism.n_coordinates
        coordinates = values <= MAX_DEFAULT_SWEEP_VALUES
        notes = [note for note in notes if "coordinates" not in note]
        if not coordinates:
            notes.append(f"{design.n_variants} variants × {settings.times.size} samples × {mechanism.n_coordinates} "
                         "coordinates: not written (give --coordinates)")  # fmt: skip
    if arguments.workers is not None and arguments.workers < 1:
        raise CommandError(f"--workers must be a whole number >= 1, got {arguments.workers}")
    if arguments.variants_per_task is not None and arguments.variants_per_task < 1:
        raise CommandError(f"--variants-per-task must be a whole number >= 1, got {arguments.variants_per_task}")
    try:  # what every variant's run would refuse, e.g. times outside a spline law's range: once, here
        _checked_times(settings.times, mechanism)
    except ValueError as error:
        raise CommandError(str(error)) from None
    if arguments.plot_point is not None and not arguments.plot_figures:
        raise CommandError("--plot-point chooses the point of the sweep's figures: give --plot with it")
    plot_point = None
    if arguments.plot_figures:
        _require_matplotlib()
        points = settings.point_names
        plot_point = arguments.plot_point or (points[0] if points else None)
        if plot_point is None or plot_point not in points:
            raise CommandError(f"--plot-point: {plot_point or 'no point'} is not recorded (recorded: "
                               f"{', '.join(points) or 'none'}): give --points with it")  # fmt: skip
    client = None
    if arguments.scheduler is not None:
        client = _connect(arguments.scheduler)
    settings.directory.mkdir(parents=True, exist_ok=True)
    for note in notes:
        _report(f"note: {note}")
    store = settings.directory / "sweep.zarr"
    bar = None
    if not arguments.quiet and sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=design.n_variants, unit="variant", delay=PROGRESS_DELAY, file=sys.stderr,
                   dynamic_ncols=True, leave=False)  # fmt: skip

    def progress(done: int, total: int) -> None:
        if bar is not None:
            bar.update(done - bar.n)

    try:
        result = sweep(
            mechanism, variants, settings.times, client, workers=arguments.workers, store=store,
            coordinates=coordinates, points=list(settings.point_names), joints=list(settings.joint_indices),
            forces=settings.forces, quasi_static=settings.quasi_static, variants_per_task=arguments.variants_per_task,
            progress=progress,
        )  # fmt: skip
    except KeyboardInterrupt:
        _report(f"interrupted: {store} holds the variants finished so far (status empty for the others)")
        return EXIT_INTERRUPTED
    except (ModelError, CommandError):
        raise
    except Exception as error:  # a task that failed: a lost worker too often, a bug, a scheduler gone
        _report(f"sweep stopped: {type(error).__name__}: {error}")
        return EXIT_STOPPED
    finally:
        if bar is not None:
            bar.close()
        if client is not None:
            client.close()
    written = [store, write_variants_csv(result, settings.directory / "variants.csv")]
    if plot_point is not None:
        from ..plots import plot_stop_times, plot_sweep_paths

        written += [plot_sweep_paths(result, plot_point, settings.directory), plot_stop_times(result, settings.directory)]
    counts = ", ".join(f"{status} {count}" for status, count in result.counts.items())
    if arguments.scheduler:
        workers = "the scheduler's workers"
    elif arguments.workers:
        workers = f"{arguments.workers} worker{'s' * (arguments.workers != 1)}"
    else:
        count = default_worker_count()
        workers = f"{count} worker{'s' * (count != 1)} (one per core)"
    print("\n".join([
        f"{mechanism.name}: {result.n_variants} variants, {settings.times.size} samples each, "
        f"t = 0 … {settings.times[-1]:g} s",
        f"status: {counts}",
        f"{result.n_tasks} tasks on {workers}: {result.wall_time:.3g} s, "
        f"{result.n_variants / max(result.wall_time, 1e-9):.3g} variants/s",
        "wrote:",
        *(f"  {path}" for path in written),
    ]))  # fmt: skip
    return EXIT_SUCCESS


def _require_distributed() -> None:
    try:
        import dask  # noqa: F401
        import distributed  # noqa: F401
        import xarray  # noqa: F401
        import zarr  # noqa: F401
    except ImportError:
        raise CommandError('sweep needs dask, distributed, zarr and xarray: pip install "sparsekin[distributed]"') from None


def _connect(address: str):
    """A client of the scheduler at `address`, or a CommandError saying it cannot be reached."""
    import distributed

    try:
        return distributed.Client(address, timeout=SCHEDULER_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as error:
        raise CommandError(f"--scheduler {address}: cannot reach a Dask scheduler there ({error})") from None


#: Seconds to wait for ``--scheduler ADDRESS`` to answer.
SCHEDULER_TIMEOUT = 10


# ---------------------------------------------------------------------- workspace
def add_workspace_command(subparsers) -> None:
    """Add ``workspace MODEL.toml --point K [--drivers 0,1] [--grid 50] [--range I=START:STOP]``."""
    parser = subparsers.add_parser(
        "workspace",
        help="where a point gets over a grid of two drivers' values, and where the mechanism locks up",
        description="Solve the mechanism over a grid of the values of two drivers (strokes, angles) by "
        "continuation from the configuration at t = 0, and write DIR/workspace.csv (the point's position "
        "and the status of every grid point), DIR/boundary.csv (where the continuation met a singular "
        "configuration) and, with --plot, workspace_<point>.png.",
    )
    parser.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    parser.add_argument("--point", required=True, metavar="K", help="the point whose positions are mapped")
    parser.add_argument("--drivers", default="0,1", metavar="D1,D2",
                        help="the two drivers: indices, names or drivers[i] (default: 0,1)")  # fmt: skip
    parser.add_argument("--grid", default="50", metavar="N[,M]", help="grid values per driver (default: 50)")
    parser.add_argument("--range", action="append", default=[], metavar="D=START:STOP", dest="ranges",
                        help="a driver's range of values, m or rad (default: the span of its law over "
                        "[analysis].t_end, widened twofold)")  # fmt: skip
    parser.add_argument("--out", type=Path, metavar="DIR", help=f"output folder (default: ./{DEFAULT_OUTPUT_ROOT}/"
                        "<model name>)")  # fmt: skip
    parser.add_argument("--plot", action="store_true", help='also draw workspace_<point>.png (needs "sparsekin[plot]")')
    parser.set_defaults(handler=workspace_command)


def workspace_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin workspace``: 0 on success, 2 on a bad argument or model.

    Raises
    ------
    CommandError, ModelError, OSError
    """
    from ..studies.workspaces import workspace

    mechanism = load_model(arguments.model)
    if arguments.point not in mechanism.points:
        known = _validate.known_list(list(mechanism.points), limit=LISTED_POINTS)
        raise CommandError(f'--point: unknown point "{arguments.point}" (known: {known})')
    drivers = [int(d) if d.strip().isdigit() else d.strip() for d in arguments.drivers.split(",")]
    if len(drivers) != 2:
        raise CommandError(f"--drivers: expected two drivers separated by a comma, got {arguments.drivers!r}")
    try:
        grid = tuple(int(n) for n in arguments.grid.split(","))
    except ValueError:
        raise CommandError(f"--grid: expected N or N,M (whole numbers >= 2), got {arguments.grid!r}") from None
    if len(grid) not in (1, 2) or min(grid) < 2:
        raise CommandError(f"--grid: expected N or N,M (whole numbers >= 2), got {arguments.grid!r}")
    ranges = None
    if arguments.ranges:
        given = {}
        for text in arguments.ranges:
            name, equals, span = text.partition("=")
            bounds = span.split(":")
            try:
                key = int(name) if name.strip().isdigit() else name.strip()
                given[drivers.index(key)] = (float(bounds[0]), float(bounds[1]))
                if len(bounds) != 2:
                    raise ValueError
            except (ValueError, IndexError):
                raise CommandError(f"--range {text}: expected D=START:STOP with D one of --drivers "
                                   f"({arguments.drivers})") from None  # fmt: skip
        if len(given) != 2:
            raise CommandError("--range: give the range of both drivers (or of none)")
        ranges = [given[0], given[1]]
    if arguments.plot:
        _require_matplotlib()
    try:
        space = workspace(mechanism, arguments.point, drivers, grid if len(grid) == 2 else grid[0], ranges)
    except ModelError as error:
        raise (error if error.file else error.in_file(str(arguments.model))) from None
    except ConvergenceError as error:
        raise CommandError(f"the model cannot be assembled at t = 0: {error}") from None
    directory = arguments.out if arguments.out is not None else DEFAULT_OUTPUT_ROOT / mechanism.name
    directory.mkdir(parents=True, exist_ok=True)
    written = write_workspace(space, directory)
    if arguments.plot:
        from ..plots import plot_workspace

        written.append(plot_workspace(space, directory))
    counts = ", ".join(f"{status} {int((space.status == status).sum())}" for status in dict.fromkeys(space.status.ravel()))
    print("\n".join([
        f"{mechanism.name}: {arguments.point} over {space.status.shape[1]} × {space.status.shape[0]} values of "
        f"{space.drivers[0]} and {space.drivers[1]}",
        f"grid points: {counts}; singular boundary: {len(space.boundary)} points",
        *([f"limits left: {', '.join(space.limits_left)}"] if space.limits_left else []),
        "wrote:",
        *(f"  {path}" for path in written),
    ]))  # fmt: skip
    return EXIT_SUCCESS


def write_workspace(space, directory: Path) -> list[Path]:
    """Write ``workspace.csv`` (``a``, ``b``, ``status``, ``P.x``, ``P.y`` per grid point, a
    the first driver's value) and ``boundary.csv`` (``a``, ``b``, ``P.x``, ``P.y``)."""
    a_label, b_label = (label.split(" ", 1)[0] for label in space.drivers)
    paths = [directory / "workspace.csv", directory / "boundary.csv"]
    with open(paths[0], "w", encoding="utf-8", newline="") as file:
        file.write(f"{a_label},{b_label},status,{space.point}.x,{space.point}.y\n")
        for j, b in enumerate(space.values[1].tolist()):
            for i, a in enumerate(space.values[0].tolist()):
                x, y = space.positions[j, i].tolist()
                file.write(f"{a!r},{b!r},{space.status[j, i]},{x!r},{y!r}\n")
    with open(paths[1], "w", encoding="utf-8", newline="") as file:
        file.write(f"{a_label},{b_label},{space.point}.x,{space.point}.y\n")
        for (a, b), (x, y) in zip(space.boundary.tolist(), space.boundary_positions.tolist()):
            file.write(f"{a!r},{b!r},{x!r},{y!r}\n")
    return paths


# ---------------------------------------------------------------------- output files
def write_outputs(mechanism: Mechanism, result: KinematicsResult | None, settings: RunSettings) -> list[Path]:
    """Write ``points.csv``, ``joints.csv``, ``coordinates.npz`` and, if asked and possible, the figures.

    Parameters
    ----------
    mechanism : Mechanism
    result : KinematicsResult or None
        The samples solved; None or empty after an early failure (then the files hold no
        rows and no figure is drawn).
    settings : RunSettings

    Returns
    -------
    list of Path
        The files written.
    """
    directory = settings.directory
    if settings.format == "zarr":
        written = [directory / "results.zarr"]
    else:
        written = [
            write_points_csv(result, settings.point_names, directory / "points.csv"),
            write_joints_csv(mechanism, result, directory / "joints.csv", settings.joint_indices),
        ]
        if settings.forces is not None:
            written.append(write_forces_csv(result, directory / "forces.csv"))
        if settings.coordinates:
            written.append(write_coordinates(result, mechanism.body_names, directory / "coordinates.npz"))
    if settings.plot and _count_samples(result) > 0:
        from ..plots import (
            draw_mechanism,
            plot_actuators,
            plot_driver_forces,
            plot_point_motion,
            plot_point_paths,
        )

        written += plot_point_motion(result, settings.point_names, directory)
        written += plot_point_paths(result, settings.point_names, directory)
        written += plot_driver_forces(result, directory)  # from the recorded forces, without the coordinates
        if result.coordinates is None:
            _report("note: actuators.png and mechanism.png need every body's coordinates: give --coordinates")
            return written
        written += plot_actuators(result, directory)
        shown = None
        if mechanism.n_bodies > MAX_DRAWN_BODIES:
            shown = [mechanism.body_names[k] for k in range(MAX_DRAWN_BODIES)]
            _report(f"note: mechanism.png shows the first {MAX_DRAWN_BODIES} of {mechanism.n_bodies} bodies")
        written.append(draw_mechanism(mechanism, result, directory, bodies=shown))
    return written


def write_points_csv(result: KinematicsResult | None, point_names: Sequence[str], path: Path) -> Path:
    """Write time, position, velocity and acceleration of each point, every float by `repr`.

    The header is ``t,A.x,A.y,A.vx,A.vy,A.ax,A.ay,J.x,...``; `repr` writes the shortest
    decimal that reads back as the same double.
    """
    header = ",".join(["t", *(f"{name}.{column}" for name in point_names for column in POINT_COLUMNS)])
    with open(path, "w", encoding="utf-8", newline="") as file:
        file.write(header + "\n")
        file.writelines(",".join(map(repr, row)) + "\n" for row in point_table(result, point_names).tolist())
    return path


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
    header = ",".join(["t", *(f"{label}.{suffix}" for _, label, suffixes in joints for suffix in suffixes)])
    if result is None:
        table = np.empty((0, 1 + 3 * len(joints)))
    else:
        table = np.column_stack([result.times, *(array for index, _, _ in joints for array in result.joint(index))])
    with open(path, "w", encoding="utf-8", newline="") as file:
        file.write(header + "\n")
        file.writelines(",".join(map(repr, row)) + "\n" for row in table.tolist())
    return path


def write_forces_csv(result: KinematicsResult | None, path: Path) -> Path:
    """Write time and the force columns the run recorded, every float by `repr`.

    The header is ``t,motor.force,motor.power,pivot.fx,pivot.fy,...``
    (`sparsekin.engine.forces.ForceOutputs`).  A model with masses or loads but no driver or
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
    with open(path, "w", encoding="utf-8", newline="") as file:
        file.write(",".join(["t", *labels]) + "\n")
        file.writelines(",".join(map(repr, row)) + "\n" for row in table.tolist())
    return path


def write_coordinates(result: KinematicsResult | None, body_names: Sequence[str], path: Path) -> Path:
    """Write arrays ``t``, ``q``, ``qd``, ``qdd`` (n_times × 3·n_bodies) and ``body_names``."""
    if result is None or result.coordinates is None:
        empty = np.empty((0, 3 * len(body_names)))
        arrays = {"t": np.empty(0), "q": empty, "qd": empty, "qdd": empty}
    else:
        arrays = {
            "t": result.times, "q": result.coordinates, "qd": result.velocities, "qdd": result.accelerations
        }
    np.savez(path, **arrays, body_names=np.array(body_names, dtype=str))
    return path


# ---------------------------------------------------------------------- messages
def _count_samples(result: KinematicsResult | None) -> int:
    return 0 if result is None else result.n_times


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


# ---------------------------------------------------------------------- animate
def add_animate_command(subparsers) -> None:
    """Add ``animate MODEL.toml [--out FILE] [--trace K,W] [--t-end T] [--steps N] [--fps F] [--duration D]
    [--at T]``."""
    parser = subparsers.add_parser(
        "animate",
        help="analyse a model and write an animation (GIF or MP4) or one frame of it (PNG)",
        description="Solve the motion as run does and write it as an animation: bodies, joints and "
        "actuators, the paths of the traced points and a time stamp, on axes that hold the whole motion. "
        "Frames are equally spaced in time and interpolated between the samples, so the clip plays in real "
        "time (or lasts --duration) whatever the number of samples. When the analysis stops (a lock-up), "
        "the clip runs up to the stop and marks it, and the exit status is 3.",
    )
    parser.add_argument("model", type=Path, metavar="MODEL.toml", help="the model file")
    parser.add_argument(
        "--out", type=Path, metavar="FILE", help="run.gif, run.mp4, or frame.png for one frame (default: "
        f"./{DEFAULT_OUTPUT_ROOT}/<model name>/animation.gif)"
    )
    parser.add_argument(
        "--trace", metavar="K,W", help="points whose paths are drawn, separated by commas, or none (default: "
        "[analysis].points, else none)"
    )
    parser.add_argument("--t-end", type=float, metavar="T", help="end time, s (default: [analysis].t_end)")
    parser.add_argument(
        "--steps", type=int, metavar="N", help=f"number of samples, t = 0 included (default: "
        f"[analysis].steps, else {DEFAULT_STEPS})"
    )
    parser.add_argument("--fps", type=float, metavar="F", help="frames per second (default 20 for a GIF, at most "
                        "50; 30 for an MP4)")  # fmt: skip
    parser.add_argument("--duration", type=float, metavar="D",
                        help="length of the clip, s (default: the analysed time, real time)")  # fmt: skip
    parser.add_argument("--at", type=float, metavar="T", help="time of the frame of a .png (default: the end)")
    parser.set_defaults(handler=animate_command)


def animate_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin animate``; returns the exit status.

    Raises
    ------
    CommandError, ModelError, OSError
        For a bad argument, a bad model file, a missing optional dependency or a file
        that cannot be written; `main` reports them.
    """
    mechanism = load_model(arguments.model)
    times = resolve_times(arguments, mechanism)
    if arguments.trace is None:
        trace = mechanism.analysis.points or ()
    elif arguments.trace.strip().lower() == "none":
        trace = ()
    else:
        trace = parse_point_names(arguments.trace, mechanism, option="--trace")
    path = arguments.out if arguments.out is not None else DEFAULT_OUTPUT_ROOT / mechanism.name / "animation.gif"
    _check_animation_options(arguments, path, times)
    path.parent.mkdir(parents=True, exist_ok=True)
    # every body's coordinates in memory (frames are drawn from them), nothing written but the clip
    settings = RunSettings(times, (), path.parent, False, (), True, "csv", True, ())
    start = time.perf_counter()
    try:
        result = _solve(mechanism, settings, arguments.model, None)
    except AnalysisInterrupted as interrupt:
        solved = _count_samples(interrupt.result)
        if solved:
            mark = f"interrupted at t = {interrupt.result.times[-1]:.6g} s"
            written = _write_animation(interrupt.result, path, arguments, trace, mark)
            _report(f"interrupted: animated {solved} of {times.size} samples: {written}")
        return EXIT_INTERRUPTED
    except ConvergenceError as error:
        _report(f"analysis stopped: {error}")
        solved = _count_samples(error.result)
        if solved == 0:
            _report(f"no sample solved: nothing to animate, {path} not written")
            return EXIT_STOPPED
        reason = "lock-up" if isinstance(error, SingularConfigurationError) else "no convergence"
        mark = f"analysis stopped: {reason} at t = {error.time:.6g} s"
        written = _write_animation(error.result, path, arguments, trace, mark)
        _report(f"animated {solved} of {times.size} samples (t = 0 … {error.result.times[-1]:g} s): {written}")
        return EXIT_STOPPED
    written = _write_animation(result, path, arguments, trace, None)
    print(f"{mechanism.name}: {result.n_times} samples, t = 0 … {result.times[-1]:g} s\n{written}\n"
          f"wall time: {time.perf_counter() - start:.3g} s\nwrote:\n  {path}")  # fmt: skip
    return EXIT_SUCCESS


def _check_animation_options(arguments: argparse.Namespace, path: Path, times: np.ndarray) -> None:
    """The file type and its optional dependencies, and the numbers, before any solving."""
    from ..plots import DEFAULT_FPS, MAX_GIF_FPS

    suffix = path.suffix.lower()
    if suffix not in (*DEFAULT_FPS, ".png"):
        raise CommandError(f"--out must end in .gif, .mp4 or .png, got {str(path)!r}")
    needed = {".gif": ("PIL", "Pillow"), ".mp4": ("imageio_ffmpeg", "imageio-ffmpeg"), ".png": (None, None)}
    module, package = needed[suffix]
    for name, shown in (("matplotlib", "matplotlib"), (module, package)):
        if name is None:
            continue
        try:
            __import__(name)
        except ImportError:
            raise CommandError(f'{path.name} needs {shown}: pip install "sparsekin[animate]"') from None
    if arguments.fps is not None and not (math.isfinite(arguments.fps) and 0.0 < arguments.fps):
        raise CommandError(f"--fps must be a number > 0, got {arguments.fps!r}")
    if arguments.fps is not None and suffix == ".gif" and arguments.fps > MAX_GIF_FPS:
        raise CommandError(f"--fps must be at most {MAX_GIF_FPS:g} for a GIF (browsers slow faster GIFs "
                           f"down), got {arguments.fps!r}")  # fmt: skip
    if arguments.duration is not None and not (math.isfinite(arguments.duration) and arguments.duration > 0.0):
        raise CommandError(f"--duration must be a number of seconds > 0, got {arguments.duration!r}")
    if arguments.at is not None and not (math.isfinite(arguments.at) and 0.0 <= arguments.at <= times[-1]):
        raise CommandError(f"--at must be a time within the analysis, 0 … {times[-1]:g} s, got {arguments.at!r}")
    if arguments.at is not None and suffix != ".png":
        raise CommandError("--at chooses the time of one frame: give --out FILE.png with it")


def _write_animation(result: KinematicsResult, path: Path, arguments, trace, stopped: str | None) -> str:
    """Write the clip or the frame; a line saying what was written."""
    from ..plots import animate, save_frame

    if path.suffix.lower() == ".png":
        at = arguments.at if arguments.at is not None and arguments.at <= result.times[-1] else None
        save_frame(result, path, at, trace=trace, stopped=stopped)
        return f"frame at t = {result.times[-1] if at is None else at:g} s"
    clip = animate(result, path, trace=trace, fps=arguments.fps, duration=arguments.duration, stopped=stopped)
    return f"animation: {clip.n_frames} frames at {clip.fps:g} fps, {clip.duration:g} s"


#: The subcommands: each adds its parser and sets ``handler`` to the function running it.
SUBCOMMANDS = (add_run_command, add_check_command, add_sweep_command, add_workspace_command, add_animate_command)
