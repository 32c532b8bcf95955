"""``sparsekin animate``: a model's motion as an animation or one frame of it."""

from __future__ import annotations

import argparse
import errno
import math
import os
import time
from pathlib import Path

import numpy as np

from ..errors import AnalysisInterrupted, ConvergenceError, SingularConfigurationError
from ..results.kinematics import KinematicsResult
from . import signals
from .common import EXIT_STOPPED, EXIT_SUCCESS, CommandError, report
from .files import count_samples
from .outputs import written_whole
from .run import add_dynamics_arguments, is_dynamics, solve_for_command
from .settings import (
    DEFAULT_OUTPUT_ROOT,
    RunSettings,
    add_label_argument,
    add_time_arguments,
    parse_point_names,
    read_model,
    resolve_times,
)
from .sizes import add_memory_argument, animation_parts, check_memory, limit_for, run_parts


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
    add_time_arguments(parser)
    parser.add_argument("--fps", type=float, metavar="F", help="frames per second (default 20 for a GIF, at most "
                        "50; 30 for an MP4)")  # fmt: skip
    parser.add_argument("--duration", type=float, metavar="D",
                        help="length of the clip, s (default: the analysed time, real time)")  # fmt: skip
    parser.add_argument("--at", type=float, metavar="T", help="time of the frame of a .png (default: the end)")
    add_label_argument(parser)
    add_dynamics_arguments(parser, "")
    add_memory_argument(parser)
    parser.set_defaults(handler=animate_command)


def animate_command(arguments: argparse.Namespace) -> int:
    """Carry out ``sparsekin animate``; returns the exit status.

    Raises
    ------
    CommandError, ModelError, OSError
        For a bad argument, a bad model file, a missing optional dependency or a file
        that cannot be written; `main` reports them.
    """
    mechanism = read_model(arguments)
    times = resolve_times(arguments, mechanism)
    dynamics = is_dynamics(arguments, mechanism)
    if arguments.trace is None:
        trace = mechanism.analysis.points or ()
    elif arguments.trace.strip().lower() == "none":
        trace = ()
    else:
        trace = parse_point_names(arguments.trace, mechanism, option="--trace")
    path = arguments.out if arguments.out is not None else DEFAULT_OUTPUT_ROOT / mechanism.name / "animation.gif"
    _check_animation_options(arguments, path, times)
    _check_writable(path)
    # every body's coordinates in memory (frames are drawn from them), nothing written but the clip
    settings = RunSettings(times, (), path.parent, False, (), True, "csv", True, ())
    check_memory(run_parts(mechanism, settings) | _animation_parts(arguments, path, times), limit_for(arguments),
                 "give a shorter --duration, a lower --fps, fewer --steps, or write an MP4")  # fmt: skip
    start = time.perf_counter()
    try:
        result = solve_for_command(mechanism, settings, arguments.model, None, dynamics=dynamics,
                                   max_step=arguments.max_step, rtol=arguments.rtol)  # fmt: skip
    except AnalysisInterrupted as interrupt:
        solved = count_samples(interrupt.result)
        if solved:
            mark = f"interrupted at t = {interrupt.result.times[-1]:.6g} s"
            written = _write_animation(interrupt.result, path, arguments, trace, mark)
            report(f"{signals.interrupted()}: animated {solved} of {times.size} samples: {written}")
        else:
            report(f"{signals.interrupted()}: nothing solved yet, {path} not written")
        return signals.exit_status()
    except ConvergenceError as error:
        report(f"analysis stopped: {error}")
        solved = count_samples(error.result)
        if solved == 0:
            report(f"no sample solved: nothing to animate, {path} not written")
            return EXIT_STOPPED
        reason = "lock-up" if isinstance(error, SingularConfigurationError) else "no convergence"
        mark = f"analysis stopped: {reason} at t = {error.time:.6g} s"
        written = _write_animation(error.result, path, arguments, trace, mark)
        report(f"animated {solved} of {times.size} samples (t = 0 … {error.result.times[-1]:g} s): {written}")
        return EXIT_STOPPED
    written = _write_animation(result, path, arguments, trace, None)
    print(f"{mechanism.name}: {result.n_times} samples, t = 0 … {result.times[-1]:g} s\n{written}\n"
          f"wall time: {time.perf_counter() - start:.3g} s\nwrote:\n  {path}")  # fmt: skip
    return EXIT_SUCCESS if signals.received() is None else signals.exit_status()


def _check_animation_options(arguments: argparse.Namespace, path: Path, times: np.ndarray) -> None:
    """The file type and its optional dependencies, and the numbers, before any solving."""
    from ..plots.animation import DEFAULT_FPS, MAX_GIF_FPS

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


def _animation_parts(arguments: argparse.Namespace, path: Path, times: np.ndarray) -> dict[str, int]:
    """What the frames of the clip hold (`animation_parts`): none for a PNG."""
    from ..plots.animation import DEFAULT_FPS, FRAME_DPI, FRAME_SIZE

    suffix = path.suffix.lower()
    if suffix == ".png":
        return {}
    fps = arguments.fps if arguments.fps is not None else DEFAULT_FPS[suffix]
    duration = arguments.duration if arguments.duration is not None else float(times[-1])
    pixels = int(FRAME_SIZE[0] * FRAME_DPI) * int(FRAME_SIZE[1] * FRAME_DPI)
    return animation_parts(max(1, round(duration * fps)), suffix == ".gif", pixels)


def _check_writable(path: Path) -> None:
    """The clip's folder (created) can be written and `path` is not a folder: before any solving."""
    if path.is_dir():
        raise CommandError(f"--out {path}: is a folder; give a file name ending in .gif, .mp4 or .png")
    if path.parent.exists() and not path.parent.is_dir():
        raise CommandError(f"--out {path}: {path.parent} is a file, not a folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    if not os.access(path.parent, os.W_OK):
        raise OSError(errno.EACCES, "Permission denied", str(path.parent))


def _write_animation(result: KinematicsResult, path: Path, arguments, trace, stopped: str | None) -> str:
    """Write the clip or the frame (at a temporary name, renamed to `path` once complete,
    signals held meanwhile); a line saying what was written."""
    from ..plots import animate, save_frame

    with signals.holding(), written_whole(path) as partial:
        if path.suffix.lower() == ".png":
            at = arguments.at if arguments.at is not None and arguments.at <= result.times[-1] else None
            save_frame(result, partial, at, trace=trace, stopped=stopped, labels=arguments.labels)
            return f"frame at t = {result.times[-1] if at is None else at:g} s"
        clip = animate(result, partial, trace=trace, fps=arguments.fps, duration=arguments.duration, stopped=stopped,
                       labels=arguments.labels)  # fmt: skip
        return f"animation: {clip.n_frames} frames at {clip.fps:g} fps, {clip.duration:g} s"
