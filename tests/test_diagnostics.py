"""Diagnostics: the rank analysis, `check_model`, redundant equations and lock-up.

References, independent of the code under test:

* the numerical rank, null spaces and smallest singular values of the same row- and
  column-scaled Jacobian from NumPy's dense SVD (small models only);
* the exact motion of the triple parallelogram: the coupler translates, every one of its
  points on a circle of radius 1 m, the cranks turn with the driven one;
* the Task 5 report: strokes of 0.06 m reach a dead centre near t = 0.76 s, strokes of
  0.05 m do not.
"""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy import sparse

from sparsekin.engine.discretization import Discretization
from sparsekin import (
    Body,
    ConvergenceError,
    Linear,
    Mechanism,
    ModelError,
    Revolute,
    RotationalDriver,
    SingularJacobianError,
    Translational,
    TranslationalDriver,
    UnjoinedPointWarning,
    load_model,
    solve_kinematics,
)
from sparsekin.analysis.check import check_model
from sparsekin.analysis.describe import equation_label
from sparsekin.analysis.rank import analyse_jacobian
from sparsekin.cli import main
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern
from sparsekin.errors import RedundantConstraintWarning, SingularConfigurationError
from sparsekin.testset import task5, task5_chain

DATA = Path(__file__).resolve().parent / "data"
TRIPLE_PARALLELOGRAM = DATA / "triple_parallelogram.toml"
TASK5_FILE = Path(__file__).resolve().parents[1] / "examples" / "task5.toml"
#: Relative tolerance of the comparisons with closed forms (as in test_closed_forms.py).
RTOL = 1e-10


# ---------------------------------------------------------------------- helpers
def jacobian_at(mechanism: Mechanism, coordinates=None, t: float = 0.0) -> sparse.csr_array:
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(t)
    assembler.fill_residual_jacobian(pattern.initial_coordinates if coordinates is None else coordinates)
    return assembler.jacobian.copy()


def scaled_dense(jacobian, analysis) -> np.ndarray:
    """The scaled Jacobian of `analysis` as a dense array."""
    return (analysis.row_scale[:, None] * jacobian.toarray()) * analysis.column_scale


def svd_rank(matrix: np.ndarray, relative: float) -> tuple[int, np.ndarray]:
    values = np.linalg.svd(matrix, compute_uv=False) if matrix.size else np.zeros(0)
    if not values.size or values[0] == 0:
        return 0, values
    return int(np.count_nonzero(values > relative * values[0])), values


def subspace_gap(basis: np.ndarray, reference: np.ndarray) -> float:
    """Largest sine of the angles between the ranges of two bases (0 when they are equal)."""
    q = np.linalg.qr(basis)[0] if basis.size else basis
    r = np.linalg.qr(reference)[0] if reference.size else reference
    if q.shape[1] != r.shape[1]:
        return math.inf
    if not q.size:
        return 0.0
    return float(np.linalg.norm(q - r @ (r.T @ q), 2))


def without_joint_at(mechanism: Mechanism, point: str) -> Mechanism:
    mechanism = mechanism.expanded()  # every joint an object, to leave one out
    joints = tuple(joint for joint in mechanism.joints if getattr(joint, "at", None) != point)
    assert len(joints) == len(mechanism.joints) - 1
    return dataclasses.replace(mechanism, joints=joints)


def triple_parallelogram(crank2_length: float = 1.0, drivers: int = 1) -> Mechanism:
    """The triple parallelogram of tests/data, built in Python (crank 2 may be longer)."""
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    points = {"O0": (0.0, 0.0), "O1": (1.0, 0.0), "O2": (2.0, 0.0), "T0": (c, s), "T1": (1 + c, s),
              "T2": (2 + crank2_length * c, crank2_length * s), "P": (1 + c, s + 0.5)}  # fmt: skip
    bodies = [Body(f"crank{i}", origin=f"O{i}", angle=math.pi / 4, points=(f"O{i}", f"T{i}")) for i in range(3)]
    bodies.append(Body("coupler", origin="T0", points=("T0", "T1", "T2", "P")))
    joints = [Revolute((f"crank{i}", "ground"), at=f"O{i}") for i in range(3)]
    joints += [Revolute(("coupler", f"crank{i}"), at=f"T{i}") for i in range(3)]
    law = Linear(rate=1.0)
    driven = [RotationalDriver((f"crank{i}", "ground"), law=law) for i in range(drivers)]
    return Mechanism(points=points, bodies=bodies, joints=joints, drivers=driven, name="triple_parallelogram")


