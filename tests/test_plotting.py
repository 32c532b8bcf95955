"""Figures: point motion against time and the drawing of the mechanism."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sparsekin import Body, Linear, Mechanism, Revolute, RotationalDriver, Translational, solve_kinematics
from sparsekin.model.modelfile import load_model

TASK5 = Path(__file__).resolve().parents[1] / "examples" / "task5.toml"


def test_import_sparsekin_does_not_need_matplotlib():
    code = "import sys, sparsekin, sparsekin.cli, sparsekin.plots; sys.exit('matplotlib' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], timeout=300).returncode == 0


@pytest.fixture(scope="module")
def matplotlib_image():
    pytest.importorskip("matplotlib")
    from matplotlib import image

    return image


@pytest.fixture(scope="module")
def task5():
    mechanism = load_model(TASK5)
    return mechanism, solve_kinematics(mechanism, np.linspace(0.0, 2.0, 41))


def slider_crank() -> Mechanism:
    """A slider-crank with a one-point slider on a guide given by `at` and `direction`."""
    return Mechanism(
        points={"O": (0.0, 0.0), "A": (0.1, 0.0), "slider B": (0.4, 0.0)},
        bodies=[
            Body("crank", origin="O", points=("O", "A")),
            Body("rod", origin="A", points=("A", "slider B")),
            Body("slider", origin="slider B", points=("slider B",)),
        ],
        joints=[
            Revolute(("crank", "ground"), at="O"),
            Revolute(("crank", "rod"), at=(0.1, 0.0)),
            Revolute(("rod", "slider"), at="slider B"),
            Translational(("ground", "slider"), at="slider B", direction=(1.0, 0.0)),
        ],
        drivers=[RotationalDriver(("crank", "ground"), law=Linear(start=0.5, rate=2 * np.pi))],
        name="slider-crank",
    )


def test_plot_point_motion_writes_one_figure_per_point(tmp_path, matplotlib_image, task5):
    _, result = task5
    paths = plot_point_motion_of(result, ["K", "A"], tmp_path)
    assert paths == [tmp_path / "point_K.png", tmp_path / "point_A.png"]
    height, width, _ = matplotlib_image.imread(paths[0]).shape
    assert height > width  # three panels stacked


def test_draw_mechanism_writes_the_drawing(tmp_path, matplotlib_image, task5):
    from sparsekin.plots import draw_mechanism

    mechanism, result = task5
    path = draw_mechanism(mechanism, result, tmp_path)
    assert path == tmp_path / "mechanism.png"
    pixels = matplotlib_image.imread(path)
    assert pixels.shape[0] > 400 and pixels[..., :3].std() > 0.05  # not blank


def test_slider_crank_with_one_point_body_and_direction_guide(tmp_path, matplotlib_image):
    from sparsekin.plots import draw_mechanism

    mechanism = slider_crank()
    result = solve_kinematics(mechanism, np.linspace(0.0, 1.0, 21))
    assert draw_mechanism(mechanism, result, tmp_path).is_file()
    assert plot_point_motion_of(result, ["slider B"], tmp_path) == [tmp_path / "point_slider_B.png"]


def plot_point_motion_of(result, names, directory):
    from sparsekin.plots import plot_point_motion

    paths = plot_point_motion(result, names, directory)
    for path in paths:
        assert path.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    return paths


@pytest.mark.parametrize("example", ["task5_distance", "planetary_gear"])
def test_examples_with_every_element_kind_are_drawn(tmp_path, matplotlib_image, example):
    from sparsekin.plots import draw_mechanism, plot_actuators

    mechanism = load_model(TASK5.with_name(f"{example}.toml"))
    result = solve_kinematics(mechanism, np.linspace(0.0, 1.0, 11))
    pixels = matplotlib_image.imread(draw_mechanism(mechanism, result, tmp_path))
    assert pixels[..., :3].std() > 0.05
    assert plot_actuators(result, tmp_path) == ([tmp_path / "actuators.png"] if example == "task5_distance" else [])


def test_every_kind_draws_itself_on_a_canvas(tmp_path, matplotlib_image):
    """Each registered kind's `draw` runs on a model that has one of each."""
    from test_model_file import every_element_mechanism

    from sparsekin.model import elements
    from sparsekin.engine.pattern import build_point_map
    from sparsekin.plots import draw_mechanism
    from sparsekin.results.kinematics import KinematicsResult

    mechanism = every_element_mechanism()  # drawn as given: it need not move
    kinds = {type(element) for element in (*mechanism.joints, *mechanism.drivers)}
    assert kinds == {*elements.JOINT_KINDS.values(), *elements.DRIVER_KINDS.values()}
    coordinates = mechanism.frames().ravel()[None]
    drawn = KinematicsResult(
        times=np.zeros(1), coordinates=coordinates, velocities=0 * coordinates, accelerations=0 * coordinates,
        newton_iterations=np.zeros(1, dtype=int), n_factorizations=0,
        n_solves=0, complete=True, point_map=build_point_map(mechanism), mechanism=mechanism,
    )  # fmt: skip
    assert draw_mechanism(mechanism, drawn, tmp_path).is_file()


