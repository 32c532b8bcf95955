"""A kinematic analysis as an animation (GIF or MP4) or one frame of it (PNG)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..results.kinematics import KinematicsResult
from .canvas import SYMBOL_SCALE
from .common import _dress, _new_figure, _require
from .configuration import _Drawer, _extent, _freeze_limits, label_choice
from .labels import LABEL_BOX

#: Frames per second of an animation, by file type.  A GIF stores frame durations in
#: hundredths of a second: 20 frames per second is 5 of them exactly.
DEFAULT_FPS = {".gif": 20.0, ".mp4": 30.0}
#: Highest frame rate of a GIF: browsers show frames of 1 hundredth of a second or less
#: for 10 hundredths.
MAX_GIF_FPS = 50.0
#: How long the last frame of an animation that stopped early (a lock-up) is held, s.
STOP_HOLD = 1.0
#: Size of an animation frame, inches, and its resolution: 640 × 560 pixels (multiples of
#: 16, as the MP4 encoder wants).
FRAME_SIZE = (8.0, 7.0)
FRAME_DPI = 80
#: Colours of traced paths, in turn.
TRACE_COLOURS = ("tab:red", "tab:purple", "tab:cyan", "tab:olive", "tab:pink", "tab:brown")
#: Colour of the mark of an analysis that stopped.
STOP_COLOUR = "#d62728"


@dataclass(frozen=True)
class Animation:
    """What `animate` wrote.

    Attributes
    ----------
    path : Path
        The file.
    times : ndarray, shape (n_frames,)
        The time shown by each frame, s.  (An MP4 of an analysis that stopped repeats its
        last frame for `STOP_HOLD` seconds; a GIF shows it longer.)
    fps : float
        Frames per second.
    duration : float
        Length of the clip, s, including `STOP_HOLD` when the analysis stopped.
    limits : tuple of float
        ``(x_min, x_max, y_min, y_max)`` of the axes, m, the same in every frame.
    stopped : bool
        The analysis stopped before its end; the last frame marks it.
    """

    path: Path
    times: np.ndarray
    fps: float
    duration: float
    limits: tuple[float, float, float, float]
    stopped: bool

    @property
    def n_frames(self) -> int:
        return self.times.size


def frame_times(result: KinematicsResult, fps: float, duration: float | None = None) -> np.ndarray:
    """The time shown by each frame of a clip of `result`, s.

    A clip of `duration` seconds (default: as long as the analysis, so that it plays in
    real time) at `fps` frames per second has ``round(duration * fps)`` frames (at least
    one); they show equally spaced times from the first sample to the last, both
    included, whatever the number and spacing of the samples.
    """
    start, end = float(result.times[0]), float(result.times[-1])
    if duration is None:
        duration = end - start
    n_frames = max(1, round(duration * fps))
    return np.linspace(start, end, n_frames) if n_frames > 1 else np.array([start])


def interpolate_coordinates(result: KinematicsResult, times) -> np.ndarray:
    """Body coordinates at any `times` within the analysis, by cubic Hermite interpolation.

    Between two samples each coordinate is the cubic that matches its values and its
    velocities (both solved) at the two samples: the error is of order h⁴ in the sample
    spacing h, and a sample time gives the sample exactly.

    Parameters
    ----------
    result : KinematicsResult
    times : array_like, shape (n,)
        Within ``[result.times[0], result.times[-1]]``, s.

    Returns
    -------
    ndarray, shape (n, 3 * n_bodies)
    """
    times = np.asarray(times, dtype=float)
    samples = result.times
    if samples.size == 1:
        return np.repeat(result.coordinates[:1], times.size, axis=0)
    if times.size and (times.min() < samples[0] or times.max() > samples[-1]):
        raise ValueError(f"`times` must lie within the analysis, [{samples[0]:g}, {samples[-1]:g}] s")
    k = np.clip(np.searchsorted(samples, times, side="right") - 1, 0, samples.size - 2)
    h = (samples[k + 1] - samples[k])[:, None]
    s = (times[:, None] - samples[k][:, None]) / h
    q0, q1 = result.coordinates[k], result.coordinates[k + 1]
    v0, v1 = result.velocities[k], result.velocities[k + 1]
    return ((2 * s**3 - 3 * s**2 + 1) * q0 + (s**3 - 2 * s**2 + s) * h * v0
            + (-2 * s**3 + 3 * s**2) * q1 + (s**3 - s**2) * h * v1)  # fmt: skip


def animate(result: KinematicsResult, path, *, trace=(), fps: float | None = None, duration: float | None = None,
            labels: bool | str = True, stopped: str | None = None, bodies=None) -> Animation:  # fmt: skip
    """Write an animation of `result`: a GIF (Pillow) or an MP4 (imageio-ffmpeg), by suffix.

    Each frame is `draw_configuration` at the frame's time, with the paths of the traced
    points so far and a time stamp, on axes whose limits hold every point at every sample
    (they do not move during the clip).  The frames show equally spaced times
    (`frame_times`); the body coordinates there are interpolated between the samples by
    cubic Hermite interpolation on the solved positions and velocities
    (`interpolate_coordinates`), so that the motion is smooth whether the analysis has
    fewer samples than the clip has frames or many more.  When the analysis stopped before
    its end (``result.complete`` is False, e.g. a lock-up), the clip runs up to the last
    solved sample, whose frame is marked in red and held for `STOP_HOLD` seconds.

    Parameters
    ----------
    result : KinematicsResult
        The analysis, with at least one sample.
    path : str or Path
        ``*.gif`` or ``*.mp4``; its folder must exist.
    trace : sequence of str
        Points whose paths are drawn.
    fps : float, optional
        Frames per second (default 20 for a GIF, 30 for an MP4; at most 50 for a GIF).
    duration : float, optional
        Length of the clip, s (default: the time span of the analysis, real time).
    labels : {"all", "joints", "none"} or bool
        Label the points and the bodies (``"all"`` or True, the default), the points where
        joints are, or nothing (`draw_configuration`).
    stopped : str, optional
        The mark of an analysis that stopped, written on the last frame (default
        "analysis stopped after t = … s" when ``result.complete`` is False).
    bodies : sequence of str, optional
        Draw only these bodies (`draw_configuration`); the axes hold them and the traced
        paths.

    Returns
    -------
    Animation
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in DEFAULT_FPS:
        raise ValueError(f"`path` must end in .gif or .mp4, got {path.name!r}")
    fps = DEFAULT_FPS[suffix] if fps is None else float(fps)
    if not (math.isfinite(fps) and fps > 0.0) or (suffix == ".gif" and fps > MAX_GIF_FPS):
        limit = f" and at most {MAX_GIF_FPS:g} for a GIF" if suffix == ".gif" else ""
        raise ValueError(f"`fps` must be a number > 0{limit}, got {fps!r}")
    if duration is not None and not (math.isfinite(duration) and duration > 0.0):
        raise ValueError(f"`duration` must be a number of seconds > 0, got {duration!r}")
    if result.n_times == 0:
        raise ValueError("`result` has no sample to animate")
    _require("matplotlib", "matplotlib", "animate")
    _require(*(("PIL", "Pillow") if suffix == ".gif" else ("imageio_ffmpeg", "imageio-ffmpeg")), "animate")
    if stopped is None and not result.complete:
        stopped = f"analysis stopped after t = {result.times[-1]:.6g} s"
    times = frame_times(result, fps, duration)
    scene = _Scene(result, trace, times, labels, stopped, bodies)
    frames = (scene.frame(k) for k in range(times.size))
    hold = STOP_HOLD if stopped else 0.0
    if suffix == ".gif":
        _write_gif(path, frames, times.size, fps, hold)
    else:
        _write_mp4(path, frames, fps, hold)
    return Animation(path, times, fps, times.size / fps + hold, scene.limits, bool(stopped))