# ---------------------------------------------------------------------- analyse_jacobian vs SVD
def planted_rank_matrix(rng, m: int, n: int, rank: int) -> np.ndarray:
    """A sparse m × n matrix of rank `rank` (generically), rows and columns badly scaled."""
    left = sparse.random_array((m, rank), density=0.5, rng=rng).toarray() if rank else np.zeros((m, 0))
    right = sparse.random_array((rank, n), density=0.5, rng=rng).toarray() if rank else np.zeros((0, n))
    matrix = left @ right
    matrix *= 10.0 ** rng.integers(-3, 4, m)[:, None]
    matrix *= 10.0 ** rng.integers(-3, 4, n)[None, :]
    if m > 1 and rng.random() < 0.5:
        matrix[-1] = matrix[0]  # an exact duplicate equation
    return matrix


@pytest.mark.parametrize("case", range(24))
def test_rank_and_null_spaces_match_the_svd(rng, case):
    for _ in range(case):  # a different matrix per case, from the one seeded generator
        rng.random()
    m, n = (int(size) for size in rng.integers(1, 30, 2))
    rank = int(rng.integers(0, min(m, n) + 1))
    matrix = planted_rank_matrix(rng, m, n, rank)
    analysis = analyse_jacobian(sparse.csr_array(matrix))
    scaled = scaled_dense(sparse.csr_array(matrix), analysis)
    expected_rank, values = svd_rank(scaled, analysis.tolerance)
    assert analysis.rank == expected_rank == np.linalg.matrix_rank(matrix) == min(rank, np.linalg.matrix_rank(matrix))
    assert (analysis.n_free, analysis.n_redundant) == (n - expected_rank, m - expected_rank)
    # Null vectors, confirmed by their residuals and equal to the SVD's null spaces.
    motions, dependencies = analysis.scaled_free_motions, analysis.dependencies
    scale = values[0] if values.size else 1.0
    assert np.linalg.norm(scaled @ motions, 2) <= 1e-12 * scale * max(1.0, np.linalg.norm(motions, 2))
    assert np.linalg.norm(scaled.T @ dependencies, 2) <= 1e-12 * scale * max(1.0, np.linalg.norm(dependencies, 2))
    u, _, vt = np.linalg.svd(scaled)
    assert subspace_gap(motions, vt[expected_rank:].T) < 1e-8
    assert subspace_gap(dependencies, u[:, expected_rank:]) < 1e-8
    # The basic forms: identity on the chosen coordinates and equations.
    np.testing.assert_allclose(motions[analysis.free_coordinates], np.eye(analysis.n_free), atol=1e-12)
    np.testing.assert_allclose(dependencies[analysis.redundant_rows], np.eye(analysis.n_redundant), atol=1e-12)
    if 0 < expected_rank:  # a Ritz value: an estimate from above, after a few sweeps of inverse iteration
        assert values[expected_rank - 1] * (1 - 1e-12) <= analysis.sigma_min <= values[expected_rank - 1] * (1 + 1e-3)


def test_task5_has_full_rank_and_its_condition_number():
    jacobian = jacobian_at(task5())
    analysis = analyse_jacobian(jacobian)
    values = np.linalg.svd(scaled_dense(jacobian, analysis), compute_uv=False)
    assert analysis.rank == 30 and analysis.n_free == analysis.n_redundant == 0
    np.testing.assert_allclose(analysis.sigma_min, values[-1], rtol=1e-9)
    np.testing.assert_allclose(analysis.sigma_max, values[0], rtol=1e-2)  # power iteration: a lower bound
    np.testing.assert_allclose(analysis.condition, values[0] / values[-1], rtol=1e-2)