# ---------------------------------------------------------------------- what a designer reads
def captured_figures(monkeypatch):
    """The figures the plotting functions save, kept for inspection (they are still written)."""
    from sparsekin.plots import figures as plotting  # the module of the run's figures

    figures = []
    save = plotting._save

    def keep(figure, path):
        figures.append(figure)
        return save(figure, path)

    monkeypatch.setattr(plotting, "_save", keep)
    return figures


def test_point_motion_shows_x_and_y_against_time(tmp_path, matplotlib_image, task5, monkeypatch):
    from sparsekin.plots import plot_point_motion

    _, result = task5
    figures = captured_figures(monkeypatch)
    plot_point_motion(result, ["K"], tmp_path)
    (figure,) = figures
    motion = result.point("K")
    for axes, values in zip(figure.axes, motion):
        x_line, y_line = axes.lines
        assert (x_line.get_label(), y_line.get_label()) == ("x", "y")
        assert np.array_equal(x_line.get_xdata(), result.times)
        assert np.array_equal(x_line.get_ydata(), values[:, 0]) and np.array_equal(y_line.get_ydata(), values[:, 1])


def test_path_figure_is_the_point_s_path_with_equal_scales(tmp_path, matplotlib_image, task5, monkeypatch):
    from sparsekin.plots import plot_point_paths
    from sparsekin.plots.figures import PATH_TIME_MARKS

    _, result = task5
    figures = captured_figures(monkeypatch)
    assert plot_point_paths(result, ["K", "A"], tmp_path) == [tmp_path / "path_K.png", tmp_path / "path_A.png"]
    axes = figures[0].axes[0]
    path, marks, start, end = axes.lines
    position = result.point("K").position
    assert np.array_equal(path.get_xydata(), position)
    assert len(marks.get_xdata()) == PATH_TIME_MARKS - 1
    assert np.array_equal(start.get_xydata()[0], position[0]) and np.array_equal(end.get_xydata()[0], position[-1])
    assert axes.get_aspect() == 1.0


def test_plot_option_writes_paths_and_actuators(tmp_path, capsys, matplotlib_image):
    from sparsekin.cli import main

    out = tmp_path / "out"
    assert main(["run", str(TASK5), "--t-end", "1", "--steps", "11", "--points", "K", "--plot", "--out", str(out)]) == 0
    for name in ("point_K.png", "path_K.png", "actuators.png", "mechanism.png"):
        assert matplotlib_image.imread(out / name)[..., :3].std() > 0.05


