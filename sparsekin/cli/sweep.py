"""``sparsekin sweep``: many variants of a model on Dask, written to ``sweep.zarr`` and
``variants.csv``."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import ModelError
from . import signals
from .common import (
    EXIT_STOPPED,
    EXIT_SUCCESS,
    CommandError,
    ProgressBar,
    report,
    require_matplotlib,
)
from .outputs import OutputFolder, manifest
from .run import add_dynamics_arguments, is_dynamics
from .settings import (
    MAX_DEFAULT_JOINTS,
    MAX_DEFAULT_POINTS,
    MAX_DEFAULT_VALUES,
    add_folder_argument,
    add_force_arguments,
    add_time_arguments,
    read_model,
    resolve_run_settings,
)
from .sizes import add_memory_argument, check_memory, limit_for, sweep_parts

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
    add_time_arguments(parser, "samples per variant")
    parser.add_argument("--points", metavar="A,J", help="points recorded, or all or none (default: "
                        f"[analysis].points, else every named point up to {MAX_DEFAULT_POINTS})")  # fmt: skip
    parser.add_argument("--joints", metavar="J1,J2", help="joints recorded, or all or none (default: every joint "
                        f"with an own coordinate up to {MAX_DEFAULT_JOINTS})")  # fmt: skip
    add_force_arguments(parser, "recorded")
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
    add_dynamics_arguments(parser, "; each variant's energy and drift go to sweep.zarr")
    add_folder_argument(parser)
    add_memory_argument(parser)
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
    from ..solve.options import check_times
    from ..studies.sweeps import VariantSet, default_worker_count, sweep, write_variants_csv

    mechanism = read_model(arguments)
    dynamics = is_dynamics(arguments, mechanism)
    columns = len(arguments.vary) + (2 * len(mechanism.points) if arguments.perturb else 0)
    check_memory(sweep_parts(mechanism, _requested_variants(arguments), max(1, columns)), limit_for(arguments),
                 "give fewer values to --vary or fewer --samples")  # before the values are made: fmt: skip
    try:
        variants = VariantSet.from_arguments(arguments.vary, arguments.samples, arguments.perturb, arguments.seed)
        design = variants.bind(mechanism)
    except ValueError as error:  # a ModelError too: the path and what was expected
        raise CommandError(str(error)) from None
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
        check_times(settings.times, mechanism)
    except ValueError as error:
        raise CommandError(str(error)) from None
    if arguments.plot_point is not None and not arguments.plot_figures:
        raise CommandError("--plot-point chooses the point of the sweep's figures: give --plot with it")
    plot_point = None
    if arguments.plot_figures:
        require_matplotlib()
        points = settings.point_names
        plot_point = arguments.plot_point or (points[0] if points else None)
        if plot_point is None or plot_point not in points:
            raise CommandError(f"--plot-point: {plot_point or 'no point'} is not recorded (recorded: "
                               f"{', '.join(points) or 'none'}): give --points with it")  # fmt: skip
    analysis = _analysis_keywords(arguments, settings, dynamics)
    with OutputFolder(settings.directory, "sweep", ["sweep.zarr", "variants.csv"]) as folder:
        client = None
        if arguments.scheduler is not None:
            client = _connect(arguments.scheduler)
        for note in notes:
            report(f"note: {note}")
        folder.clean(keep=["sweep.zarr"])  # the store is written in place from the first task on
        store = settings.directory / "sweep.zarr"
        record = {"variants_requested": design.n_variants}
        try:
            with ProgressBar(design.n_variants, "variant", arguments.quiet) as progress:
                result = sweep(
                    mechanism, variants, settings.times, client, workers=arguments.workers, store=store,
                    coordinates=coordinates, points=list(settings.point_names), joints=list(settings.joint_indices),
                    forces=settings.forces, variants_per_task=arguments.variants_per_task, progress=progress,
                    **analysis,
                )  # fmt: skip
        except KeyboardInterrupt:
            with signals.holding():
                status = signals.exit_status()
                folder.commit([], [store], _manifest(arguments, "interrupted", status, record))
                report(f"{signals.interrupted()}: {store} holds the variants finished so far (status empty for the "
                       "others)")  # fmt: skip
            return status
        except (ModelError, CommandError):
            raise
        except Exception as error:  # a task that failed: a lost worker too often, a bug, a scheduler gone
            folder.commit([], [store], _manifest(arguments, "stopped", EXIT_STOPPED, record))
            report(f"sweep stopped: {type(error).__name__}: {error}")
            return EXIT_STOPPED
        finally:
            if client is not None:
                client.close()
        with signals.holding():
            staged = [write_variants_csv(result, folder.staged("variants.csv"))]
            if plot_point is not None:
                from ..plots import plot_stop_times, plot_sweep_paths

                staged += [plot_sweep_paths(result, plot_point, folder.staging), plot_stop_times(result, folder.staging)]
            exit_status = EXIT_SUCCESS if signals.received() is None else signals.exit_status()
            written = folder.commit(staged, [store], _manifest(arguments, "complete", exit_status, record))
    counts = ", ".join(f"{status} {count}" for status, count in result.counts.items())
    if arguments.scheduler:
        workers = "the scheduler's workers"
    elif arguments.workers:
        workers = f"{arguments.workers} worker{'s' * (arguments.workers != 1)}"
    else:
        count = default_worker_count()
        workers = f"{count} worker{'s' * (count != 1)} (one per core)"
    analysed = "forward dynamics, " if dynamics else ""
    print("\n".join([
        f"{mechanism.name}: {result.n_variants} variants, {analysed}{settings.times.size} samples each, "
        f"t = 0 … {settings.times[-1]:g} s",
        f"status: {counts}",
        f"{result.n_tasks} tasks on {workers}: {result.wall_time:.3g} s, "
        f"{result.n_variants / max(result.wall_time, 1e-9):.3g} variants/s",
        "wrote:",
        *(f"  {path}" for path in written),
    ]))  # fmt: skip
    return exit_status


def _analysis_keywords(arguments: argparse.Namespace, settings, dynamics: bool) -> dict:
    """The keywords of `sparsekin.sweep` that say what each variant's run is (checked)."""
    if dynamics:
        from ..solve.options import DynamicsOptions

        if settings.quasi_static:
            raise CommandError("--quasi-static is for kinematic runs: forward dynamics has the accelerations of "
                               "its motion")  # fmt: skip
        for option, keywords in (("--max-step", {"max_step": arguments.max_step}), ("--rtol", {"rtol": arguments.rtol})):
            try:
                DynamicsOptions(**keywords)
            except ValueError as error:
                raise CommandError(f"{option}: {error}") from None
        return {"analysis": "dynamics", "max_step": arguments.max_step, "rtol": arguments.rtol}
    return {"analysis": "kinematics", "quasi_static": settings.quasi_static}


