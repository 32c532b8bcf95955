"""Animations: frames equally spaced in time and interpolated between samples, GIF and MP4
files of the expected length, fixed axes, and a lock-up animated up to the stop.

The files are read back with their own readers (Pillow, ffmpeg), not with the code that
wrote them.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from sparsekin import SingularConfigurationError, load_model, solve_kinematics
from sparsekin.cli import main
from sparsekin.testset import task5

TASK5 = Path(__file__).resolve().parents[1] / "examples" / "task5.toml"
#: The red of the mark of a stopped analysis (matplotlib's "tab:red").
STOP_RED = np.array([214, 39, 40])


@pytest.fixture(scope="module")
def image():
    pytest.importorskip("matplotlib", reason='animations need matplotlib: pip install "sparsekin[animate]"')
    return pytest.importorskip(
        "PIL.Image", reason='GIF animations need Pillow: pip install "sparsekin[animate]"'
    )


@pytest.fixture(scope="module")
def task5_result():
    return solve_kinematics(task5(), np.linspace(0.0, 4.0, 81))


@pytest.fixture(scope="module")
def lock_up():
    """Task 5 with strokes of 0.06 m locks at t = 0.755244 s (docs/task5.md)."""
    with pytest.raises(SingularConfigurationError) as stop:
        solve_kinematics(task5(amplitude=0.06), np.linspace(0.0, 2.0, 201))
    return stop.value


def gif_frames(image, path: Path) -> tuple[list[np.ndarray], list[int]]:
    """Every frame as RGB and its duration in ms, as Pillow reads them."""
    frames, durations = [], []
    with image.open(path) as clip:
        for k in range(clip.n_frames):
            clip.seek(k)
            durations.append(clip.info["duration"])
            frames.append(np.asarray(clip.convert("RGB")))
    return frames, durations


def red_pixels(frame: np.ndarray) -> int:
    return int((np.abs(frame.astype(int) - STOP_RED).max(axis=-1) < 30).sum())


# ---------------------------------------------------------------------- frame times
@pytest.mark.parametrize("samples", [11, 101, 1001])
def test_a_ten_second_run_makes_a_ten_second_clip_whatever_its_samples(samples):
    from sparsekin.plots import frame_times

    result = solve_kinematics(task5(), np.linspace(0.0, 10.0, samples))
    times = frame_times(result, fps=20)
    assert times.size == 200
    np.testing.assert_allclose(np.diff(times), 10.0 / 199, rtol=1e-12)
    assert (times[0], times[-1]) == (0.0, 10.0)
    assert frame_times(result, fps=20, duration=5.0).size == 100  # slow motion or fast, by duration


def test_interpolated_frames_are_within_hermite_s_error_bound_of_positions_solved_there(rng):
    """Cubic Hermite interpolation on positions and velocities: between samples h apart the
    error is at most h⁴/384 · max|q⁗| (the classical bound), and none at the samples.
    max|q⁗| comes from second differences of the accelerations of a run at 1 ms."""
    from sparsekin.plots import interpolate_coordinates

    mechanism = task5()
    fine = solve_kinematics(mechanism, np.linspace(0.0, 4.0, 4001))
    fourth_derivative = np.abs(np.diff(fine.accelerations, 2, axis=0)).max() / 1e-3**2
    frame_times = np.sort(rng.uniform(0.0, 4.0, 60))
    solved_there = solve_kinematics(mechanism, np.concatenate([[0.0], frame_times])).coordinates[1:]
    errors = []
    for samples in (21, 41, 81):  # h = 0.2, 0.1, 0.05 s
        h = 4.0 / (samples - 1)
        result = solve_kinematics(mechanism, np.linspace(0.0, 4.0, samples))
        errors.append(np.abs(interpolate_coordinates(result, frame_times) - solved_there).max())
        assert errors[-1] <= h**4 / 384 * fourth_derivative
        assert np.array_equal(interpolate_coordinates(result, result.times), result.coordinates)
    assert errors[0] / errors[-1] > 100  # fourth order: 256 for h / 4 (a third-order scheme gives 64)


def test_times_outside_the_analysis_are_refused(task5_result):
    from sparsekin.plots import interpolate_coordinates

    with pytest.raises(ValueError, match=r"`times` must lie within the analysis, \[0, 4\] s"):
        interpolate_coordinates(task5_result, [4.5])


# ---------------------------------------------------------------------- GIF
def test_gif_has_the_frames_and_duration_of_the_clip_on_fixed_axes(tmp_path, image, task5_result):
    from sparsekin.plots import animate

    clip = animate(task5_result, tmp_path / "task5.gif", trace=["K"], fps=10)
    frames, durations = gif_frames(image, tmp_path / "task5.gif")
    assert len(frames) == clip.n_frames == 40
    assert durations == [100] * 40 and clip.duration == 4.0
    # the mechanism moves: frames a second apart differ in many pixels
    assert (frames[0] != frames[10]).any(axis=-1).mean() > 0.01
    # the axes do not: the tick labels left of and below the axes are the same in every frame
    height, width, _ = frames[0].shape
    for frame in frames[1:]:
        assert np.array_equal(frame[:, : width // 12], frames[0][:, : width // 12])
        assert np.array_equal(frame[-height // 14 :], frames[0][-height // 14 :])
    # ... and hold every point at every sample
    x_min, x_max, y_min, y_max = clip.limits
    for name in task5_result.point_names:
        position = task5_result.point(name).position
        assert x_min < position[:, 0].min() and position[:, 0].max() < x_max
        assert y_min < position[:, 1].min() and position[:, 1].max() < y_max


def test_gif_durations_add_up_at_a_rate_that_is_no_whole_number_of_hundredths(tmp_path, image):
    from sparsekin.plots import animate

    result = solve_kinematics(task5(), np.linspace(0.0, 1.0, 21))
    animate(result, tmp_path / "fast.gif", fps=30, labels=False)
    frames, durations = gif_frames(image, tmp_path / "fast.gif")
    assert len(frames) == 30
    assert sum(durations) == 1000 and set(durations) <= {30, 40}


def test_a_lock_up_is_animated_up_to_the_stop_and_marked(tmp_path, image, lock_up):
    from sparsekin.plots import animate
    from sparsekin.plots.animation import STOP_HOLD

    result = lock_up.result
    assert lock_up.time == pytest.approx(0.755244, abs=1e-6)
    assert not result.complete and 0.74 < result.times[-1] <= lock_up.time
    clip = animate(result, tmp_path / "lock.gif", fps=20)
    frames, durations = gif_frames(image, tmp_path / "lock.gif")
    assert len(frames) == clip.n_frames == round(20 * result.times[-1])
    assert clip.times[-1] == result.times[-1]
    assert durations[:-1] == [50] * (len(frames) - 1) and durations[-1] == 50 + 1000 * STOP_HOLD
    assert red_pixels(frames[0]) == 0 and red_pixels(frames[-1]) > 1000  # the red mark of the stop


def test_bad_arguments_are_refused(tmp_path, task5_result, image):
    from sparsekin.plots import animate

    with pytest.raises(ValueError, match=r"`path` must end in .gif or .mp4, got 'clip.avi'"):
        animate(task5_result, tmp_path / "clip.avi")
    with pytest.raises(ValueError, match="`fps` must be a number > 0 and at most 50 for a GIF"):
        animate(task5_result, tmp_path / "clip.gif", fps=60)
    with pytest.raises(ValueError, match="`duration` must be a number of seconds > 0"):
        animate(task5_result, tmp_path / "clip.gif", duration=0.0)
    with pytest.raises(KeyError, match='unknown point "Q" to trace'):
        animate(task5_result, tmp_path / "clip.gif", trace=["Q"])
    assert not list(tmp_path.iterdir())


# ---------------------------------------------------------------------- MP4
def test_mp4_has_the_frames_and_duration_of_the_clip(tmp_path, image):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg", reason='MP4 needs imageio-ffmpeg: pip install '
                                         '"sparsekin[animate]"')  # fmt: skip
    from sparsekin.plots import animate

    result = solve_kinematics(task5(), np.linspace(0.0, 2.0, 41))
    clip = animate(result, tmp_path / "task5.mp4", trace=["K"], fps=15)
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(tmp_path / "task5.mp4"))
    assert frames == clip.n_frames == 30
    assert seconds == pytest.approx(2.0, abs=0.07)  # ffmpeg reports the container's duration
    reader = imageio_ffmpeg.read_frames(str(tmp_path / "task5.mp4"))
    meta = next(reader)
    first, *_, last = (np.frombuffer(frame, np.uint8) for frame in reader)
    assert meta["size"] == (640, 560) and meta["fps"] == pytest.approx(15.0)
    assert np.abs(first.astype(int) - last.astype(int)).max() > 100  # the mechanism moved


# ---------------------------------------------------------------------- command line
def test_animate_command_writes_the_clip(tmp_path, capsys, image):
    out = tmp_path / "clip.gif"
    status = main(["animate", str(TASK5), "--t-end", "2", "--steps", "41", "--fps", "10", "--trace", "K,A",
                   "--out", str(out)])  # fmt: skip
    assert status == 0
    captured = capsys.readouterr()
    assert captured.err == "" and str(out) in captured.out and "20 frames at 10 fps, 2 s" in captured.out
    frames, durations = gif_frames(image, out)
    assert len(frames) == 20 and sum(durations) == 2000


def test_animate_command_writes_one_frame(tmp_path, capsys, image):
    out = tmp_path / "frame.png"
    assert (
        main(["animate", str(TASK5), "--t-end", "2", "--steps", "41", "--at", "1.5", "--out", str(out)]) == 0
    )
    with image.open(out) as frame:
        assert frame.size == (640, 560)
    assert "frame at t = 1.5 s" in capsys.readouterr().out


def test_animate_command_on_a_lock_up_exits_3_with_the_clip_up_to_the_stop(tmp_path, capsys, image):
    model = tmp_path / "stroke_006.toml"
    model.write_text(TASK5.read_text().replace("amplitude = 0.05", "amplitude = 0.06"))
    out = tmp_path / "lock.gif"
    assert main(["animate", str(model), "--t-end", "2", "--steps", "201", "--out", str(out)]) == 3
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2 and lines[0].startswith(
        "sparsekin: analysis stopped: singular configuration at t = 0.755"
    )
    assert lines[1].startswith("sparsekin: animated 76 of 201 samples (t = 0 … 0.75 s)")
    frames, _ = gif_frames(image, out)
    assert len(frames) == 15 and red_pixels(frames[-1]) > 1000


@pytest.mark.parametrize(
    "options, message",
    [
        (["--out", "clip.avi"], "--out must end in .gif, .mp4 or .png, got"),
        (["--trace", "K,Q"], '--trace: unknown point "Q" (known: A, B, D'),
        (["--fps", "60"], "--fps must be at most 50 for a GIF"),
        (["--fps", "0"], "--fps must be a number > 0"),
        (["--duration", "-1"], "--duration must be a number of seconds > 0"),
        (["--at", "1"], "--at chooses the time of one frame: give --out FILE.png with it"),
        (["--out", "frame.png", "--at", "20"], "--at must be a time within the analysis, 0 … 10 s"),
    ],
    ids=["suffix", "trace", "gif-fps", "zero-fps", "duration", "at-without-png", "at-outside"],
)
def test_animate_command_bad_arguments_are_one_line(tmp_path, capsys, options, message, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["animate", str(TASK5), *options]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("sparsekin: error: ") and message in line
    assert not list(tmp_path.iterdir())  # nothing solved, nothing written


@pytest.mark.parametrize("suffix, module, package", [(".gif", "PIL", "Pillow"), (".mp4", "imageio_ffmpeg", "imageio-ffmpeg"),
                                                     (".png", "matplotlib", "matplotlib")])  # fmt: skip
def test_animate_command_without_its_extra_names_it(tmp_path, capsys, monkeypatch, suffix, module, package):
    monkeypatch.setitem(sys.modules, module, None)  # import -> ImportError
    out = tmp_path / f"clip{suffix}"
    assert main(["animate", str(TASK5), "--out", str(out)]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line == f'sparsekin: error: clip{suffix} needs {package}: pip install "sparsekin[animate]"'
    assert not out.exists()


@pytest.mark.parametrize("suffix, module, package", [(".gif", "PIL", "Pillow"), (".mp4", "imageio_ffmpeg", "imageio-ffmpeg")])
def test_animate_without_its_extra_names_it(tmp_path, monkeypatch, task5_result, suffix, module, package):
    from sparsekin.plots import animate

    monkeypatch.setitem(sys.modules, module, None)
    with pytest.raises(ImportError, match=rf'^{package} is needed here: pip install "sparsekin\[animate\]"$'):
        animate(task5_result, tmp_path / f"clip{suffix}")
    assert not list(tmp_path.iterdir())


def test_a_model_error_is_reported_against_the_file(tmp_path, capsys):
    model = tmp_path / "broken.toml"
    model.write_text(TASK5.read_text().replace('bodies = ["c3", "c4"]', 'bodies = ["c3", "c11"]'))
    assert main(["animate", str(model), "--out", str(tmp_path / "x.gif")]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "broken.toml" in line and '"c11"' in line
    assert load_model(TASK5).name == "task5"
