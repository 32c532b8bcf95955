"""``sparsekin workspace``: where a point gets over a grid of two drivers' values."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..errors import ConvergenceError, ModelError
from ..model import _validate
from . import signals
from .common import EXIT_SUCCESS, CommandError, require_matplotlib
from .files import write_workspace
from .outputs import OutputFolder, manifest
from .settings import (
    LISTED_POINTS,
    add_folder_argument,
    output_folder,
    read_model,
)
from .sizes import add_memory_argument, check_memory, limit_for, workspace_parts


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
    add_folder_argument(parser)
    add_memory_argument(parser)
    parser.add_argument("--plot", action="store_true", help='also draw workspace_<point>.png (needs "sparsekin[plot]")')
    parser.set_defaults(handler=workspace_command)


def workspace_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin workspace``: 0 on success, 2 on a bad argument or model.

    Raises
    ------
    CommandError, ModelError, OSError
    """
    from ..studies.workspaces import workspace

    mechanism = read_model(arguments)
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
        require_matplotlib()
    check_memory(workspace_parts(mechanism, math.prod(grid) if len(grid) == 2 else grid[0] ** 2),
                 limit_for(arguments), "give a coarser --grid")  # fmt: skip
    with OutputFolder(output_folder(arguments, mechanism), "workspace", ["workspace.csv", "boundary.csv"]) as folder:
        try:
            space = workspace(mechanism, arguments.point, drivers, grid if len(grid) == 2 else grid[0], ranges)
        except ModelError as error:
            raise (error if error.file else error.in_file(str(arguments.model))) from None
        except ConvergenceError as error:
            raise CommandError(f"the model cannot be assembled at t = 0: {error}") from None
        with signals.holding():
            staged = write_workspace(space, folder.staging)
            if arguments.plot:
                from ..plots import plot_workspace

                staged.append(plot_workspace(space, folder.staging))
            exit_status = EXIT_SUCCESS if signals.received() is None else signals.exit_status()
            record = manifest(arguments.command_line, arguments.model, "complete", exit_status,
                              {"grid_points": int(space.status.size)})  # fmt: skip
            written = folder.commit(staged, [], record)
    counts = ", ".join(f"{status} {int((space.status == status).sum())}" for status in dict.fromkeys(space.status.ravel()))
    print("\n".join([
        f"{mechanism.name}: {arguments.point} over {space.status.shape[1]} × {space.status.shape[0]} values of "
        f"{space.drivers[0]} and {space.drivers[1]}",
        f"grid points: {counts}; singular boundary: {len(space.boundary)} points",
        *([f"limits left: {', '.join(space.limits_left)}"] if space.limits_left else []),
        "wrote:",
        *(f"  {path}" for path in written),
    ]))  # fmt: skip
    return exit_status
