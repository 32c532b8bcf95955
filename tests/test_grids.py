"""Grid repeats against the same mechanisms written out by hand, and against closed forms.

`hand_built` writes every copy as objects; a grid must give the same elements
(`Mechanism.expanded`), the same equations (`assert_same_equations`: pattern, residual,
Jacobian and acceleration right-hand side at random configurations) and the same motion.
The rotating squares and the lattice also follow their exact motions.
"""

from __future__ import annotations

import contextlib
import math
import re
from dataclasses import replace

import numpy as np
import pytest
from examples_loader import EXAMPLES
from hand_built import lattice_as_before, lattice_by_hand, rotating_squares_by_hand
from test_repeat import assert_same_equations

from sparsekin.engine.discretization import Discretization
from sparsekin import (Body, Mechanism, ModelError, RedundantConstraintWarning, Revolute, load_model, save_model,
                       solve_kinematics, testset)
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern
from sparsekin.model.units import Cycle, OnCopies, Repeat, Step, Unit

# Newton converges to 1e-12 relative; a chain of n bars accumulates n roundings.
POSITION_ATOL = 1e-11


def squares_motion(n: int, times: np.ndarray, angle=0.3, amplitude=0.2, omega=1.0):
    """Closed form: the centres (i·p(θ), j·p(θ)) and angles (−1)^(i+j)·θ of every square,
    with their first and second time derivatives; arrays of shape (n_t, n, n, 3), [i, j]."""
    theta = angle + amplitude * np.sin(omega * times)
    rate = amplitude * omega * np.cos(omega * times)
    accel = -amplitude * omega**2 * np.sin(omega * times)
    pitch = np.cos(theta) + np.sin(theta)
    slope = np.cos(theta) - np.sin(theta)  # dp/dθ; d²p/dθ² = −p
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    sign = (-1.0) ** (i + j)
    out = []
    for p, a in ((pitch, theta), (slope * rate, rate), (slope * accel - pitch * rate**2, accel)):
        out.append(np.stack(np.broadcast_arrays(i * p[:, None, None], j * p[:, None, None],
                                                sign * a[:, None, None]), axis=-1))  # fmt: skip
    return out


def square_columns(mechanism: Mechanism, n: int) -> np.ndarray:
    """The coordinate columns (x, y, angle) of square (i, j), shape (n, n, 3)."""
    bodies = np.array([[mechanism.body_index(f"s{i}_{j}.sq") for j in range(n)] for i in range(n)])
    return 3 * bodies[..., None] + np.arange(3)


# ---------------------------------------------------------------------- the rotating squares
@pytest.mark.parametrize("n", [2, 3, 6])
def test_rotating_squares_follow_the_closed_form_with_poissons_ratio_minus_one(n):
    mechanism = testset.rotating_squares(n)
    times = np.linspace(0.0, 2 * np.pi, 41)
    with pytest.warns(RedundantConstraintWarning) if n > 2 else contextlib.nullcontext():  # (n − 2)² left out
        result = solve_kinematics(mechanism, times)
    position, velocity, acceleration = squares_motion(n, times)
    columns = square_columns(mechanism, n)
    tolerance = POSITION_ATOL * n
    np.testing.assert_allclose(result.coordinates[:, columns], position, rtol=0, atol=tolerance)
    np.testing.assert_allclose(result.velocities[:, columns], velocity, rtol=0, atol=10 * tolerance)
    np.testing.assert_allclose(result.accelerations[:, columns], acceleration, rtol=0, atol=100 * tolerance)
    width = result.coordinates[:, columns[-1, 0, 0]] - result.coordinates[:, columns[0, 0, 0]]
    height = result.coordinates[:, columns[0, -1, 1]] - result.coordinates[:, columns[0, 0, 1]]
    np.testing.assert_allclose(width, height, rtol=0, atol=tolerance)  # strains equal: Poisson's ratio −1
    assert np.ptp(width) > 0.05 * (n - 1)  # and the lattice does open and close


