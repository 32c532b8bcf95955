"""The forward-dynamics gallery: the struck metamaterial (examples/dynamics/struck_lattice.toml)
against its one-degree-of-freedom equation, integrated here on its own; and the gallery's list
of dynamics examples.

The lattice: n × n unit squares of mass m (inertia m/6 about the centre), square (p, q)
turned by ±θ with its centre at (p, q)·d(θ), d = cos θ + sin θ, relative to square (0, 0)'s
pinned centre (the square to its right slides along x, so the grid does not turn); the plate
(mass m_p) rides on the hinges of the right edge, at x = (n − ½)·d(θ); a spring k at each of
the 2n(n − 1) hinges sees the relative angle ±2θ against its drawn ±2θ₀.  So

    T = ½ M(θ) θ̇²,  M(θ) = d′(θ)² (m Σ(p² + q²) + m_p (n − ½)²) + n² m/6,
    V = ½ k · 2n(n − 1) · 4 (θ − θ₀)²,

and M θ̈ + ½ M′ θ̇² + 8 k n(n − 1)(θ − θ₀) = 0 (Lagrange), with d′ = cos θ − sin θ and
d″ = −d.  The plate starts at velocity −v along x, the rest at rest: the smallest
mass-weighted change keeps the projection on the one mode, θ̇₀ = −m_p v (n − ½) d′(θ₀) / M(θ₀).
The reference is scipy's DOP853 at a relative tolerance of 1e-12.
"""

from __future__ import annotations

import importlib.util
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import sparsekin as sk
from sparsekin.solve.initial_state import initial_state_change, initial_state_lines

ROOT = Path(__file__).resolve().parents[1]
LATTICE = ROOT / "examples" / "dynamics" / "struck_lattice.toml"
#: The file's numbers (read back from the model below where they can be).
N, THETA0, STIFFNESS, SPEED = 4, 0.3, 2.0, 2.0
#: Three seconds: the lattice shuts and has reopened past its drawn angle.
TIMES = np.linspace(0.0, 3.0, 61)


def pitch(theta):
    return np.cos(theta) + np.sin(theta)


def pitch_rate(theta):
    return np.cos(theta) - np.sin(theta)


def reference_angle(square_mass: float, plate_mass: float, times: np.ndarray) -> np.ndarray:
    """θ(t) of the one-degree-of-freedom equation (module docstring)."""
    moment = square_mass * sum(p * p + q * q for p in range(N) for q in range(N)) + plate_mass * (N - 0.5) ** 2
    rotation = N * N * square_mass / 6.0

    def mass(theta):
        return pitch_rate(theta) ** 2 * moment + rotation

    def rates(_, state):
        theta, omega = state
        mass_rate = -2.0 * pitch_rate(theta) * pitch(theta) * moment
        return [omega, (-0.5 * mass_rate * omega**2 - 8.0 * STIFFNESS * N * (N - 1) * (theta - THETA0)) / mass(theta)]

    start = -plate_mass * SPEED * (N - 0.5) * pitch_rate(THETA0) / mass(THETA0)
    solution = solve_ivp(rates, (times[0], times[-1]), [THETA0, start], method="DOP853", rtol=1e-12, atol=1e-14,
                         t_eval=times)  # fmt: skip
    return solution.y[0]


@pytest.fixture(scope="module")
def lattice():
    return sk.load_model(LATTICE)


def solved(lattice, max_step: float):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sk.RedundantConstraintWarning)  # the lattice's closed loops
        return sk.solve_dynamics(lattice, TIMES, max_step, rho_inf=1.0)