def test_removing_joint_e_frees_two_motions_one_of_them_c6_about_d():
    mechanism = without_joint_at(task5(), "E")
    jacobian = jacobian_at(mechanism)
    analysis = analyse_jacobian(jacobian)
    scaled = scaled_dense(jacobian, analysis)
    assert analysis.rank == 28 == np.linalg.matrix_rank(scaled)
    assert subspace_gap(analysis.scaled_free_motions, np.linalg.svd(scaled)[2][28:].T) < 1e-10
    # The null space holds the rotation of c6 alone about D, its frame origin.
    c6_angle = 3 * mechanism.body_index("c6") + 2
    assert c6_angle in analysis.free_coordinates
    alone = analysis.free_motions[:, list(analysis.free_coordinates).index(c6_angle)]
    np.testing.assert_allclose(alone / alone[c6_angle], np.eye(30)[c6_angle], atol=1e-12)


def test_a_duplicated_joint_is_named_redundant_not_the_original():
    mechanism = task5()
    duplicated = dataclasses.replace(mechanism, joints=(*mechanism.joints, mechanism.joints[3]))
    jacobian = jacobian_at(duplicated)
    analysis = analyse_jacobian(jacobian)
    pattern = build_pattern(duplicated)
    assert analysis.rank == 30
    labels = [equation_label(duplicated, pattern, row) for row in analysis.redundant_rows]
    assert labels == ["joints[14] (revolute c1–c5 at B), equation x", "joints[14] (revolute c1–c5 at B), equation y"]
    # each redundant row is the original row: the dependency has -1 there (scaled rows are equal)
    np.testing.assert_allclose(analysis.dependencies[[6, 7]], -np.eye(2), atol=1e-12)


def test_smallest_singular_triplet_near_the_dead_centre_matches_the_svd():
    """Task 5 at 0.06 m, 0.3 ms before its dead centre: cond ~ 3e4, unlike anywhere at 0.05 m."""
    mechanism = task5(amplitude=0.06)
    result = solve_kinematics(mechanism, np.linspace(0.0, 0.755, 756))
    jacobian = jacobian_at(mechanism, result.coordinates[-1], result.times[-1])
    analysis = analyse_jacobian(jacobian)
    u, values, vt = np.linalg.svd(scaled_dense(jacobian, analysis))
    assert analysis.rank == 30
    np.testing.assert_allclose(analysis.smallest_singular_value * analysis.sigma_max, values[-1], rtol=1e-8)
    assert abs(abs(vt[-1] @ analysis.smallest_motion) - 1.0) < 1e-8
    assert abs(abs(u[:, -1] @ analysis.smallest_equations) - 1.0) < 1e-8


#: The subprocess of `test_an_exactly_singular_square_jacobian_never_reaches_superlu`: analyses
#: the saved Jacobian many times (a crash, not an exception, is what is looked for) and checks
#: every answer against the reference rank and redundant rows, and its null spaces.
_ANALYSE_MANY_TIMES = """
import sys
import numpy as np
from scipy import sparse
from sparsekin.analysis.rank import analyse_jacobian
jacobian = sparse.csr_array(sparse.load_npz(sys.argv[1]))
rank, redundant, repeats = int(sys.argv[2]), [int(r) for r in sys.argv[3].split(",")], int(sys.argv[4])
for _ in range(repeats):
    analysis = analyse_jacobian(jacobian)
    assert analysis.rank == rank and analysis.redundant_rows.tolist() == redundant, analysis.redundant_rows
    assert np.abs(jacobian @ analysis.free_motions).max() < 1e-12
    assert np.abs(jacobian.T @ (analysis.row_scale[:, None] * analysis.dependencies)).max() < 1e-12
print("analysed", repeats, "times")
"""


