"""``sparsekin check``: a model's degrees of freedom, rank, redundant equations and free motions."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from .common import EXIT_PROBLEM, EXIT_SUCCESS, CommandError
from .settings import read_model


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

    mechanism = read_model(arguments)
    if not math.isfinite(arguments.time):
        raise CommandError(f"--time must be a finite number (s), got {arguments.time!r}")
    report = check_model(mechanism, time=arguments.time)
    print(report)
    return EXIT_SUCCESS if report.sound else EXIT_PROBLEM
