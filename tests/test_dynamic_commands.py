"""``sparsekin check`` and ``sparsekin animate`` on forward-dynamics models.

``check`` reports where a run starts: the drawing assembled, and the given velocities moved
onto the constraints by the smallest mass-weighted change.  The reference is IFToMM A01
(a 1 kg point mass P on a massless 1 m link pinned at O, the link along +x) whose link
frame is given the velocity (vx, vy, ω) = (0.6, 0.4, 0) at the pin, worked by hand: the
pin holds O, so the consistent velocities are (0, 0, ω) and P moves at (0, ω).  The
mass-weighted change is the change of P's velocity, |(0, ω) − (0.6, 0.4)|, least at
ω = 0.4: 0.6 kg^½·m/s; kinetic energies ½·(0.6² + 0.4²) = 0.26 J given, ½·0.4² = 0.08 J
consistent, ½·0.6² = 0.18 J in the change; the largest change of a component is vx, −0.6.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sparsekin import Body, Mechanism, Revolute, load_model
from sparsekin.cli import main
from sparsekin.solve.initial_state import initial_state_change

ROOT = Path(__file__).resolve().parents[1]
PENDULUM = ROOT / "examples" / "dynamics" / "pendulum.toml"
FOUR_BAR = ROOT / "examples" / "four_bar.toml"
PUSHED = PENDULUM.read_text(encoding="utf-8").replace("velocity = [0.0, 0.0, 0.0]", "velocity = [0.6, 0.4, 0.0]")


def test_check_reports_how_far_the_velocities_moved_as_worked_by_hand(tmp_path):
    model = tmp_path / "pushed.toml"
    model.write_text(PUSHED, encoding="utf-8")
    checked = subprocess.run([sys.executable, "-m", "sparsekin", "check", str(model)], capture_output=True,
                             text=True, timeout=300, check=False)  # fmt: skip
    assert checked.returncode == 0 and checked.stderr == "", checked.stderr
    lines = checked.stdout.splitlines()
    (positions,) = [line for line in lines if line.startswith("initial positions (dynamics)")]
    (velocities,) = [line for line in lines if line.startswith("initial velocities (dynamics)")]
    assert positions.endswith("no point moved")
    numbers = re.search(r"√\(Δq̇ᵀMΔq̇\) = (\S+) kg\^½·m/s \(kinetic energy (\S+) J given, (\S+) J consistent, (\S+) J "
                        r"in the change\); largest change: pendulum\.vx by (\S+) m/s$", velocities)  # fmt: skip
    assert numbers, velocities
    np.testing.assert_allclose([float(n) for n in numbers.groups()], [0.6, 0.26, 0.08, 0.18, -0.6], rtol=1e-6)
    assert lines[-1] == "verdict: sound"  # the free rotation is the degree of freedom gravity moves


def test_the_velocity_change_in_full_precision():
    pendulum = Mechanism(points={"O": (0.0, 0.0), "P": (1.0, 0.0)}, joints=[Revolute(("link", "ground"), at="O")],
                         bodies=[Body("link", origin="O", points=("O", "P"), mass=1.0, com="P",
                                      velocity=(0.6, 0.4, 0.0))])  # fmt: skip
    change = initial_state_change(pendulum)
    np.testing.assert_allclose(change.velocities, [0.0, 0.0, 0.4], rtol=0, atol=1e-14)
    np.testing.assert_allclose([change.velocity_change, change.kinetic_given, change.kinetic, change.energy_of_change],
                               [0.6, 0.26, 0.08, 0.18], rtol=1e-13)  # fmt: skip
    assert change.moves == [] and change.n_moved == 0


def test_check_of_a_consistent_dynamics_model_says_so(capsys):
    assert main(["check", str(PENDULUM)]) == 0
    out = capsys.readouterr().out
    assert "initial velocities (dynamics): consistent at t = 0 s as given (kinetic energy 0 J)" in out
    assert "free motions (1), the degrees of freedom that the masses and loads move:" in out


def test_check_of_a_kinematic_model_is_unchanged_without_dynamics(capsys):
    assert main(["check", str(FOUR_BAR)]) == 0
    assert "(dynamics)" not in capsys.readouterr().out


def test_check_of_a_model_whose_motion_is_not_determined_is_a_problem(tmp_path, capsys):
    model = tmp_path / "massless.toml"
    model.write_text(PUSHED.replace("mass = 1.0", "mass = 0.0"), encoding="utf-8")
    assert main(["check", str(model)]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("initial state (dynamics): cannot start: the motion is not determined") for line in lines)
    assert lines[-1] == "verdict: a forward-dynamics run cannot start"


@pytest.fixture(scope="module")
def image():
    pytest.importorskip("matplotlib", reason='animations need matplotlib: pip install "sparsekin[animate]"')
    return pytest.importorskip("PIL.Image", reason='GIF animations need Pillow: pip install "sparsekin[animate]"')


def test_animate_runs_forward_dynamics_for_a_dynamics_model(tmp_path, capsys, image):
    out = tmp_path / "pendulum.gif"
    assert main(["animate", str(PENDULUM), "--t-end", "1", "--steps", "21", "--fps", "10", "--max-step", "5e-3",
                 "--out", str(out)]) == 0  # fmt: skip
    captured = capsys.readouterr()
    assert captured.err == "" and "pendulum: 21 samples, t = 0 … 1 s" in captured.out
    with image.open(out) as clip:
        assert clip.n_frames == 10


@pytest.mark.parametrize("model, options, message", [
    (FOUR_BAR, ["--max-step", "1e-3"], '--max-step is for forward dynamics: give --dynamics (or [analysis] type = "dynamics")'),
    (PENDULUM, ["--max-step", "-1"], "--max-step must be a positive number of seconds, got -1.0"),
])  # fmt: skip
def test_animate_dynamics_mistakes_are_one_line(tmp_path, capsys, model, options, message, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["animate", str(model), *options]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line == f"sparsekin: error: {message}"
    assert not list(tmp_path.iterdir())


def test_check_reports_how_far_the_drawing_moved_as_worked_by_hand(tmp_path, capsys):
    """A01 with its link driven from 0.1 rad at 1 rad/s: the drawing (the link along +x) is
    turned by 0.1 rad about O, so P moves by the chord 2·sin(0.05) m; the link's rate
    comes from the law, 1 rad/s, which moves the mass at 1 m/s: √(Δq̇ᵀMΔq̇) = 1 kg^½·m/s,
    0.5 J, the largest change ω by +1 rad/s."""
    driven = PENDULUM.read_text(encoding="utf-8").replace("[analysis]", """[[drivers]]
type = "rotational"
bodies = ["pendulum", "ground"]
law = { type = "linear", rate = 1.0, start = 0.1 }

[analysis]""")  # fmt: skip
    model = tmp_path / "driven.toml"
    model.write_text(driven, encoding="utf-8")
    change = initial_state_change(load_model(model))
    assert change.n_moved == 1 and change.moves[0][0] == "P"
    np.testing.assert_allclose(change.moves[0][1], 2.0 * np.sin(0.05), rtol=1e-12)
    np.testing.assert_allclose([change.velocity_change, change.energy_of_change], [1.0, 0.5], rtol=1e-12)
    assert main(["check", str(model)]) == 0
    out = capsys.readouterr().out
    assert "initial positions (dynamics): the drawing assembled at t = 0 s by the smallest change: 1 point moved, " \
           "the largest first: P 0.1 m" in out  # fmt: skip
    assert "largest change: pendulum.omega by +1 rad/s" in out