def test_an_exactly_singular_square_jacobian_never_reaches_superlu(tmp_path):
    """Three parallelogram cells with a third bar each, no driver: a square 36 × 36 Jacobian of
    rank 33 (one redundant bar per cell, one free motion per cell: the cells sway).  Scaled
    (entries that are exactly 0 at the drawing dropped) it is structurally singular, and
    SuperLU reads past a column left without candidate rows: a process factoring it 60
    times crashed (SIGSEGV) in 9 of 10 runs before the structural check.  300 analyses in a
    fresh process, each checked against NumPy's SVD rank and the null spaces."""
    from scipy.sparse.csgraph import structural_rank

    from sparsekin.testset import parallel_bar_chain

    jacobian = jacobian_at(dataclasses.replace(parallel_bar_chain(3, bars=3), drivers=[]))
    analysis = analyse_jacobian(jacobian)
    scaled = sparse.csr_matrix(scaled_dense(jacobian, analysis))  # without the entries that are exactly 0
    assert jacobian.shape == (36, 36) and structural_rank(scaled) < 36  # the case that crashed
    rank, _ = svd_rank(scaled.toarray(), 36 * np.finfo(float).eps * 100)
    assert rank == analysis.rank == 33 and analysis.n_redundant == analysis.n_free == 3
    sparse.save_npz(tmp_path / "jacobian.npz", sparse.csr_matrix(jacobian))
    script = tmp_path / "analyse.py"
    script.write_text(_ANALYSE_MANY_TIMES)
    redundant = ",".join(map(str, analysis.redundant_rows))
    # one BLAS thread: 300 analyses in about 2 s, not a minute on a loaded machine (SuperLU is the same)
    environment = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]), OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, str(script), str(tmp_path / "jacobian.npz"), "33", redundant, "300"],
                          capture_output=True, text=True, env=environment, timeout=600, check=False)  # fmt: skip
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])  # -11: SIGSEGV
    assert done.stdout.strip() == "analysed 300 times"


@pytest.fixture(scope="module")
def chain():
    """Task 5 units in series, 10^5 bodies: (mechanism, Jacobian at t = 0)."""
    mechanism = task5_chain(10**4)
    return mechanism, jacobian_at(mechanism)


def test_a_chain_of_1e5_bodies_has_full_rank(chain):
    """(How long it takes: benchmarks/test_rank_speed.py.)"""
    _, jacobian = chain
    analysis = analyse_jacobian(jacobian)
    assert analysis.shape == (300_000, 300_000) and analysis.rank == 300_000
    # A long serial chain is ill-conditioned in absolute coordinates (about n²), but its
    # smallest singular value, 2e-10 of the largest, stays above the rank tolerance (7e-11).
    assert analysis.tolerance < 0.5 * analysis.smallest_singular_value < 1e-9
    residual = np.linalg.norm(analysis.row_scale * (jacobian @ (analysis.column_scale * analysis.smallest_motion)))
    np.testing.assert_allclose(residual, analysis.smallest_singular_value * analysis.sigma_max, rtol=1e-6)