@pytest.mark.parametrize("n", [2, 3, 5])
def test_rotating_squares_counts_follow_the_specification(n):
    mechanism = testset.rotating_squares(n)
    assert mechanism.n_bodies == n * n and mechanism.n_coordinates == 3 * n * n
    assert mechanism.n_equations == 4 * n * n - 4 * n + 4
    assert sum(isinstance(j, Revolute) for j in mechanism.joints) == 2 * n * (n - 1) + 1
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    np.testing.assert_allclose(assembler.residual, 0.0, atol=1e-14)  # assembled as drawn
    rank = np.linalg.matrix_rank(assembler.jacobian.toarray())
    assert rank == 3 * n * n  # no degree of freedom; the rest are (n − 2)² states of self-stress
    assert mechanism.n_equations - rank == (n - 2) ** 2


def test_rotating_squares_are_the_specification_written_by_hand(rng):
    n = 4
    grid, by_hand = testset.rotating_squares(n), rotating_squares_by_hand(n)
    assert [b.name for b in grid.bodies] == [b.name for b in by_hand.bodies]
    assert [(j.bodies, type(j)) for j in grid.joints] == [(j.bodies, type(j)) for j in by_hand.joints]
    assert grid.drivers[0] == by_hand.drivers[0]
    assert_same_equations(grid, by_hand, rng)


def test_the_rotating_squares_file_has_a_two_by_two_motif_and_the_same_motion():
    mechanism = load_model(EXAMPLES / "rotating_squares.toml")
    repeat = mechanism.repeats[0]
    assert repeat.is_grid and len(repeat.unit.bodies) == 4
    ni, nj = repeat.count
    times = np.linspace(0.0, 3.0, 13)
    with pytest.warns(RedundantConstraintWarning):  # its states of self-stress are left out
        result = solve_kinematics(mechanism, times)
    position = squares_motion(2 * max(ni, nj), times)[0]
    for i, j in [(0, 0), (1, 0), (2 * ni - 1, 0), (0, 2 * nj - 1), (2 * ni - 1, 2 * nj - 1), (3, 2)]:
        name = f"s{i // 2}_{j // 2}." + "abcd"[i % 2 + 2 * (j % 2)]
        b = mechanism.body_index(name)
        np.testing.assert_allclose(result.coordinates[:, 3 * b : 3 * b + 3], position[:, i, j], atol=1e-10)


# ---------------------------------------------------------------------- the lattice
def test_the_lattice_grid_is_the_lattice_by_hand_and_moves_as_before(rng):
    rows, cols = 4, 5
    grid = testset.lattice(rows, cols)
    assert grid.expanded() == lattice_by_hand(rows, cols)
    assert_same_equations(grid, lattice_by_hand(rows, cols), rng)
    before = lattice_as_before(rows, cols)
    assert (grid.n_bodies, grid.n_joints, grid.n_drivers, grid.n_equations) == (
        before.n_bodies, before.n_joints, before.n_drivers, before.n_equations)  # fmt: skip
    times = np.linspace(0.0, 2.0, 41)
    result, reference = solve_kinematics(grid, times), solve_kinematics(before, times)
    for r in range(1, rows + 1):
        for c in range(cols + 1):
            pairs = [(f"c{c}_{r - 1}.V", f"V{r}_{c}")] + ([(f"c{c}_{r - 1}.H", f"H{r}_{c}")] if c < cols else [])
            for new, old in pairs:
                a, b = grid.body_index(new), before.body_index(old)
                np.testing.assert_allclose(result.coordinates[:, 3 * a : 3 * a + 3],
                                           reference.coordinates[:, 3 * b : 3 * b + 3], rtol=0, atol=1e-12)  # fmt: skip


def test_the_lattice_file_is_the_test_set_lattice():
    from_file = load_model(EXAMPLES / "lattice.toml")
    rows, cols = from_file.repeats[0].count[1], from_file.repeats[0].count[0] - 1
    assert from_file == replace(testset.lattice(rows, cols), analysis=from_file.analysis)


# ---------------------------------------------------------------------- grids in files
@pytest.mark.parametrize("build", [lambda: testset.lattice(3, 2), lambda: testset.rotating_squares(3),
                                   lambda: load_model(EXAMPLES / "rotating_squares.toml")])  # fmt: skip
