"""The ``sparsekin`` command line.

``sparsekin run MODEL.toml`` reads a model file, runs the kinematic analysis and writes
``points.csv``, ``joints.csv`` and ``coordinates.npz`` (``--format zarr``: one Zarr store;
with ``--plot``, also PNG figures) as described in ``docs/model-format.md``.  On a large
model it writes what a person can use by default (`~sparsekin.cli.settings.DEFAULT_RULE`).
A progress bar shows on stderr for runs longer than two seconds.  Exit status: 0 on success, 2 on a bad model
or bad arguments (one line on stderr, no traceback; a size beyond the memory, or a folder
another run is writing, too), 3 when the analysis stops or the disk is full, and 130 on
Ctrl-C, 143 on SIGTERM, 129 on SIGHUP (in these cases the samples solved so far are still
written).  Files are renamed into place once whole and ``run.json`` is written last
(`~sparsekin.cli.outputs`); signals are handled in `~sparsekin.cli.signals`, sizes in
`~sparsekin.cli.sizes`.

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

Each subcommand is a module (`run`, `check`, `sweep`, `workspace`, `animate`) holding a pair
of functions: one adds its parser to the subparsers, the other runs it and returns the exit
status.  `SUBCOMMANDS` lists the first of each pair, so a new subcommand only needs its
module and one entry there.  What they share: `~sparsekin.cli.common` (exit statuses, usage
errors, one-line reports, optional dependencies, the progress bar), `~sparsekin.cli.settings`
(the options combined with the model's ``[analysis]``) and `~sparsekin.cli.files` (the CSV
files, written once).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from ..errors import ModelError
from . import signals
from .animate import add_animate_command
from .check import add_check_command
from .common import EXIT_USAGE, PROGRAM, CommandError, report
from .run import add_run_command
from .sweep import add_sweep_command
from .warning_lines import one_line_warnings
from .workspace import add_workspace_command

__all__ = ["main", "build_parser"]

#: The subcommands: each adds its parser and sets ``handler`` to the function running it.
SUBCOMMANDS = (add_run_command, add_check_command, add_sweep_command, add_workspace_command, add_animate_command)


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
    command = argv is None  # the process is the command: it ends with it
    argv = sys.argv[1:] if command else list(argv)
    parser = build_parser()
    try:
        arguments = parser.parse_args(argv)
    except SystemExit as exit_request:  # usage errors and --help: argparse has printed
        return int(exit_request.code or 0)
    arguments.command_line = [PROGRAM, *argv]
    with signals.stop_on_signals(then_ignore=command):
        try:
            with one_line_warnings(PROGRAM):
                return arguments.handler(arguments)
        except (CommandError, ModelError) as error:
            report(f"error: {error}")
        except OSError as error:  # an output folder or file that cannot be written
            report(f"error: {error.filename}: {error.strerror}" if error.filename else f"error: {error}")
        except KeyboardInterrupt:  # before any sample was solved (the commands handle it after)
            report(f"{signals.interrupted()}: nothing solved yet, nothing written")
            return signals.exit_status()
    return EXIT_USAGE


def build_parser() -> argparse.ArgumentParser:
    """The argument parser, with one subparser per entry of `SUBCOMMANDS`."""
    parser = argparse.ArgumentParser(
        prog=PROGRAM, description="Kinematics and dynamics of planar linkages described in a TOML model file."
    )
    subparsers = parser.add_subparsers(title="commands", dest="command", required=True, metavar="COMMAND")
    for add_subcommand in SUBCOMMANDS:
        add_subcommand(subparsers)
    return parser