def _requested_variants(arguments: argparse.Namespace) -> int:
    """The variants the options ask for, counted from their text (the N of each
    ``--vary PATH=START:STOP:N`` that reads as a whole number, times ``--samples``)."""
    count = max(1, arguments.samples or 1)
    for text in arguments.vary:
        try:
            count *= max(1, int(text.rsplit(":", 1)[-1]))
        except ValueError:  # `VariantSet.from_arguments` says what is wrong with it
            pass
    return count


def _manifest(arguments: argparse.Namespace, status: str, exit_status: int, counts: dict) -> dict:
    return manifest(arguments.command_line, arguments.model, status, exit_status, counts)


def _require_distributed() -> None:
    try:
        import dask  # noqa: F401
        import distributed  # noqa: F401
        import xarray  # noqa: F401
        import zarr  # noqa: F401
    except ImportError:
        raise CommandError('sweep needs dask, distributed, zarr and xarray: pip install "sparsekin[distributed]"') from None


#: Seconds to wait for ``--scheduler ADDRESS`` to answer.
SCHEDULER_TIMEOUT = 10


def _connect(address: str, timeout: float = SCHEDULER_TIMEOUT):
    """A client of the scheduler at `address`, or a CommandError saying it cannot be
    reached within `timeout` seconds."""
    import distributed

    try:
        return distributed.Client(address, timeout=timeout)
    except (OSError, TimeoutError, ValueError) as error:
        raise CommandError(f"--scheduler {address}: cannot reach a Dask scheduler there ({error})") from None