def test_save_model_writes_a_grid_back_as_a_grid(build, tmp_path):
    mechanism = build()
    save_model(mechanism, tmp_path / "grid.toml")
    text = (tmp_path / "grid.toml").read_text()
    assert re.search(r"count = \[\d+, \d+\]", text) and "[bodies." not in text  # the unit, not its copies
    assert load_model(tmp_path / "grid.toml") == mechanism


def bar_unit(**only) -> Unit:
    return Unit("cell", points={"A": (0.0, 0.0), "B": (1.0, 0.0), "C": (0.0, 1.0)},
                bodies=[Body("bar", origin="A", points=("A", "B")), Body("post", origin="A", points=("A", "C"))],
                joints=[Revolute(("bar", "left.bar"), at="A"), Revolute(("post", "below.post"), at="A"),
                        Revolute(("bar", "post"), at="A")],
                **only)  # fmt: skip


def test_neighbours_open_and_attached_boundaries_and_copies_restrictions():
    grid = Repeat(bar_unit(), count=(3, 2), prefix="g", offset=((1.0, 0.0), (0.0, 1.0)),
                  boundary={"below.post": "ground"})  # fmt: skip
    mechanism = Mechanism(points={}, bodies=[], repeats=[grid])
    joints = [joint.bodies for joint in mechanism.joints]
    # copy (0, 0): no left (open), below attached to the ground
    assert joints[:2] == [("g0_0.post", "ground"), ("g0_0.bar", "g0_0.post")]
    assert ("g1_1.bar", "g0_1.bar") in joints and ("g1_1.post", "g1_0.post") in joints
    assert mechanism.n_joints == 3 * 6 - 2  # the two left hinges of column 0 are left out
    assert mechanism.copies[0].n_left_out() == 2
    restricted = Unit("cell", points={"A": (0.0, 0.0), "B": (1.0, 0.0)},
                      bodies=[Body("bar", origin="A", points=("A", "B")),
                              OnCopies(Body("tab", origin="B", points=("B",)), i=-1, j=(0, 0))],
                      joints=[OnCopies(Revolute(("bar", "ground"), at="A"), i=0), Revolute(("tab", "bar"), at="B")])
    mechanism = Mechanism(points={}, bodies=[], repeats=[Repeat(restricted, count=(3, 2), prefix="r")])
    assert [b.name for b in mechanism.bodies] == ["r0_0.bar", "r1_0.bar", "r2_0.bar", "r2_0.tab", "r0_1.bar",
                                                  "r1_1.bar", "r2_1.bar"]  # fmt: skip
    assert [j.bodies for j in mechanism.joints] == [("r0_0.bar", "ground"), ("r2_0.tab", "r2_0.bar"),
                                                    ("r0_1.bar", "ground")]  # fmt: skip
    assert mechanism.body_index("r0_1.bar") == 4 and mechanism.frames().shape == (7, 3)
    with pytest.raises(KeyError):
        mechanism.body_index("r2_1.tab")  # that copy has no tab


def test_a_one_column_grid_leaves_its_left_hinges_out_of_every_copy():
    """A unit part that no copy has (the left hinge of a one-column grid) adds no equation:
    the pattern is that of the grid written out."""
    from sparsekin.engine.pattern import build_pattern

    grid = Repeat(bar_unit(), count=(1, 3), prefix="g", offset=((1.0, 0.0), (0.0, 1.0)),
                  boundary={"below.post": "ground"})  # fmt: skip
    mechanism = Mechanism(points={}, bodies=[], repeats=[grid])
    pattern, by_hand = build_pattern(mechanism), build_pattern(mechanism.expanded())
    assert (pattern.n_equations, pattern.n_coordinates) == (by_hand.n_equations, by_hand.n_coordinates) == (12, 18)
    np.testing.assert_array_equal(pattern.indptr, by_hand.indptr)
    np.testing.assert_array_equal(pattern.indices, by_hand.indices)