def drawn_canvas(mechanism, coordinates):
    """A canvas on which every joint and driver of `mechanism` has drawn itself."""
    from sparsekin.plots import Canvas
    from sparsekin.plots.canvas import SYMBOL_SCALE
    from sparsekin.plots.common import _new_figure

    _, axes = _new_figure((4.0, 4.0))
    canvas = Canvas(axes, mechanism, coordinates, size=SYMBOL_SCALE * 2.0)
    for element in (*mechanism.joints, *mechanism.drivers):
        element.draw(canvas)
    return canvas


@pytest.mark.parametrize("frame_angles", ["along-the-actuator", "zero"])
def test_cylinders_and_rods_lie_along_their_actuator_whatever_their_frame(matplotlib_image, frame_angles):
    """Task 5's c7–c10 carry one point each: each is drawn from its pin along the line to
    the other pin of its actuator (N→M, H→G), at every time, whether the file gives
    their frames the actuator's angle or leaves them at 0."""
    from dataclasses import replace

    mechanism = load_model(TASK5)
    if frame_angles == "zero":
        mechanism = replace(mechanism, bodies=tuple(replace(body, angle=0.0) for body in mechanism.bodies))
    result = solve_kinematics(mechanism, np.linspace(0.0, 4.0, 9))
    ends = {"c8": ("N", "M"), "c7": ("M", "N"), "c10": ("H", "G"), "c9": ("G", "H")}  # from its pin, inwards
    for sample in range(result.n_times):
        canvas = drawn_canvas(mechanism, result.coordinates[sample])
        assert set(ends) <= canvas.drawn_bodies
        for body, (own, other) in ends.items():
            pin, far = (result.point(name).position[sample] for name in (own, other))
            middle, along = canvas.body_labels[body]
            start = middle - along / 2
            np.testing.assert_allclose(start, pin, atol=1e-12)  # the bar starts at the body's pin
            inward = (far - pin) / np.hypot(*(far - pin))
            np.testing.assert_allclose(along / np.hypot(*along), inward, atol=1e-12)  # along the actuator


def test_a_slider_block_sits_on_its_guide(matplotlib_image):
    mechanism = slider_crank()
    result = solve_kinematics(mechanism, np.linspace(0.0, 1.0, 21))
    for sample in (0, 7, 13):
        canvas = drawn_canvas(mechanism, result.coordinates[sample])
        assert "slider" in canvas.drawn_bodies
        block, _ = canvas.body_labels["slider"]
        np.testing.assert_allclose(block, result.point("slider B").position[sample], atol=1e-12)


def crowded_mechanism() -> Mechanism:
    """A four-bar whose coupler carries four more points within 1 % of its length of B, and
    a rocker pivot with two more ground points beside it: names that would pile up."""
    points = {"O": (0.0, 0.0), "A": (0.1, 0.0), "B": (0.3041666666666667, 0.28428150172359473), "Q": (0.4, 0.0)}
    cluster = {f"P{k}": (points["B"][0] + 0.003 * math.cos(k), points["B"][1] + 0.003 * math.sin(k)) for k in range(4)}
    ground = {"C1": (0.405, 0.004), "S1": (0.398, -0.003)}
    points |= cluster | ground
    return Mechanism(
        points=points,
        bodies=[
            Body("crank", origin="O", points=("O", "A")),
            Body("coupler", origin="A", points=("A", "B", *cluster)),
            Body("rocker", origin="Q", points=("Q", "B")),
        ],
        joints=[
            Revolute(("crank", "ground"), at="O"),
            Revolute(("crank", "coupler"), at="A"),
            Revolute(("coupler", "rocker"), at="B"),
            Revolute(("rocker", "ground"), at="Q"),
        ],
        drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=2 * np.pi))],
        name="crowded",
    )