def largest_error(lattice, result) -> float:
    """The largest distance of any square or the plate from the reference motion: angles in
    rad, centres and the plate's position in m (squares are 1 m wide)."""
    bodies = {name: k for k, name in enumerate(lattice.body_names)}
    masses = {lattice.bodies[bodies["s0_0.a"]].mass, lattice.bodies[bodies["plate"]].mass}
    assert masses == {1.0, 5.0}
    theta = reference_angle(1.0, 5.0, TIMES)
    frames = result.coordinates.reshape(TIMES.size, -1, 3)
    origin = frames[:, bodies["s0_0.a"], :2]
    error = 0.0
    for name, k in bodies.items():
        if name == "plate":
            expected = (N - 0.5) * pitch(theta)
            error = max(error, np.max(np.abs(frames[:, k, 0] - origin[:, 0] - expected)))
            np.testing.assert_allclose(frames[:, k, 2], math.pi / 2, rtol=0, atol=1e-12)  # it does not turn
            continue
        i, j = map(int, re.fullmatch(r"s(\d+)_(\d+)\.[abcd]", name).groups())
        motif = name[-1]
        p, q = 2 * i + (motif in "bd"), 2 * j + (motif in "cd")
        sign = 1.0 if motif in "ad" else -1.0
        error = max(error, np.max(np.abs(frames[:, k, 2] - sign * theta)),
                    np.max(np.abs(frames[:, k, :2] - origin - np.outer(pitch(theta), [p, q]))))  # fmt: skip
    return error


def test_the_struck_lattice_moves_as_its_one_degree_of_freedom(lattice):
    """Every square and the plate on the exact motion within the integrator's error, which
    falls as h² (the lattice shuts from 0.3 to 0.11 rad and reopens in these 3 s)."""
    coarse, fine = solved(lattice, 5e-3), solved(lattice, 2.5e-3)
    errors = largest_error(lattice, coarse), largest_error(lattice, fine)
    assert errors[0] < 2e-5, errors
    assert 3.5 < errors[0] / errors[1] < 4.5, errors
    opening = fine.coordinates[:, 3 * lattice.body_names.index("s0_0.a") + 2]
    assert opening.min() < 0.12 and opening[-1] > THETA0
    # no damper, no gravity: the energy stays that of the consistent start
    assert np.abs(fine.energy.balance).max() < 1e-5 * fine.energy.kinetic[0]


def test_the_blow_is_shared_by_the_smallest_mass_weighted_change(lattice):
    """The consistent start keeps the projection of the plate's momentum on the one mode,
    and ``check`` prints the line the how-to shows."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sk.RedundantConstraintWarning)
        change = initial_state_change(lattice)
    moment = sum(p * p + q * q for p in range(N) for q in range(N)) + 5.0 * (N - 0.5) ** 2
    mass = pitch_rate(THETA0) ** 2 * moment + N * N / 6.0
    omega = -5.0 * SPEED * (N - 0.5) * pitch_rate(THETA0) / mass
    corner = lattice.body_names.index("s0_0.a")
    np.testing.assert_allclose(change.velocities[3 * corner + 2], omega, rtol=1e-12)
    np.testing.assert_allclose(change.kinetic, 0.5 * mass * omega**2, rtol=1e-12)
    np.testing.assert_allclose(change.kinetic_given, 0.5 * 5.0 * SPEED**2, rtol=1e-15)
    howto = (ROOT / "docs" / "how-to" / "dynamics.md").read_text(encoding="utf-8")
    assert initial_state_lines(change, lattice)[1] in howto


def test_the_gallery_lists_each_dynamics_example_with_a_title():
    spec = importlib.util.spec_from_file_location("sparsekin_docs", ROOT / "docs" / "_ext" / "sparsekin_docs.py")
    if importlib.util.find_spec("sphinx") is None:
        pytest.skip('the docs extra is not installed: pip install -e ".[docs]"')
    docs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(docs)
    for name in ("n_four_bar", "andrews", "struck_lattice"):
        assert name in docs.DYNAMICS_GALLERY and name in docs.GALLERY_TITLES
        assert (ROOT / docs.example_file(name)).is_file()
        assert sk.load_model(ROOT / docs.example_file(name)).analysis.type == "dynamics"