@pytest.mark.parametrize("count, copy", [(10, "copy 5"), ((7, 7), "copy (5, 0)")])
def test_a_part_on_some_copies_only_is_checked_in_the_first_copy_that_has_it(count, copy):
    """A part restricted to copies in the middle of a repeat, away from those checked for the
    drawing (the first, the last, a period), is checked too: its mistake is named."""
    unit = Unit("cell", points={"A": (0.0, 0.0), "B": (1.0, 0.0)}, bodies=[Body("bar", origin="A", points=("A", "B"))],
                joints=[Revolute(("bar", "ground"), at="A"), OnCopies(Revolute(("bar", "nosuch"), at="B"), i=5)])
    offset = (2.0, 0.0) if isinstance(count, int) else ((2.0, 0.0), (0.0, 2.0))
    with pytest.raises(ModelError, match=rf'repeat\[0\] {re.escape(copy)}: units.cell.joints\[1\].bodies\[1\]: unknown body "nosuch"'):
        Mechanism(points={}, bodies=[], repeats=[Repeat(unit, count=count, prefix="u", offset=offset)])


def test_grid_variations_step_along_i_and_j_and_cycle_on_a_checkerboard():
    unit = Unit("cell", points={"A": (0.0, 0.0)}, bodies=[Body("bar", origin="A", angle=0.1)])
    repeat = Repeat(unit, count=(3, 2), prefix="v", offset=((2.0, 0.0), (0.0, 3.0)),
                    vary={"points.A": Step(((0.1, 0.0), (0.0, 0.2))), "bodies.bar.angle": Cycle([0.1, -0.1])})
    mechanism = Mechanism(points={}, bodies=[], repeats=[repeat])
    assert mechanism.points["v2_1.A"] == pytest.approx((2 * 2.1, 3.2))
    frames = mechanism.frames()
    np.testing.assert_allclose(frames[:, 2], [0.1, -0.1, 0.1, -0.1, 0.1, -0.1])
    assert mechanism.bodies[4].angle == 0.1 and mechanism.bodies[4].name == "v1_1.bar"


GRID_MISTAKES = {
    "prev in a grid": (dict(joints=[Revolute(("bar", "prev.bar"), at="A")]), (2, 2), {},
                       r'units\.cell\.joints\[0\]\.bodies\[1\]: "prev\.bar": a grid has no copy before; use "left\.NAME"'),
    "left in a chain": (dict(joints=[Revolute(("bar", "left.bar"), at="A")]), 3, {}, r'needs a grid \(count = \[ni, nj\]\)'),
    "left names no body": (dict(joints=[Revolute(("bar", "left.arm"), at="A")]), (2, 2), {},
                           r'joints\[0\]\.bodies\[1\]: "left\.arm" names no body of the unit'),
    "a scalar step": (dict(), (2, 2), dict(vary={"points.A": Step((0.1, 0.2))}), r"a grid's step is \[\[dxi, dyi\]"),
    "a column beyond": (dict(bodies=[OnCopies(Body("bar", origin="A"), i=4)]), (3, 2), {},
                        r"bodies\.bar\.copies\.i: 4 is beyond the repeat's 3 columns"),
    "first in a grid": (dict(), (2, 2), dict(first={"prev.bar": "ground"}), r"first: a grid's missing neighbours"),
}


@pytest.mark.parametrize(("unit_changes", "count", "repeat_changes", "message"), GRID_MISTAKES.values(),
                         ids=GRID_MISTAKES.keys())  # fmt: skip
def test_a_grid_mistake_names_the_repeat_and_the_element(unit_changes, count, repeat_changes, message):
    parts = dict(points={"A": (0.0, 0.0)}, bodies=[Body("bar", origin="A")]) | unit_changes
    with pytest.raises(ModelError, match=message):
        Repeat(Unit("cell", **parts), count=count, **repeat_changes)


