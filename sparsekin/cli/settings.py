"""What ``run`` (and ``sweep``, ``animate``) compute: the options combined with the model's
``[analysis]`` defaults (`RunSettings`), the sample times and the named points, joints and
forces, each checked against the model."""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..model import _validate
from ..model.mechanism import Mechanism
from ..model.modelfile import load_model
from .common import CommandError
from .sizes import check_model_document, check_times, limit_for

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
#: Samples of ``sparsekin run`` when neither ``--steps`` nor ``[analysis].steps`` is given.
DEFAULT_STEPS = 101
#: Parent of the default output folder, ``./sparsekin-out/<model name>``.
DEFAULT_OUTPUT_ROOT = Path("sparsekin-out")
#: Most point names listed in the message about an unknown point.
LISTED_POINTS = 20


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
    labels : {"all", "joints", "none"}
        What ``mechanism.png`` labels.
    abscissa : str or None
        The driver whose value the motion figures are plotted against (None: time).
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
    labels: str = "all"
    abscissa: str | None = None


def read_model(arguments: argparse.Namespace) -> Mechanism:
    """The model file of a command, its repeats counted first: one whose copies would not
    fit in memory is refused before they are built (`check_model_document`)."""
    import tomllib

    path = Path(arguments.model)
    try:
        if path.is_file() and path.stat().st_size <= MAX_PRECHECK_BYTES:
            document = tomllib.loads(path.read_bytes().decode("utf-8-sig"))
            check_model_document(document, limit_for(arguments))
    except (OSError, ValueError, RecursionError):  # not a model file: `load_model` says what is wrong
        pass
    return load_model(path)


#: Model files larger than this are not read twice (a model at scale repeats a unit).
MAX_PRECHECK_BYTES = 16 * 2**20


def add_time_arguments(parser, samples: str = "number of samples") -> None:
    """``--t-end`` and ``--steps`` (of ``run``, ``sweep`` and ``animate``; `resolve_times`)."""
    parser.add_argument("--t-end", type=float, metavar="T", help="end time, s (default: [analysis].t_end)")
    parser.add_argument("--steps", type=int, metavar="N", help=f"{samples}, t = 0 included (default: "
                        f"[analysis].steps, else {DEFAULT_STEPS})")  # fmt: skip


def add_folder_argument(parser) -> None:
    """``--out DIR`` (of ``run``, ``sweep`` and ``workspace``; `output_folder`)."""
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help=f"output folder (default: ./{DEFAULT_OUTPUT_ROOT}/<model name>)")  # fmt: skip


def output_folder(arguments: argparse.Namespace, mechanism: Mechanism) -> Path:
    """``--out``, else ``./sparsekin-out/<model name>``."""
    return arguments.out if arguments.out is not None else DEFAULT_OUTPUT_ROOT / mechanism.name


def add_force_arguments(parser, where: str) -> None:
    """``--forces`` and ``--quasi-static`` (of ``run`` and ``sweep``)."""
    parser.add_argument(
        "--forces", metavar="D1,J2", help=f"drivers and joints whose forces are {where}, separated by commas, or all "
        f"or none (default, for a model with a mass or a load: all of them if there are at most "
        f"{MAX_DEFAULT_FORCE_ELEMENTS})"
    )
    parser.add_argument("--quasi-static", action="store_true",
                        help="forces without the inertial forces: what holds the mechanism still in each position")


def resolve_run_settings(arguments: argparse.Namespace, mechanism: Mechanism) -> RunSettings:
    """Combine the options with the model's ``[analysis]`` defaults and check them.

    `arguments` are those of ``run`` or of a command that shares its options (``sweep``):
    an option the command does not have takes its default.

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
    directory = output_folder(arguments, mechanism)
    return RunSettings(
        times, tuple(point_names), directory, getattr(arguments, "plot", False), joint_indices, coordinates,
        getattr(arguments, "format", "csv"), getattr(arguments, "quiet", False), tuple(notes), forces, quasi_static,
        getattr(arguments, "labels", "all"), _abscissa(arguments, mechanism),
    )  # fmt: skip


def add_label_argument(parser) -> None:
    """``--labels none|joints|all`` (of ``run --plot`` and ``animate``)."""
    parser.add_argument("--labels", choices=("none", "joints", "all"), default="all",
                        help="what the drawings of the mechanism label: every point and body (all, the default), "
                        "the points where joints are (joints), or nothing (none)")  # fmt: skip


def _abscissa(arguments: argparse.Namespace, mechanism: Mechanism) -> str | None:
    """The driver of ``--abscissa DRIVER``, checked; None without it."""
    driver = getattr(arguments, "abscissa", None)
    if driver is None:
        return None
    from ..engine.outputs import element_index

    try:
        element_index(mechanism, "drivers", driver)
    except KeyError as error:
        raise CommandError(f"--abscissa: {error.args[0]}") from None
    return driver


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
    check_times(steps, limit_for(arguments))
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
    sparsekin.cli.common.CommandError: --points: unknown point "Q" (known: A, J)
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