def save_frame(result: KinematicsResult, path, time: float | None = None, *, trace=(), labels: bool | str = True,
               stopped: str | None = None, bodies=None) -> Path:  # fmt: skip
    """Write one frame of the animation of `result` as a PNG file.

    The frame at `time` (default: the last sample) is drawn as in `animate`, with the
    traced paths up to that time, on the axes of the whole clip.

    Returns
    -------
    Path
        The file written.
    """
    end = float(result.times[-1])
    time = end if time is None else float(time)
    if not result.times[0] <= time <= end:
        raise ValueError(f"`time` must lie within the analysis, [{result.times[0]:g}, {end:g}] s, got {time!r}")
    if stopped is None and not result.complete and time == end:
        stopped = f"analysis stopped after t = {end:.6g} s"
    times = np.union1d(frame_times(result, DEFAULT_FPS[".gif"]), [time])
    scene = _Scene(result, trace, times, labels, stopped if time == end else None, bodies)
    scene.draw(int(np.searchsorted(times, time)))
    path = Path(path)
    scene.figure.savefig(path, dpi=FRAME_DPI)
    return path


class _Scene:
    """The figure of an animation: fixed axes, and what changes from frame to frame."""

    def __init__(self, result: KinematicsResult, trace, times: np.ndarray, labels: bool | str, stopped: str | None,
                 bodies=None):  # fmt: skip
        if result.coordinates is None:
            raise ValueError("`result` has no coordinates to draw: solve with coordinates=True (the default)")
        mechanism = result.mechanism
        self.times, self.labels, self.stopped = times, label_choice(labels), stopped
        self.drawer = _Drawer(mechanism, bodies)
        self.coordinates = interpolate_coordinates(result, times)
        self.trace_names = tuple(trace)
        self.traces = self.drawer.traced(self.trace_names, self.coordinates)  # (n_frames, n_traced, 2)
        extent_points = np.vstack([self.drawer.positions(result.coordinates).reshape(-1, 2),
                                   self.drawer.origins(result.coordinates).reshape(-1, 2),
                                   self.traces.reshape(-1, 2)])  # fmt: skip
        self.size = SYMBOL_SCALE * _extent(extent_points)
        self.figure, self.axes = _new_figure(FRAME_SIZE)
        self.figure.set_dpi(FRAME_DPI)
        axes = self.axes
        low, high = extent_points.min(axis=0), extent_points.max(axis=0)
        margin = 0.06 * float((high - low).max()) + 3.0 * self.size
        axes.update_datalim([low - margin, high + margin])
        axes.margins(0.0)
        axes.autoscale_view()
        axes.set_aspect("equal", adjustable="datalim")
        _dress(axes, mechanism.name)
        self.figure.get_layout_engine().execute(self.figure)
        self.figure.set_layout_engine("none")
        _freeze_limits(axes)
        self.limits = (*axes.get_xlim(), *axes.get_ylim())
        self.stamp = axes.text(0.02, 0.98, "", transform=axes.transAxes, ha="left", va="top", fontsize=11,
                               family="monospace", zorder=7, bbox=LABEL_BOX)  # fmt: skip
        self.trace_lines = []
        for k, name in enumerate(self.trace_names):
            colour = TRACE_COLOURS[k % len(TRACE_COLOURS)]
            axes.plot(self.traces[:, k, 0], self.traces[:, k, 1], color=colour, linewidth=0.8, alpha=0.25, zorder=1)
            (line,) = axes.plot([], [], color=colour, linewidth=1.8, zorder=1.5, label=f"path of {name}")
            self.trace_lines.append(line)
        if self.trace_names:
            axes.legend(loc="upper right", fontsize=9)
        self.changing: list = []
        self.drawer.texts = {}
        self.figure.canvas.draw()  # what no frame changes, drawn once
        self.background = self.figure.canvas.copy_from_bbox(self.figure.bbox)

    def draw(self, k: int) -> None:
        """Draw frame `k` on the figure."""
        for artist in self.changing:
            artist.remove()
        paths = []
        for line, trace in zip(self.trace_lines, np.moveaxis(self.traces[: k + 1], 1, 0)):
            line.set_data(trace[:, 0], trace[:, 1])
            paths.extend(np.stack([trace[:-1], trace[1:]], axis=1))
        self.changing = self.drawer.draw(self.axes, self.coordinates[k], self.size, labels=self.labels,
                                         extra_obstacles=paths)  # fmt: skip
        stop = self.stopped is not None and k == self.times.size - 1
        self.stamp.set_text(f"t = {self.times[k]:7.3f} s")
        self.stamp.set_color(STOP_COLOUR if stop else "black")
        if stop:
            self.changing.append(self.axes.text(
                0.5, 0.04, self.stopped, transform=self.axes.transAxes,
                ha="center", va="bottom", fontsize=12, fontweight="bold", color=STOP_COLOUR, zorder=8,
                bbox={"boxstyle": "round,pad=0.3", "facecolor": "white", "edgecolor": STOP_COLOUR, "linewidth": 2},
            ))  # fmt: skip
            for spine in self.axes.spines.values():
                spine.set_edgecolor(STOP_COLOUR)
                spine.set_linewidth(3.0)

    def frame(self, k: int) -> np.ndarray:
        """Frame `k` as an RGB array, shape (height, width, 3): the background drawn once,
        and over it only what changes (matplotlib's blitting)."""
        self.draw(k)
        canvas = self.figure.canvas
        canvas.restore_region(self.background)
        moving = [*self.changing, *self.drawer.texts.values(), *self.trace_lines, self.stamp]
        if self.stopped is not None and k == self.times.size - 1:
            moving += self.axes.spines.values()
        for artist in sorted(moving, key=lambda artist: artist.get_zorder()):
            self.axes.draw_artist(artist)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _write_gif(path: Path, frames, n_frames: int, fps: float, hold: float) -> None:
    """Frames on one palette (made from the first and the last frame, which between them
    hold every colour the clip uses); durations in whole hundredths of a second that add
    up to the clip's length."""
    from PIL import Image

    frames = list(frames)
    first, last = frames[0], frames[-1]
    palette = Image.fromarray(np.vstack([first, last])).quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    images = [Image.fromarray(frame).quantize(palette=palette, dither=Image.Dither.NONE) for frame in frames]
    ends = np.round(100.0 * np.arange(1, n_frames + 1) / fps).astype(int)
    centiseconds = np.diff(ends, prepend=0)
    centiseconds[-1] += round(100.0 * hold)
    images[0].save(path, save_all=True, append_images=images[1:], duration=[10 * int(c) for c in centiseconds],
                   loop=0, disposal=1, optimize=False)  # fmt: skip


def _write_mp4(path: Path, frames, fps: float, hold: float) -> None:
    """H.264 frames through imageio-ffmpeg (yuv420p, which every player reads)."""
    import imageio_ffmpeg

    writer = None
    frame = None
    for frame in frames:
        if writer is None:
            height, width, _ = frame.shape
            writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264",
                                                 pix_fmt_out="yuv420p", quality=7, macro_block_size=16,
                                                 ffmpeg_log_level="error")  # fmt: skip
            writer.send(None)
        writer.send(np.ascontiguousarray(frame))
    for _ in range(round(hold * fps)):
        writer.send(np.ascontiguousarray(frame))
    writer.close()