@pytest.mark.parametrize("example", ["task5", "excavator", "watt_six_bar", "crowded"])
def test_labels_do_not_overlap(matplotlib_image, example):
    """Every point and body is labelled, and no two label boxes overlap, as matplotlib
    measures them in the drawn figure (the text and its background box)."""
    from sparsekin.plots import draw_configuration
    from sparsekin.plots.common import _new_figure

    mechanism = crowded_mechanism() if example == "crowded" else load_model(TASK5.with_name(f"{example}.toml"))
    result = solve_kinematics(mechanism, np.linspace(0.0, 1.0, 3))
    for sample in range(result.n_times):
        figure, axes = _new_figure((8.0, 7.0))
        draw_configuration(axes, mechanism, result.coordinates[sample])
        figure.canvas.draw()
        renderer = figure.canvas.get_renderer()
        boxes = []
        for text in axes.texts:
            extent = text.get_window_extent(renderer)
            if text.get_bbox_patch() is not None:
                extent = type(extent).union([extent, text.get_bbox_patch().get_window_extent(renderer)])
            boxes.append(extent)
        names = sorted(text.get_text() for text in axes.texts)
        assert names == sorted([*mechanism.points, *mechanism.body_names])
        for i, first in enumerate(boxes):
            for second in boxes[i + 1 :]:
                overlap_x = min(first.x1, second.x1) - max(first.x0, second.x0)
                overlap_y = min(first.y1, second.y1) - max(first.y0, second.y0)
                assert overlap_x <= 0.5 or overlap_y <= 0.5, (example, sample)
            assert axes.bbox.x0 <= first.x0 and first.x1 <= axes.bbox.x1


def test_a_part_of_a_long_chain_is_drawn_alone(matplotlib_image):
    """`bodies=` draws those bodies, the points they carry and the elements between them
    and the ground, on axes that fit them: the first 12 bodies of the 2001-body chain."""
    from sparsekin.plots import draw_configuration
    from sparsekin.plots.common import _new_figure

    chain = load_model(TASK5.with_name("four_bar_chain.toml"))
    result = solve_kinematics(chain, np.linspace(0.0, 0.2, 3))
    first = [chain.body_names[k] for k in range(12)]
    figure, axes = _new_figure((8.0, 7.0))
    draw_configuration(axes, chain, result.coordinates[-1], bodies=first)
    carried = {point for name in first for point in chain.bodies[chain.body_index(name)].points}
    assert sorted(text.get_text() for text in axes.texts) == sorted([*carried, *first])
    x_min, x_max = axes.get_xlim()
    assert x_max < 10.0  # 6 loops of 1 m, not the 1000 of the chain
    with pytest.raises(KeyError, match='unknown body "nope" to draw'):
        draw_configuration(axes, chain, result.coordinates[-1], bodies=["nope"])


def test_plot_option_without_the_coordinates_draws_what_was_recorded(tmp_path, capsys, matplotlib_image):
    from sparsekin.cli import main

    out = tmp_path / "out"
    assert main(["run", str(TASK5), "--t-end", "1", "--steps", "11", "--points", "K", "--no-coordinates", "--plot",
                 "--out", str(out)]) == 0  # fmt: skip
    assert (out / "point_K.png").is_file() and (out / "path_K.png").is_file()
    assert not (out / "mechanism.png").exists() and not (out / "actuators.png").exists()
    assert "note: actuators.png and mechanism.png need every body's coordinates: give --coordinates" in (
        capsys.readouterr().err
    )


def test_plot_option_draws_the_first_bodies_of_a_long_chain(tmp_path, capsys, matplotlib_image):
    from sparsekin.cli import main
    from sparsekin.cli.files import MAX_DRAWN_BODIES

    out = tmp_path / "out"
    chain = TASK5.with_name("four_bar_chain.toml")
    assert main(["run", str(chain), "--t-end", "0.1", "--steps", "3", "--points", "A0", "--plot", "--out", str(out)]) == 0
    assert f"note: mechanism.png shows the first {MAX_DRAWN_BODIES} of 2001 bodies" in capsys.readouterr().err
    assert matplotlib_image.imread(out / "mechanism.png")[..., :3].std() > 0.05