def test_a_bad_copy_is_named_by_its_column_and_row(tmp_path):
    text = (EXAMPLES / "lattice.toml").read_text().replace('at = "T"', 'at = "Z"', 1)
    (tmp_path / "bad.toml").write_text(text)
    with pytest.raises(ModelError, match=r'repeat\[0\] copy \(0, 0\): units\.cell\.joints\[1\]\.at: unknown point "Z"'):
        load_model(tmp_path / "bad.toml")
    text = (EXAMPLES / "lattice.toml").read_text().replace('bodies = ["left.H", "V"]', 'bodies = ["left.H", "W"]')
    (tmp_path / "bad.toml").write_text(text)
    with pytest.raises(ModelError, match=r'repeat\[0\] copy \(1, 0\): units\.cell\.joints\[2\]\.bodies\[1\]: unknown body "W"'):
        load_model(tmp_path / "bad.toml")
    text = (EXAMPLES / "lattice.toml").read_text().replace('"below.V"', '"below.W"', 1)
    (tmp_path / "bad.toml").write_text(text)
    with pytest.raises(ModelError, match=r'units\.cell\.joints\[0\]\.bodies\[1\]: "below\.W" names no body of the unit'):
        load_model(tmp_path / "bad.toml")


def test_copies_is_a_key_of_unit_parts_only(tmp_path):
    text = (EXAMPLES / "slider_crank.toml").read_text().replace("[[joints]]", "[[joints]]\ncopies = { i = 0 }", 1)
    (tmp_path / "bad.toml").write_text(text)
    with pytest.raises(ModelError, match=r'joints\[0\]: unknown key "copies"'):
        load_model(tmp_path / "bad.toml")


def test_grid_angles_are_exact_for_a_pitch_from_the_file():
    """The contract's rotating-squares offset, 2·(cos 0.3 + sin 0.3), to the file's digits."""
    pitch = load_model(EXAMPLES / "rotating_squares.toml").repeats[0].offset[0][0]
    assert pitch == pytest.approx(2 * (math.cos(0.3) + math.sin(0.3)), abs=1e-12)


