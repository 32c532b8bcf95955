"""Figures of a crank linkage: labels to choose (`--labels`), several paths in one figure,
a driver's value as the abscissa (`--abscissa`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from jansen import jansen_leg
from test_plotting import captured_figures

from sparsekin import solve_kinematics
from sparsekin.cli import main
from sparsekin.model.modelfile import save_model

pytest.importorskip("matplotlib")

TIMES = np.linspace(0.0, 2.0 * math.pi, 25)


@pytest.fixture(scope="module")
def leg_run():
    leg = jansen_leg()
    return leg, solve_kinematics(leg, TIMES)


@pytest.mark.parametrize("labels, expected", [
    ("all", {"O", "P", "A", "C", "D", "E", "F", "G", "crank", "upper_bar", "lower_bar", "rocker", "upper_triangle",
             "outer_bar", "leg"}),
    ("joints", {"O", "P", "A", "C", "D", "E", "F"}),  # not the foot G: no joint there
    ("none", set()),
    (False, set()),
])  # fmt: skip
def test_the_drawing_labels_what_is_asked(leg_run, labels, expected):
    from sparsekin.plots import draw_configuration
    from sparsekin.plots.common import _new_figure

    leg, run = leg_run
    _, axes = _new_figure((6.0, 6.0))
    draw_configuration(axes, leg, run.coordinates[0], labels=labels)
    assert {text.get_text() for text in axes.texts} == expected
    with pytest.raises(ValueError, match="`labels` must be one of"):
        draw_configuration(axes, leg, run.coordinates[0], labels="some")


def test_several_paths_in_one_figure(leg_run, tmp_path, monkeypatch):
    from sparsekin.plots import plot_paths_together

    _, run = leg_run
    figures = captured_figures(monkeypatch)
    assert plot_paths_together(run, ["G", "F", "D"], tmp_path / "paths.png") == tmp_path / "paths.png"
    axes = figures[0].axes[0]
    paths = [line for line in axes.lines if line.get_label() in ("G", "F", "D")]
    for line, name in zip(paths, ["G", "F", "D"]):
        assert np.array_equal(line.get_xydata(), run.point(name).position)
    assert axes.get_aspect() == 1.0


def test_motion_against_the_crank_angle(leg_run, tmp_path, monkeypatch):
    from sparsekin.plots import plot_point_motion

    _, run = leg_run
    figures = captured_figures(monkeypatch)
    plot_point_motion(run, ["G"], tmp_path, abscissa="drivers[0]")
    axes = figures[0].axes[-1]
    crank = np.degrees(run.driver(0).value)  # start 0 at the drawn angle, rate 1 rad/s
    np.testing.assert_allclose(axes.lines[0].get_xdata(), np.degrees(TIMES), atol=1e-9)
    assert np.array_equal(axes.lines[0].get_xdata(), crank)
    assert axes.get_xlabel() == "drivers[0] (degrees)"
    with pytest.raises(KeyError, match='unknown driver "crank"'):
        plot_point_motion(run, ["G"], tmp_path, abscissa="crank")


def test_command_line_labels_overlay_and_abscissa(tmp_path, capsys):
    path = tmp_path / "leg.toml"
    save_model(jansen_leg(), path)
    out = tmp_path / "out"
    assert main(["run", str(path), "--t-end", "6.283", "--steps", "13", "--points", "G,F", "--plot", "--labels",
                 "joints", "--abscissa", "drivers[0]", "--out", str(out), "--quiet"]) == 0  # fmt: skip
    for name in ("paths.png", "point_G.png", "mechanism.png"):
        assert (out / name).stat().st_size > 0
    assert main(["run", str(path), "--t-end", "1", "--abscissa", "nope", "--out", str(out)]) == 2
    assert '--abscissa: unknown driver "nope"' in capsys.readouterr().err
    frame = tmp_path / "frame.png"
    assert main(["animate", str(path), "--t-end", "1", "--steps", "5", "--out", str(frame), "--labels", "none"]) == 0
    assert frame.stat().st_size > 0
