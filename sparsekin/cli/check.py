"""``sparsekin check``: a model's degrees of freedom, rank, redundant equations and free motions (and,
for forward dynamics, where a run starts)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import warnings
from pathlib import Path

from ..errors import ModelError, RedundantConstraintWarning
from .common import EXIT_PROBLEM, EXIT_SUCCESS, CommandError
from .run import is_dynamics
from .settings import read_model


def add_check_command(subparsers) -> None:
    """Add ``check MODEL.toml [--time T] [--dynamics]``."""
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
    parser.add_argument("--dynamics", action="store_true", default=None,
                        help='check the model for forward dynamics (as [analysis] type = "dynamics"): its free '
                        "motions are its degrees of freedom, and two lines say how far a run moves the drawing and "
                        "the given velocities to start")  # fmt: skip
    parser.set_defaults(handler=check_command)


def check_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin check``: print the report; 0 if the model is sound, else 1.

    Raises
    ------
    CommandError, ModelError
        For a bad time or a bad model file; `main` reports them.
    """
    from ..analysis.check import check_model

    mechanism = read_model(arguments)
    if not math.isfinite(arguments.time):
        raise CommandError(f"--time must be a finite number (s), got {arguments.time!r}")
    report = check_model(mechanism, time=arguments.time)
    if is_dynamics(arguments, mechanism):
        report = dataclasses.replace(report, under_forces=True, **_initial_state(mechanism, arguments.time))
    print(report)
    return EXIT_SUCCESS if report.sound else EXIT_PROBLEM


def _initial_state(mechanism, time: float) -> dict:
    """The report's lines on where a forward-dynamics run starts
    (`sparsekin.solve.initial_state`), or the problem that it cannot."""
    from ..solve.initial_state import initial_state_change, initial_state_lines

    try:
        with warnings.catch_warnings():  # the report lists the redundant equations already
            warnings.simplefilter("ignore", RedundantConstraintWarning)
            change = initial_state_change(mechanism, time)
        return {"initial_state": initial_state_lines(change, mechanism)}
    except ModelError as error:
        return {"initial_state": (f"initial state (dynamics): cannot start: {error}",),
                "cannot_start": "a forward-dynamics run cannot start"}  # fmt: skip