def test_the_lattice_size_figure_shows_poissons_ratio_minus_one(tmp_path):
    from sparsekin.plots.metamaterials import lattice_size, plot_lattice_size

    with pytest.warns(RedundantConstraintWarning):  # the one state of self-stress of 3 × 3 squares
        result = solve_kinematics(testset.rotating_squares(3), np.linspace(0.0, 3.0, 31))
    bodies = (("s0_0.sq", "s2_0.sq"), ("s0_0.sq", "s0_2.sq"), "s1_1.sq")
    size = lattice_size(result, *bodies)
    theta = 0.3 + 0.2 * np.sin(result.times)
    np.testing.assert_allclose(size.opening, theta, atol=1e-12)
    np.testing.assert_allclose(size.width, 2 * (np.cos(theta) + np.sin(theta)), atol=1e-11)
    np.testing.assert_allclose(size.poisson_ratio[np.isfinite(size.poisson_ratio)], -1.0, atol=1e-9)
    path = plot_lattice_size(result, *bodies, tmp_path / "size.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


LATTICE_FILE_MISTAKES = {
    "a zero count": (("count = [9, 6]", "count = [0, 6]"), r"repeat\[0\]\.count\[0\]: expected a whole number >= 1, got 0"),
    "three counts": (("count = [9, 6]", "count = [9, 6, 2]"), r"repeat\[0\]\.count: expected a number of copies or \[ni, nj\]"),
    "one offset": (("offset = [[1.0, 0.0], [0.0, 1.0]]", "offset = [1.0, 0.0]"),
                   r"repeat\[0\]\.offset: expected two lattice vectors \[\[dxi, dyi\], \[dxj, dyj\]\]"),
    "a boundary above": (('boundary = { "below.V" = "ground", "below.H" = "ground" }', 'boundary = { "above.V" = "ground" }'),
                         r'repeat\[0\]\.boundary: expected keys "left\.NAME" or "below\.NAME" with NAME a body of unit "cell"'),
    "copies k": (("copies = { i = [0, -2] }", "copies = { k = 1 }"), r'units\.cell\.bodies\.H\.copies: unknown key "k"'),
    "an empty range": (("copies = { i = [0, -2] }", "copies = { i = [3, 1] }"), r"bodies\.H\.copies\.i: the range \[3, 1\] keeps no column"),
    "first in a grid": (("count = [9, 6]", 'count = [9, 6]\nfirst = { "prev.V" = "ground" }'),
                        r"repeat\[0\]\.first: a grid's missing neighbours are attached with boundary"),
    "a scalar step": (('"drivers[0].law.phase".cycle', '"drivers[0].law.phase".step = 0.1\n"drivers[0].law.amplitude".cycle'),
                      r"""repeat\[0\]\.vary\."drivers\[0\]\.law\.phase"\.step: a grid's step is \[si, sj\]"""),
}


@pytest.mark.parametrize(("edit", "message"), LATTICE_FILE_MISTAKES.values(), ids=LATTICE_FILE_MISTAKES.keys())
def test_a_mistake_in_a_grid_file_is_one_line_naming_it(edit, message, tmp_path):
    text = (EXAMPLES / "lattice.toml").read_text()
    assert edit[0] in text
    (tmp_path / "bad.toml").write_text(text.replace(*edit, 1))
    with pytest.raises(ModelError, match=message) as caught:
        load_model(tmp_path / "bad.toml")
    assert "\n" not in str(caught.value)


def test_a_point_rides_on_the_first_body_of_its_copy_that_lists_it():
    """As in the mechanism written by hand: where the first body that lists a point is left
    out of a copy, the point rides on the next one (and on the ground if none)."""
    from sparsekin.engine.pattern import build_point_map

    unit = Unit("cell", points={"A": (0.0, 0.0), "B": (1.0, 0.0), "C": (1.0, 1.0)},
                bodies=[OnCopies(Body("first", origin="A", points=("A", "B")), i=0),
                        Body("second", origin="B", points=("B",)), OnCopies(Body("third", origin="C", points=("C",)), i=1)])
    mechanism = Mechanism(points={}, bodies=[], repeats=[Repeat(unit, count=(2, 1), prefix="g")])
    grid, by_hand = build_point_map(mechanism), build_point_map(mechanism.expanded())
    for name in ("g0_0.A", "g0_0.B", "g1_0.A", "g1_0.B", "g0_0.C", "g1_0.C"):
        assert grid.locate(name)[0] == by_hand.locate(name)[0], name
    assert grid.locate("g1_0.B")[0] == mechanism.body_index("g1_0.second") and grid.locate("g1_0.A")[0] == -1


def test_masses_and_loads_on_some_copies_give_the_forces_of_the_grid_written_out():
    """The forces that hold a grid's motion (masses of present bodies, loads on some rows,
    a harmonic load law) are those of the same mechanism written copy by copy."""
    from sparsekin import Force
    from sparsekin import Harmonic as Law

    cell, vary = testset.lattice_unit(3)
    bodies = (replace(cell.bodies[0], mass=1.5, inertia=0.1), replace(cell.bodies[1], mass=0.5, inertia=0.02))
    loaded = Unit(cell.name, points=cell.points, bodies=bodies, joints=cell.joints, drivers=cell.drivers,
                  loads=[OnCopies(Force("V", at="T", value=(Law(amplitude=2.0, omega=3.0), -4.0)), j=-1),
                         OnCopies(Force("H", at="R", value=(0.0, -1.0)), i=(1, 2))],
                  only=cell.only)  # fmt: skip
    repeat = Repeat(loaded, count=(4, 3), prefix="c", offset=((1.0, 0.0), (0.0, 1.0)), vary=vary,
                    boundary={"below.V": "ground", "below.H": "ground"})  # fmt: skip
    grid = Mechanism(points={}, bodies=[], repeats=[repeat], gravity=(0.0, -9.81))
    by_hand = grid.expanded()
    assert grid.n_loads == by_hand.n_loads == 4 + 2 * 3
    times = np.linspace(0.0, 1.0, 11)
    result, reference = solve_kinematics(grid, times, forces="all"), solve_kinematics(by_hand, times, forces="all")
    assert result.force_labels == reference.force_labels
    scale = np.abs(reference.force_tracks).max()
    np.testing.assert_allclose(result.force_tracks, reference.force_tracks, rtol=0, atol=1e-10 * scale)


def expected_names(unit_parts, count, boundary):
    """Brute force, copy by copy, straight from the contract's words: the body names and
    the joints' body pairs of a grid of `unit_parts` = (bodies, joints), each part
    ``(name or pair, i bound, j bound)`` with bounds None, an integer or (first, last)."""
    ni, nj = count

    def keeps(bound, index, size):
        if bound is None:
            return True
        first, last = (bound, bound) if isinstance(bound, int) else bound
        first, last = (b + size if b < 0 else b for b in (first, last))
        return first <= index <= last

    def has(i, j, body):
        return 0 <= i < ni and 0 <= j < nj and any(
            name == body and keeps(bi, i, ni) and keeps(bj, j, nj) for name, bi, bj in unit_parts[0])

    bodies, joints = [], []
    for j in range(nj):
        for i in range(ni):
            bodies += [f"g{i}_{j}.{name}" for name, bi, bj in unit_parts[0] if has(i, j, name)]
    for j in range(nj):
        for i in range(ni):
            for pair, bi, bj in unit_parts[1]:
                if not (keeps(bi, i, ni) and keeps(bj, j, nj)):
                    continue
                names = []
                for reference in pair:
                    other = {"left.": (i - 1, j), "below.": (i, j - 1)}.get(reference.split(".")[0] + ".", (i, j))
                    local = reference.split(".")[-1]
                    if other == (i, j) or has(*other, local):
                        names.append(f"g{other[0]}_{other[1]}.{local}" if has(*other, local) else None)
                    elif not (0 <= other[0] < ni and 0 <= other[1] < nj) and reference in boundary:
                        names.append(boundary[reference])
                    else:
                        names.append(None)
                if None not in names:
                    joints.append(tuple(names))
    return bodies, joints


GRID_SHAPES = {
    "bars on some columns": (
        [("a", None, None), ("b", (0, -2), None), ("c", None, (1, 2))],
        [(("a", "left.a"), None, None), (("b", "a"), None, None), (("c", "below.a"), None, None),
         (("c", "left.b"), None, -1), (("a", "below.c"), 1, None)],
        (4, 3), {"below.a": "ground"}),
    "a single column and row": (
        [("a", None, None), ("b", -1, -1)],
        [(("a", "below.a"), None, None), (("b", "left.a"), None, None), (("a", "left.a"), None, (1, 1))],
        (1, 2), {"left.a": "ground"}),
}


@pytest.mark.parametrize(("bodies", "joints", "count", "boundary"), GRID_SHAPES.values(), ids=GRID_SHAPES.keys())
def test_which_parts_each_copy_has_follows_the_contract_word_for_word(bodies, joints, count, boundary):
    def wrapped(part, bound_i, bound_j):
        return part if bound_i is None and bound_j is None else OnCopies(part, i=bound_i, j=bound_j)

    unit = Unit("cell", points={"A": (0.0, 0.0)},
                bodies=[wrapped(Body(name, origin="A"), bi, bj) for name, bi, bj in bodies],
                joints=[wrapped(Revolute(pair, at="A"), bi, bj) for pair, bi, bj in joints])  # fmt: skip
    mechanism = Mechanism(points={}, bodies=[], repeats=[Repeat(unit, count=count, prefix="g", boundary=boundary)])
    expected_bodies, expected_joints = expected_names((bodies, joints), count, boundary)
    assert list(mechanism.body_names) == expected_bodies
    assert [joint.bodies for joint in mechanism.joints] == expected_joints
    assert mechanism.frames().shape == (len(expected_bodies), 3)
    assert build_pattern(mechanism).n_equations == 2 * len(expected_joints)


@pytest.mark.parametrize(("count", "bound", "message"), [
    (1, 3, r"3 is beyond the repeat's 1 copy \(0 … 0"),
    (3, (2, 1), r"the range \[2, 1\] keeps no copy$"),
])  # fmt: skip
def test_a_chain_restriction_beyond_its_copies_is_named_in_words(count, bound, message):
    unit = Unit("cell", points={"A": (0.0, 0.0)}, bodies=[Body("bar", origin="A", points=("A",))],
                joints=[OnCopies(Revolute(("bar", "ground"), at="A"), i=bound)])
    with pytest.raises(ModelError, match=message):
        Mechanism(points={}, bodies=[], repeats=[Repeat(unit, count=count, prefix="u")])