def test_a_chain_of_1e5_bodies_without_one_joint_names_its_free_motions(chain):
    mechanism, _ = chain
    broken = without_joint_at(mechanism, "u5000.E")
    jacobian = jacobian_at(broken)
    analysis = analyse_jacobian(jacobian)
    assert analysis.rank == 299_998 and analysis.n_free == 2 and analysis.n_redundant == 0
    assert np.max(np.abs(jacobian @ analysis.free_motions)) < 1e-12
    moving = {broken.bodies[c // 3].name for c in analysis.free_coordinates}
    assert moving <= {f"u5000.c{k}" for k in range(1, 11)}


# ---------------------------------------------------------------------- check_model and `sparsekin check`
def test_task5_is_sound(capsys):
    report = check_model(load_model(TASK5_FILE))
    assert report.sound and report.assembled
    assert (report.rank, report.dof_by_count, report.dof_by_rank) == (30, (2, 0), (2, 0))
    assert main(["check", str(TASK5_FILE)]) == 0
    printed = capsys.readouterr().out
    assert "redundant equations: none" in printed and "free motions: none" in printed
    assert printed.rstrip().endswith("verdict: sound")


def test_the_triple_parallelogram_has_one_redundant_consistent_equation(capsys):
    report = check_model(load_model(TRIPLE_PARALLELOGRAM))
    assert report.problems == ("1 redundant equation",)
    assert (report.rank, report.dof_by_count, report.dof_by_rank) == (12, (0, -1), (1, 0))
    (redundant,) = report.redundant
    assert redundant.label.startswith("joints[5] (revolute coupler–crank2 at T2), equation")
    assert redundant.consistent and redundant.residual < 1e-15 and not redundant.involves_drivers
    assert main(["check", str(TRIPLE_PARALLELOGRAM)]) == 1
    assert "verdict: 1 redundant equation" in capsys.readouterr().out


def test_task5_without_joint_e_has_two_free_motions(tmp_path, capsys):
    path = tmp_path / "without_e.toml"
    path.write_text(TASK5_FILE.read_text().replace('[[joints]]\ntype = "revolute"\nbodies = ["c6", "c2"]\nat = "E"\n\n', ""))
    with pytest.warns(UnjoinedPointWarning, match='point "E" is carried by c2 and c6'):
        mechanism = load_model(path)
    report = check_model(mechanism)
    assert report.problems == ("2 free motions",)
    assert (report.dof_by_count, report.dof_by_rank) == ((4, 2), (4, 2))
    assert "c6 rotates about D (-0.2, 0.5)" in [motion.bodies for motion in report.free_motions]
    assert main(["check", str(path)]) == 1
    assert "free motions (2):" in capsys.readouterr().out


def test_an_unreachable_stroke_cannot_be_assembled():
    mechanism = task5()
    unreachable = dataclasses.replace(
        mechanism, drivers=(TranslationalDriver("actuator1", law=Linear(rate=0.0, start=5.0)), mechanism.drivers[1])
    )
    report = check_model(unreachable)
    assert not report.assembled and report.problems[0] == "cannot assemble at t = 0 s"
    assert report.assembly.startswith("cannot assemble at t = 0 s: Newton–Raphson did not converge")


def test_contradicting_joints_are_reported_once_the_model_moves():
    """A third crank 1 % longer: consistent as drawn, it locks the parallelogram (to second order)."""
    report = check_model(triple_parallelogram(crank2_length=1.01), time=0.0)
    assert [equation.consistent for equation in report.redundant] == [True]
    moved = check_model(triple_parallelogram(crank2_length=1.01), time=0.3)
    assert not moved.assembled or not all(equation.consistent for equation in moved.redundant)


def test_a_bad_file_is_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / "broken.toml"
    path.write_text(TASK5_FILE.read_text().replace('bodies = ["c3", "c4"]', 'bodies = ["c3", "c11"]'))
    assert main(["check", str(path)]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"sparsekin: error: {path}: joints[1].bodies[1]: unknown body")


# ---------------------------------------------------------------------- redundant equations in a run
def parallelogram_motion(times: np.ndarray):
    """Coordinates, velocities, accelerations (n, 12) and points T2, P of the exact motion."""
    theta = math.pi / 4 + times
    cosine, sine, zero, one = np.cos(theta), np.sin(theta), np.zeros_like(times), np.ones_like(times)
    q, qd, qdd = [], [], []
    for i in range(3):  # the cranks turn about their fixed pivots
        q += [zero + i, zero, theta]
        qd += [zero, zero, one]
        qdd += [zero, zero, zero]
    q += [cosine, sine, zero]  # the coupler translates with the tip of crank 0
    qd += [-sine, cosine, zero]
    qdd += [-cosine, -sine, zero]
    points = {
        "T2": (np.stack([2 + cosine, sine], 1), np.stack([-sine, cosine], 1), np.stack([-cosine, -sine], 1)),
        "P": (np.stack([1 + cosine, sine + 0.5], 1), np.stack([-sine, cosine], 1), np.stack([-cosine, -sine], 1)),
    }
    return (np.stack(q, 1), np.stack(qd, 1), np.stack(qdd, 1)), points


@pytest.mark.parametrize("source", ["file", "python"])
def test_the_triple_parallelogram_runs_exactly_without_its_redundant_equation(source):
    mechanism = load_model(TRIPLE_PARALLELOGRAM) if source == "file" else triple_parallelogram()
    times = np.linspace(0.0, 2.0, 201)
    with pytest.warns(RedundantConstraintWarning, match=r"13 equations for 12 coordinates: 1 redundant equation "
                      r"left out .*joints\[5\] \(revolute coupler–crank2 at T2\), equation"):  # fmt: skip
        result = solve_kinematics(mechanism, times)
    assert result.complete and result.n_subdivisions == 0
    assert result.redundant_equations[0].startswith("joints[5] (revolute coupler–crank2 at T2)")
    expected, points = parallelogram_motion(times)
    for solved, exact, scale in zip((result.coordinates, result.velocities, result.accelerations), expected, (3, 1, 1)):
        np.testing.assert_allclose(solved, exact, rtol=RTOL, atol=RTOL * scale)
    for name, motion in points.items():
        for solved, exact in zip(result.point(name), motion):
            np.testing.assert_allclose(solved, exact, rtol=RTOL, atol=RTOL * 3)


def test_the_command_line_runs_the_triple_parallelogram_with_a_one_line_warning(tmp_path, capsys):
    assert main(["run", str(TRIPLE_PARALLELOGRAM), "--out", str(tmp_path)]) == 0
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("sparsekin: warning: 13 equations for 12 coordinates: 1 redundant equation left out")


def test_contradicting_redundant_joints_stop_the_run():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RedundantConstraintWarning)
        with pytest.raises(ConvergenceError, match=r"the redundant equation joints\[5\] .* is not satisfied at "
                           r"t = 0\.1 s: residual 6\.\d+e-05; the redundant joints contradict each other") as caught:  # fmt: skip
            solve_kinematics(triple_parallelogram(crank2_length=1.01), np.linspace(0.0, 1.0, 11))
    assert caught.value.result.n_times == 1


def test_redundant_drivers_are_refused():
    with pytest.raises(ModelError, match=r"12 coordinates but 14 equations, and the drivers take part in a "
                       r"redundancy: .*drivers\[1\] \(angle crank1 − ground\)"):  # fmt: skip
        solve_kinematics(triple_parallelogram(drivers=2), [0.0, 0.1])


def test_free_motions_are_refused_with_their_description():
    with pytest.raises(ModelError, match=r"30 coordinates but 28 equations of rank 28: 2 free motions left after "
                       r"the 2 drivers: .*c6 rotates about D \(-0\.2, 0\.5\)"):  # fmt: skip
        solve_kinematics(without_joint_at(task5(), "E"), [0.0, 0.1])


def test_bodies_without_any_equation_are_refused():
    free = Mechanism(points={"A": (0.0, 0.0)}, bodies=[Body("c1", origin="A")])
    with pytest.raises(ModelError, match=r"3 coordinates but no equation: every body \(c1\) moves freely"):
        solve_kinematics(free, [0.0])
    assert check_model(free).problems == ("3 free motions",)


# ---------------------------------------------------------------------- lock-up
@pytest.fixture(scope="module")
def lock_up():
    """Task 5 with strokes of 0.06 m over 10 s at 1 ms: the error it stops with."""
    times = np.linspace(0.0, 10.0, 10_001)
    with pytest.raises(SingularConfigurationError) as caught:
        solve_kinematics(task5(amplitude=0.06), times)
    return times, caught.value


def test_strokes_of_6_cm_lock_at_the_dead_centre(lock_up):
    times, error = lock_up
    assert isinstance(error, SingularJacobianError) and isinstance(error, ConvergenceError)
    # The dead centre, located to a millionth of the step: 0.7552443 s.
    assert 0.755244 < error.time < 0.7552446
    message = str(error)
    assert message.startswith("singular configuration at t = 0.755244 s: drivers[0] (stroke of joint "
                              '"actuator1") = 0.878959; drivers[1] (stroke of joint "actuator2") = 1.13137; '
                              "uncontrolled motion: ")  # fmt: skip
    assert " rotates about " in message and "; constraints involved: " in message
    assert error.driver_values == pytest.approx(
        {'drivers[0] (stroke of joint "actuator1")': 0.8246211251235321 + 0.06 * math.sin(1.5 * error.time),
         'drivers[1] (stroke of joint "actuator2")': 1.0770329614269007 + 0.06 * math.sin(1.5 * error.time)},
        abs=1e-12,
    )  # fmt: skip
    assert error.smallest_singular_value < 1e-5
    solved = error.result
    assert solved.n_times == 756 == np.searchsorted(times, error.time)
    np.testing.assert_array_equal(solved.times, times[:756])
    assert np.all(np.isfinite(solved.coordinates)) and np.all(np.isfinite(solved.accelerations))


def test_the_constraints_involved_are_those_of_the_dense_svd(lock_up):
    """The left singular vector at the last sample, from a dense SVD, names the same four equations."""
    _, error = lock_up
    mechanism = task5(amplitude=0.06)
    pattern = build_pattern(mechanism)
    solved = error.result
    jacobian = jacobian_at(mechanism, solved.coordinates[-1], solved.times[-1])
    analysis = analyse_jacobian(jacobian)
    u = np.linalg.svd(scaled_dense(jacobian, analysis))[0][:, -1]
    largest = np.argsort(-np.abs(u))[:4]
    involved = str(error).split("constraints involved: ")[1]
    for row in largest:
        assert equation_label(mechanism, pattern, int(row)) in involved
    # The dead centre of c3: the actuator-2 line H–G through its pivot L.
    for label in ('drivers[1] (stroke of joint "actuator2")', "joints[0] (revolute c3–ground at L)",
                  "joints[7] (revolute c3–c9 at G)", "joints[11] (revolute c10–ground at H)"):  # fmt: skip
        assert label in involved


def test_strokes_of_5_cm_run_through_ten_seconds():
    result = solve_kinematics(task5(amplitude=0.05), np.linspace(0.0, 10.0, 10_001))
    assert result.complete and result.n_subdivisions == 0


def test_the_command_line_stops_at_the_dead_centre_and_writes_what_it_solved(tmp_path, capsys):
    model = tmp_path / "task5_006.toml"
    model.write_text(TASK5_FILE.read_text().replace("amplitude = 0.05", "amplitude = 0.06"))
    assert main(["run", str(model), "--out", str(tmp_path / "out")]) == 3
    first, second = capsys.readouterr().err.splitlines()
    assert first.startswith("sparsekin: analysis stopped: singular configuration at t = 0.755244 s")
    assert second.startswith("sparsekin: wrote 76 of 1001 samples")
    assert len((tmp_path / "out" / "points.csv").read_text().splitlines()) == 1 + 76


def test_a_healthy_mechanism_that_cannot_follow_its_law_is_not_called_singular():
    """A stroke that jumps out of reach at t = 0.5 s: no step is short enough, the Jacobian is regular."""

    class OutOfReach:
        def evaluate(self, t, initial):
            return initial + (5.0 if t >= 0.5 else 0.0), 0.0, 0.0

    mechanism = task5()
    jumping = dataclasses.replace(
        mechanism, drivers=(TranslationalDriver("actuator1", law=OutOfReach()), mechanism.drivers[1])
    )
    with pytest.raises(ConvergenceError, match=r"at t = 0\.5 s .*the Jacobian at the last configuration solved "
                       r"\(t = 0\.4999999\d* s\) is regular") as caught:  # fmt: skip
        solve_kinematics(jumping, np.linspace(0.0, 1.0, 11))
    assert not isinstance(caught.value, SingularJacobianError)
    assert caught.value.result.n_times == 5


def test_a_model_drawn_at_a_dead_centre_is_refused_at_t_0():
    """A slider-crank drawn stretched out, its slider driven: the crank angle is not controlled.

    The equations are dependent at the first sample: a model error that names the
    dependency (as `check` does), not a lock-up."""
    mechanism = Mechanism(
        points={"O": (0.0, 0.0), "A": (0.1, 0.0), "B": (0.4, 0.0)},
        bodies=[Body("crank", origin="O", points=("O", "A")), Body("rod", origin="A", points=("A", "B")),
                Body("slider", origin="B", points=("B",))],
        joints=[Revolute(("crank", "ground"), at="O"), Revolute(("crank", "rod"), at="A"),
                Revolute(("rod", "slider"), at="B"), Translational(("ground", "slider"), axis=("O", "B"), name="guide")],
        drivers=[TranslationalDriver("guide", law=Linear(rate=-0.1))],
    )  # fmt: skip
    with pytest.raises(ModelError, match=r"the 9 equations have rank 8 at t = 0 s: drivers\[0\] \(stroke of joint "
                       r'"guide"\), equation driven value depends on joints\[0\] .*so the drivers leave a motion free: '
                       r"crank rotates about O \(0, 0\), rod rotates about B"):  # fmt: skip
        solve_kinematics(mechanism, [0.0, 0.1])


def test_the_redundancy_warning_points_at_the_call_of_solve_kinematics():
    with pytest.warns(RedundantConstraintWarning) as caught:
        solve_kinematics(triple_parallelogram(), np.linspace(0.0, 0.2, 3))
    assert [w.filename for w in caught if issubclass(w.category, RedundantConstraintWarning)] == [__file__]
