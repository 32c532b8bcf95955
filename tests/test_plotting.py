"""Figures: point motion against time and the drawing of the mechanism."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sparsekin import Body, Linear, Mechanism, Revolute, RotationalDriver, Translational, solve_kinematics
from sparsekin.modelfile import load_model

TASK5 = Path(__file__).resolve().parents[1] / "examples" / "task5.toml"


def test_import_sparsekin_does_not_need_matplotlib():
    code = "import sys, sparsekin, sparsekin.cli, sparsekin.plotting; sys.exit('matplotlib' in sys.modules)"
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
    from sparsekin.plotting import draw_mechanism

    mechanism, result = task5
    path = draw_mechanism(mechanism, result, tmp_path)
    assert path == tmp_path / "mechanism.png"
    pixels = matplotlib_image.imread(path)
    assert pixels.shape[0] > 400 and pixels[..., :3].std() > 0.05  # not blank


def test_slider_crank_with_one_point_body_and_direction_guide(tmp_path, matplotlib_image):
    from sparsekin.plotting import draw_mechanism

    mechanism = slider_crank()
    result = solve_kinematics(mechanism, np.linspace(0.0, 1.0, 21))
    assert draw_mechanism(mechanism, result, tmp_path).is_file()
    assert plot_point_motion_of(result, ["slider B"], tmp_path) == [tmp_path / "point_slider_B.png"]


def plot_point_motion_of(result, names, directory):
    from sparsekin.plotting import plot_point_motion

    paths = plot_point_motion(result, names, directory)
    for path in paths:
        assert path.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    return paths


@pytest.mark.parametrize("example", ["task5_distance", "planetary_gear"])
def test_examples_with_every_element_kind_are_drawn(tmp_path, matplotlib_image, example):
    from sparsekin.plotting import draw_mechanism, plot_actuators

    mechanism = load_model(TASK5.with_name(f"{example}.toml"))
    result = solve_kinematics(mechanism, np.linspace(0.0, 1.0, 11))
    pixels = matplotlib_image.imread(draw_mechanism(mechanism, result, tmp_path))
    assert pixels[..., :3].std() > 0.05
    assert plot_actuators(result, tmp_path) == ([tmp_path / "actuators.png"] if example == "task5_distance" else [])


def test_every_kind_draws_itself_on_a_canvas(tmp_path, matplotlib_image):
    """Each registered kind's `draw` runs on a model that has one of each."""
    from test_model_file import every_element_mechanism

    from sparsekin import elements
    from sparsekin.pattern import build_point_map
    from sparsekin.plotting import draw_mechanism
    from sparsekin.results import KinematicsResult

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
