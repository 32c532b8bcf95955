"""Exact link lengths on an approximate drawing (`Body.lengths`), and the assembly from it.

Theo Jansen's leg from its thirteen "holy numbers" drawn on a plan rounded to whole
units: its foot path must be the exact one, which the test computes on its own by
intersecting circles (the positions of every joint from the crank angle, one loop
closure at a time).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from jansen import LINKS, jansen_leg, jansen_points

from sparsekin import Body, ModelError, check_model, solve_kinematics
from sparsekin.analysis.assemble import assemble
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.discretization import discretize
from sparsekin.model.lengths import nearest_points
from sparsekin.model.modelfile import load_model, save_model


def test_nearest_points_of_a_rough_triangle_meet_its_lengths_and_stay_near_the_drawing():
    drawn = np.array([[[0.0, 0.0], [40.0, 1.0], [20.0, 30.0]]])
    first, second, lengths = np.array([0, 1, 0]), np.array([1, 2, 2]), np.array([41.5, 40.1, 55.8])
    points, error = nearest_points(drawn, first, second, lengths)
    sides = np.hypot(*(points[0, first] - points[0, second]).T)
    np.testing.assert_allclose(sides, lengths, rtol=1e-14)
    assert error[0] < 1e-13
    # nearest: the change is a combination of the constraints' gradients (Lagrange)
    across = points[0, first] - points[0, second]
    gradient = np.zeros((3, 3, 2))
    gradient[np.arange(3), first] = across
    gradient[np.arange(3), second] -= across
    change = (points - drawn).ravel()
    coefficients, *_ = np.linalg.lstsq(gradient.reshape(3, 6).T, change, rcond=None)
    np.testing.assert_allclose(gradient.reshape(3, 6).T @ coefficients, change, atol=1e-12)


def test_jansen_leg_from_its_holy_numbers_on_a_rounded_drawing_walks_the_exact_foot_path():
    leg = jansen_leg()
    times = np.linspace(0.0, 2.0 * math.pi, 73)
    result = solve_kinematics(leg, times)
    drawn_crank = math.atan2(leg.points["A"][1], leg.points["A"][0])  # the crank's drawn direction
    reference = jansen_points(drawn_crank + times)
    for name in ("A", "C", "D", "E", "F", "G"):
        np.testing.assert_allclose(result.point(name).position, reference[name], rtol=0.0, atol=1e-9, err_msg=name)
    # the rounding alone moved the foot by up to about a unit: the lengths matter
    rough = {name: xy for name, xy in leg.points.items()}
    assert max(abs(rough["G"][0] - reference["G"][0, 0]), abs(rough["G"][1] - reference["G"][0, 1])) > 0.05


def test_a_crank_started_two_thirds_of_a_turn_from_its_drawing_assembles_on_the_drawn_branch():
    phase = 4.0 * math.pi / 3.0
    leg = jansen_leg(phase=phase)
    times = np.linspace(0.0, 1.0, 11)
    result = solve_kinematics(leg, times)
    drawn_crank = math.atan2(leg.points["A"][1], leg.points["A"][0])
    reference = jansen_points(drawn_crank + phase + times)
    np.testing.assert_allclose(result.point("G").position, reference["G"], rtol=0.0, atol=1e-9)


def test_check_reports_the_moves_largest_first_and_the_lengths_used(capsys):
    leg = jansen_leg()
    report = check_model(leg)
    assert report.sound and report.assembled
    distances = [distance for _, distance in report.moves]
    assert distances == sorted(distances, reverse=True) and distances[0] > 0.1
    reference = jansen_points(math.atan2(leg.points["A"][1], leg.points["A"][0]))
    name, largest = report.moves[0]
    assert largest == pytest.approx(np.hypot(*(np.array(leg.points[name]) - reference[name][0])), abs=1e-9)
    assert len(report.lengths) == len(LINKS)
    text = str(report)
    assert "points moved from the drawing" in text and "upper_triangle: P–C 41.5 (drawn" in text


def test_the_assembly_follows_the_drawing_and_reports_its_steps():
    leg = jansen_leg(phase=4.0 * math.pi / 3.0)
    model = discretize(leg)
    pattern = model.constraints
    assembler = Assembler(model)
    assembler.set_time(0.0)
    assembly = assemble(assembler, pattern.initial_coordinates, pattern.coordinate_weights)
    assert assembly.steps > 1 and assembly.residual <= 1e-12


def test_lengths_round_trip_through_the_file_and_contradictions_name_the_body(tmp_path):
    leg = jansen_leg()
    path = tmp_path / "leg.toml"
    save_model(leg, path)
    assert "lengths = [" in path.read_text()
    again = load_model(path)
    assert again.bodies == leg.bodies
    text = path.read_text().replace('["D", "G", 49.0]', '["D", "G", 110.0]')
    path.write_text(text)
    with pytest.raises(ModelError, match=r"bodies\.leg: the lengths D–F 36\.7, F–G 65\.7 and D–G 110 cannot close"):
        load_model(path)


@pytest.mark.parametrize("entry, message", [
    (("O", "Z", 1.0), 'lengths\\[0\\]\\[1\\]: "Z" is not one of the body\'s points'),
    (("O", "O", 1.0), "expected two different points"),
    (("O", "A", -1.0), "expected a length > 0"),
])  # fmt: skip
def test_bad_lengths_are_refused(entry, message):
    with pytest.raises(ModelError, match=message):
        Body("crank", origin="O", points=("O", "A"), lengths=(entry,))


def test_legs_on_one_crankshaft_are_ordered_hub_last_and_check_says_so():
    """Thirty legs welded to one crankshaft: the factors of the hub-last order hold no more
    than those of the same legs welded one to the next (a chain), and the foot is exact."""
    from jansen import jansen_machine

    from sparsekin.engine.linalg import RefactorSolver
    from sparsekin.engine.ordering import hub_coordinates, hub_last_ordering

    fills = {}
    for topology in ("hub", "chain"):
        machine = jansen_machine(30, topology)
        model = discretize(machine)
        pattern = model.constraints
        ordering = hub_last_ordering(model)
        assert (ordering is not None) == (topology == "hub") == bool(hub_coordinates(pattern).size)
        solver = RefactorSolver()
        if ordering is not None:
            solver.suggest(*ordering)
        assembler = Assembler(model)
        assembler.set_time(0.0)
        assembler.fill_residual_jacobian(pattern.initial_coordinates)
        solver.factor(assembler.jacobian)
        assert solver.n_fallbacks == 0
        fills[topology] = solver.nnz_factors / pattern.nnz
        run = solve_kinematics(machine, np.linspace(0.0, 1.0, 5))
        np.testing.assert_allclose(run.point("u29.G").position, jansen_points(0.3 + run.times)["G"], atol=1e-9)
    assert fills["hub"] <= 1.5 * fills["chain"]
    report = check_model(jansen_machine(30, "hub"))
    # the shaft's angle: 3 equations of each weld, 2 of its pin, 1 of its driver
    assert report.hubs == ((f"hub: shaft carries many bodies (up to 93 Jacobian entries in a column); the run "
                            f"eliminates it last: factors {fills['hub']:.3g}× the Jacobian"),)  # fmt: skip


def test_a_mass_at_the_foot_of_a_rough_drawing_sits_at_the_exact_foot():
    """Quasi-static: the crank's torque balances gravity on a point mass at the foot,
    torque · ω = m g · (the foot's upward speed), the speed from the circle intersections by
    central differences."""
    leg = jansen_leg()
    massive = dataclasses.replace(leg, gravity=(0.0, -9.81), bodies=tuple(
        dataclasses.replace(body, mass=2.0, com="G") if body.name == "leg" else body for body in leg.bodies))
    times = np.linspace(0.0, 2.0 * math.pi, 13)
    run = solve_kinematics(massive, times, quasi_static=True)
    crank = math.atan2(leg.points["A"][1], leg.points["A"][0]) + times
    step = 1e-5
    upward = (jansen_points(crank + step)["G"][:, 1] - jansen_points(crank - step)["G"][:, 1]) / (2 * step)
    torque = run.driver_force(0).force
    np.testing.assert_allclose(torque, 2.0 * 9.81 * upward, rtol=0.0, atol=1e-6 * 2.0 * 9.81 * np.abs(upward).max())


def test_a_hub_held_through_another_body_is_named_with_a_way_out():
    """The crankshaft pinned to a bearing welded to the ground: its own equations do not hold
    it alone, so the run cannot eliminate it last, and check warns."""
    from jansen import jansen_machine

    from sparsekin import Revolute, Rigid

    machine = jansen_machine(30, "hub")
    held = dataclasses.replace(machine, bodies=(*machine.own("bodies"), Body("bearing", origin="O")),
                               joints=(Revolute(("shaft", "bearing"), at="O"), Rigid(("bearing", "ground"))))  # fmt: skip
    (line,) = check_model(held).hubs
    assert line.startswith("warning: hub: shaft carries many bodies") and "the run cannot eliminate it last" in line
    assert "attach the copies one to the next (a chain)" in line
