"""`check_model`: is a mechanism sound?  Degrees of freedom, rank, redundancy, free motions.

`check_model` assembles a mechanism at a time (Newton–Raphson from its drawing, the
redundant equations left out and one coordinate of each free motion held), studies the
rank of its Jacobian there (`sparsekin.analysis.rank.analyse_jacobian`) and reports, in words,
what is wrong with it; ``sparsekin check MODEL.toml`` prints that report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from ..engine.assembly import Assembler
from ..engine.discretization import discretize
from ..engine.outputs import LimitState, limit_states, own_coordinates
from ..engine.pattern import build_output_pattern
from ..engine.reduced import CONSISTENCY_TOLERANCE
from ..model.mechanism import Mechanism
from .assemble import ASSEMBLY_TOLERANCE, AssemblyFailed, assemble, point_moves, reduced_system
from .describe import (
    coordinate_label,
    describe_motion,
    equation_label,
    motion_summary,
    row_preference,
)
from .idle_drivers import idle_drivers
from .notices import actuator_directions, hub_lines, law_offsets, notice_lines, unjoined_point_lines
from .rank import SMALLEST_TALL_LU, JacobianAnalysis, analyse_jacobian
from .rigidity import counts_line, describe_redundant, listed_redundant

__all__ = ["ModelReport", "RedundantEquation", "FreeMotion", "check_model", "format_report"]

#: Most names of massless bodies in a report.
LISTED_MASSLESS = 6


@dataclass(frozen=True)
class RedundantEquation:
    """An equation that depends on the others at the analysed configuration.

    Attributes
    ----------
    row : int
        Its row in the Jacobian.
    label : str
        ``joints[5] (revolute coupler–crank2 at T2), equation x``.
    residual : float
        Its residual at the configuration, in `unit`: zero when the redundancy is
        consistent.
    unit : str
        ``"m"`` or ``"rad"``.
    consistent : bool
        Whether `residual` is within `CONSISTENCY_TOLERANCE`.
    depends_on : str
        The other equations of the dependency, with their shares.
    involves_drivers : bool
        Whether a driver takes part in the dependency (the drivers then prescribe a
        motion that the joints already fix).
    """

    row: int
    label: str
    residual: float
    unit: str
    consistent: bool
    depends_on: str
    involves_drivers: bool


@dataclass(frozen=True)
class FreeMotion:
    """A motion that no equation controls (one vector of a basis of the null space).

    Attributes
    ----------
    coordinate : str
        The coordinate this motion moves and the other free motions do not (``c6.angle``).
    bodies : str
        How the bodies move: ``c6 rotates about D (-0.2, 0.5)``.
    coordinates : str
        The coordinates it moves, with their shares of the motion.
    """

    coordinate: str
    bodies: str
    coordinates: str


@dataclass(frozen=True, eq=False)
class ModelReport:
    """What `check_model` found: counts, rank, redundant equations and free motions.

    Attributes
    ----------
    name : str
    time : float
        The time of the analysis, s.
    n_bodies, n_coordinates, n_joints, n_joint_equations, n_drivers, n_equations : int
    assembled : bool
        Whether Newton–Raphson reached a configuration satisfying the equations (the
        redundant ones left out, the free coordinates held) from the model's drawing.
    assembly : str
        How the assembly went, in words.
    rank : int
        Numerical rank of the Jacobian at the assembled configuration (at the drawn one
        if the assembly failed).
    analysis : JacobianAnalysis
        The details of that rank analysis.
    redundant : tuple of RedundantEquation
    free_motions : tuple of FreeMotion
    limits : tuple of LimitState
        Each element with ``limits``: its own coordinate at the assembled configuration
        and whether it is within them.
    total_mass : float
        The sum of the bodies' masses, kg.
    massless_bodies : tuple of str
        Moving bodies without a mass (at most `LISTED_MASSLESS` names, copies' by their
        expanded names), and `n_massless` how many there are.
    n_loads : int
    gravity : (gx, gy)
        m/s².
    has_forces : bool
        Whether a run computes forces by default: a body has a mass or an inertia, or a
        load acts (`Mechanism.has_forces`).
    law_offsets, actuator_directions, unjoined_points : tuple of str
        The notices of `sparsekin.analysis.notices`: drivers whose law at t = 0 is away
        from the drawing, which sign extends each actuator, points carried by bodies that
        no joint connects there (a warning; not a problem of the verdict).
    left_out : tuple of str
        For each repeat that leaves parts out of some copies (a grid's open boundaries,
        ``copies = {…}``): one line saying how many, ``repeat[0]: 20 elements on the
        open boundary or restricted to some copies``.
    moves : tuple of (str, float)
        The named points that the assembly moved from the drawing, the largest move
        first (at most `sparsekin.analysis.assemble.MOST_LISTED_MOVES`), m; `n_moved` how
        many moved (-1: too many points to locate).
    lengths : tuple of str
        One line per body with `lengths`: each stated length and its drawn distance.
    hubs : tuple of str
        A line when bodies carry many others (`sparsekin.analysis.notices.hub_lines`).
    initial_state : tuple of str
        For a model run by forward dynamics, how far its run moves the drawing and the
        given velocities (`sparsekin.solve.initial_state`, which ``sparsekin check``
        adds), or why it cannot start; shown before the verdict.
    under_forces : bool
        The model is run by forward dynamics: its free motions are the degrees of
        freedom its masses and loads move, not a problem.
    cannot_start : str
        Why a forward-dynamics run cannot start (a problem), or empty.
    idle_drivers : tuple of str
        The drivers whose unit rate moves no named point at the assembled configuration
        (a crank of zero length: `sparsekin.analysis.idle_drivers`), by label.
    """

    name: str
    time: float
    n_bodies: int
    n_coordinates: int
    n_joints: int
    n_joint_equations: int
    n_drivers: int
    n_equations: int
    assembled: bool
    assembly: str
    rank: int
    redundant: tuple[RedundantEquation, ...]
    free_motions: tuple[FreeMotion, ...]
    analysis: JacobianAnalysis
    limits: tuple[LimitState, ...] = ()
    total_mass: float = 0.0
    massless_bodies: tuple[str, ...] = ()
    n_massless: int = 0
    n_loads: int = 0
    gravity: tuple[float, float] = (0.0, 0.0)
    has_forces: bool = False
    law_offsets: tuple[str, ...] = ()
    actuator_directions: tuple[str, ...] = ()
    unjoined_points: tuple[str, ...] = ()
    left_out: tuple[str, ...] = ()
    moves: tuple[tuple[str, float], ...] = ()
    n_moved: int = 0
    lengths: tuple[str, ...] = ()
    hubs: tuple[str, ...] = ()
    initial_state: tuple[str, ...] = ()
    under_forces: bool = False
    cannot_start: str = ""
    idle_drivers: tuple[str, ...] = ()

    @property
    def dof_by_count(self) -> tuple[int, int]:
        """Grübler's count, 3 per body minus the equations: without and with the drivers."""
        return self.n_coordinates - self.n_joint_equations, self.n_coordinates - self.n_equations

    @property
    def dof_by_rank(self) -> tuple[int, int]:
        """Degrees of freedom from the numerical rank: without and with the drivers.

        Without the drivers, the rank of the joints' rows is ``rank - n_drivers + d``
        where d is the number of independent dependencies that involve drivers.
        """
        n_free = self.n_coordinates - self.rank
        driver_dependencies = self.analysis.dependency_rank(np.arange(self.n_joint_equations, self.n_equations))
        return n_free + self.n_drivers - driver_dependencies, n_free

    @property
    def problems(self) -> tuple[str, ...]:
        """One line per problem; empty when the model is sound."""
        problems = []
        if not self.assembled:
            problems.append(f"cannot assemble at t = {self.time:g} s")
        if self.redundant:
            inconsistent = sum(not equation.consistent for equation in self.redundant)
            drivers = any(equation.involves_drivers for equation in self.redundant)
            text = f"{len(self.redundant)} redundant equation{'s' * (len(self.redundant) != 1)}"
            if inconsistent:
                text += f", {inconsistent} of them not satisfied (the joints contradict each other)"
            if drivers:
                text += (", drivers among them (the drivers prescribe a motion that the joints fix, or the "
                         "configuration is a dead centre)")
            problems.append(text)
        if self.free_motions and not self.under_forces:
            problems.append(f"{len(self.free_motions)} free motion{'s' * (len(self.free_motions) != 1)}")
        if self.cannot_start:
            problems.append(self.cannot_start)
        if self.idle_drivers:
            problems.append(f"{len(self.idle_drivers)} driver{'s' * (len(self.idle_drivers) != 1)} moving no point "
                            f"({', '.join(self.idle_drivers)})")
        outside = sum(not state.within for state in self.limits)
        if outside:
            problems.append(f"{outside} element{'s' * (outside != 1)} outside {'their' if outside != 1 else 'its'} limits")
        return tuple(problems)

    @property
    def sound(self) -> bool:
        """No problem: assembled, no redundant equation, no free motion, no driver moving
        no point, no element outside its limits (`problems` is empty)."""
        return not self.problems

    def __str__(self) -> str:
        return format_report(self)


def check_model(mechanism: Mechanism, time: float = 0.0, *, tall_lu_from: int = SMALLEST_TALL_LU) -> ModelReport:
    """Assemble `mechanism` at `time` and report its rank, redundant equations and free motions.

    Newton–Raphson first brings the drawn configuration onto the constraints (leaving out
    the redundant equations and holding the free coordinates, both found at the drawn
    configuration), then `analyse_jacobian` studies the Jacobian there.

    Parameters
    ----------
    mechanism : Mechanism
    time : float
        Time of the analysis, s (the drivers' values at that time are used).
    tall_lu_from : int
        A Jacobian with more equations than coordinates, at least this many, is analysed
        by a sparse LU first (`sparsekin.analysis.rank.SMALLEST_TALL_LU`; see
        `analyse_jacobian`).

    Returns
    -------
    ModelReport
        ``str(report)`` is a readable report; ``report.sound`` says whether anything is
        wrong.

    Examples
    --------
    >>> from sparsekin import Body, Linear, Mechanism, Revolute, RotationalDriver
    >>> crank = Mechanism(
    ...     points={"O": (0.0, 0.0), "A": (0.1, 0.0)},
    ...     bodies=[Body("crank", origin="O", points=("O", "A"))],
    ...     joints=[Revolute(("crank", "ground"), at="O")],
    ...     drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=2.0))],
    ... )
    >>> report = check_model(crank)
    >>> report.sound, report.rank, report.dof_by_count, report.dof_by_rank
    (True, 3, (1, 0), (1, 0))
    >>> unpinned = Mechanism(points=crank.points, bodies=crank.bodies, drivers=crank.drivers)
    >>> report = check_model(unpinned)
    >>> report.problems
    ('2 free motions',)
    >>> [motion.bodies for motion in report.free_motions]
    ['crank translates along (1, 0)', 'crank translates along (0, 1)']
    """
    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    is_number = isinstance(time, (int, float, np.integer, np.floating)) and not isinstance(time, bool)
    if not (is_number and math.isfinite(time)):
        raise ValueError(f"`time` must be a finite number (s), got {time!r}.")
    discretization = discretize(mechanism)
    pattern = discretization.constraints
    weights = pattern.residual_weights
    preference = row_preference(mechanism, pattern)
    drawn = pattern.initial_coordinates.copy()
    moves, n_moved, hubs = (), 0, ()
    if pattern.n_equations == 0:  # nothing to assemble: every coordinate is free
        analysis = analyse_jacobian(sparse.csr_array((0, pattern.n_coordinates)))
        assembled, coordinates, assembly = True, drawn, f"nothing to assemble at t = {time:g} s: no equation"
        residual = raw_residual = np.zeros(0)
    else:
        assembler = Assembler(discretization)
        assembler.set_time(float(time))
        assembler.fill_residual_jacobian(drawn)
        first = analyse_jacobian(assembler.jacobian, row_preference=preference, tall_lu_from=tall_lu_from)
        assembled, coordinates, assembly = _assemble(mechanism, pattern, assembler, float(time), drawn, first)
        assembler.fill_residual_jacobian(coordinates)
        moved = float(np.max(np.abs(coordinates - drawn) * pattern.coordinate_weights, initial=0.0))
        if assembled and moved > ASSEMBLY_TOLERANCE:  # else the drawing's analysis holds (twice the cost saved)
            left_out = preference.copy()
            left_out[first.redundant_rows] += 2.0  # the equations the assembly left out: named first
            analysis = analyse_jacobian(assembler.jacobian, row_preference=left_out, tall_lu_from=tall_lu_from)
        else:
            analysis = first
        if assembled and moved > ASSEMBLY_TOLERANCE:
            found = point_moves(mechanism, drawn, coordinates)
            moves, n_moved = ((), -1) if found is None else (tuple(found[0]), found[1])
        raw_residual = assembler.residual
        hubs = hub_lines(discretization, assembler.jacobian) if assembled else ()
        residual = raw_residual * weights
    n_joint_equations = int(pattern.element_first_row[len(mechanism.joints)])
    consistent = np.abs(residual[analysis.redundant_rows]) <= CONSISTENCY_TOLERANCE
    depends_on, involves_drivers = describe_redundant(mechanism, pattern, analysis, consistent)
    redundant = tuple(
        RedundantEquation(
            row=int(row),
            label=equation_label(mechanism, pattern, int(row)),
            residual=float(abs(raw_residual[row])),
            unit="rad" if pattern.row_is_angle[row] else "m",
            consistent=bool(consistent[k]),
            depends_on=depends_on[k],
            involves_drivers=bool(involves_drivers[k]),
        )
        for k, row in enumerate(analysis.redundant_rows.tolist())
    )
    free_motions = tuple(
        FreeMotion(
            coordinate=coordinate_label(mechanism, int(column)),
            bodies=describe_motion(
                mechanism, pattern, coordinates,
                analysis.free_motions[:, k], analysis.scaled_free_motions[:, k],
            ),
            coordinates=motion_summary(mechanism, analysis.scaled_free_motions[:, k]),
        )
        for k, column in enumerate(analysis.free_coordinates)
    )
    limited = [e for kind in ("joints", "drivers") for e in mechanism.declared(kind) if getattr(e, "limits", None)]
    limits = ()
    if limited:
        outputs = build_output_pattern(mechanism)
        rest = np.zeros((1, pattern.n_coordinates))
        values = own_coordinates(outputs, coordinates[None], rest, rest)[0]
        limits = tuple(limit_states(mechanism, outputs, values, [float(time)]))
    massless, n_massless = _massless_bodies(mechanism)
    idle = ()
    if assembled and pattern.n_equations and not analysis.n_free:
        idle = idle_drivers(mechanism, pattern, assembler.jacobian, analysis.redundant_rows, coordinates)
    return ModelReport(
        idle_drivers=idle,
        law_offsets=law_offsets(mechanism, pattern),
        actuator_directions=actuator_directions(mechanism),
        unjoined_points=unjoined_point_lines(mechanism),
        limits=limits,
        total_mass=mechanism.total_mass,
        massless_bodies=massless,
        n_massless=n_massless,
        n_loads=mechanism.n_loads,
        gravity=mechanism.gravity,
        has_forces=mechanism.has_forces,
        moves=moves,
        n_moved=n_moved,
        hubs=hubs,
        lengths=tuple(_lengths_line(where, stated) for where, stated in mechanism.shapes.lengths),
        left_out=tuple(f"{c.label}: {n} element{'s' * (n != 1)} on the open boundary or restricted to some copies"
                       for c in mechanism.copies if (n := c.n_left_out())),
        name=mechanism.name,
        time=float(time),
        n_bodies=mechanism.n_bodies,
        n_coordinates=pattern.n_coordinates,
        n_joints=len(mechanism.joints),
        n_joint_equations=n_joint_equations,
        n_drivers=len(mechanism.drivers),
        n_equations=pattern.n_equations,
        assembled=assembled,
        assembly=assembly,
        rank=analysis.rank,
        redundant=redundant,
        free_motions=free_motions,
        analysis=analysis,
    )


def _lengths_line(where: str, stated) -> str:
    """``bodies.crank: O–A 15 (drawn 15.13)``: a body's stated lengths, with the drawn distances."""
    return f"{where}: " + ", ".join(f"{a}–{b} {length:.10g} (drawn {drawn:.6g})" for a, b, length, drawn in stated)


def _massless_bodies(mechanism: Mechanism) -> tuple[tuple[str, ...], int]:
    """The first `LISTED_MASSLESS` moving bodies without a mass, and how many there are."""
    names = [body.name for body in mechanism.own("bodies") if not body.mass]
    count = len(names)
    for copies in mechanism.copies:
        massless = [e for e, body in enumerate(copies.unit.bodies) if not body.mass]
        count += int(copies.having("bodies")[massless].sum())
        names += [copies.name(k, copies.unit.bodies[e].name) for k in range(min(copies.count, LISTED_MASSLESS))
                  for e in massless if copies.present("bodies", k, e)]  # fmt: skip
    return tuple(names[:LISTED_MASSLESS]), count


def _assemble(mechanism, pattern, assembler, time, drawn, analysis):
    """The path from the drawing onto the equations that are not redundant, the free
    coordinates held (`sparsekin.analysis.assemble`).  Returns (converged, coordinates, words)."""
    system = reduced_system(assembler, analysis, drawn)
    try:
        assembly = assemble(system, drawn, pattern.coordinate_weights, tolerance=ASSEMBLY_TOLERANCE)
    except AssemblyFailed as failure:
        weighted = np.abs(system.residual) * system.weights
        kept = system.rows
        worst = int(kept[np.argmax(weighted[: kept.size])]) if kept.size else -1
        where = equation_label(mechanism, pattern, worst) if worst >= 0 else "no equation"
        return False, drawn, (
            f"cannot assemble at t = {time:g} s: Newton–Raphson did not converge from the drawing "
            f"({failure.reason}; residual {np.max(weighted, initial=0.0):.3g} at the last iterate, relative "
            f"to the model size; largest in {where})"
        )
    moved = float(np.max(np.abs(assembly.coordinates - drawn) * pattern.coordinate_weights, initial=0.0))
    how = "as drawn"
    if assembly.steps:
        how = (f"in {assembly.corrections} Newton correction{'s' * (assembly.corrections != 1)} over "
               f"{assembly.steps} step{'s' * (assembly.steps != 1)} from the drawing, on its branch")
    return True, assembly.coordinates, (
        f"assembled at t = {time:g} s {how}: largest residual {assembly.residual:.2g}, largest change of a coordinate "
        f"{moved:.2g} (lengths relative to the model size, {pattern.length_scale:.4g} m; angles in rad)"
    )


def format_report(report: ModelReport) -> str:
    """The report of ``sparsekin check``: a few lines, then one block per problem."""
    analysis = report.analysis
    joints_text = f"{report.n_joint_equations} from {report.n_joints} joint{'s' * (report.n_joints != 1)}"
    drivers_text = f"{report.n_equations - report.n_joint_equations} from {report.n_drivers} driver" + (
        "s" * (report.n_drivers != 1)
    )
    count_without, count_with = report.dof_by_count
    rank_without, rank_with = report.dof_by_rank
    where = "assembled" if report.assembled else "drawn"
    lines = [
        f"model {report.name}: {report.n_bodies} bodies, {report.n_coordinates} coordinates, "
        f"{report.n_equations} equations ({joints_text}, {drivers_text})",
        f"degrees of freedom by count (3 per body minus equations): {count_without} without the drivers, "
        f"{count_with} with them",
        report.assembly,
        f"rank of the Jacobian at the {where} configuration: {report.rank} for {report.n_equations} "
        f"equations and {report.n_coordinates} coordinates (singular values of the row- and "
        f"column-scaled Jacobian above {analysis.tolerance:.2g} × the largest)",
        f"degrees of freedom by rank: {rank_without} without the drivers, {rank_with} with them",
        f"condition number of the scaled Jacobian (on its rank): {_number(analysis.condition)}",
    ]
    lines[1:1] = report.left_out
    lines[3 + len(report.left_out) : 3 + len(report.left_out)] = _assembly_lines(report)
    lines.append(counts_line(report.n_coordinates, report.n_equations, report.rank))
    if report.redundant:
        lines.append(f"redundant equations ({len(report.redundant)}):")
        listed = listed_redundant([equation.consistent for equation in report.redundant])
        for equation in (report.redundant[k] for k in listed.tolist()):
            state = "consistent" if equation.consistent else "NOT satisfied"
            lines.append(f"  {equation.label}: residual {equation.residual:.3g} {equation.unit}, {state}")
            lines.append(f"      depends on {equation.depends_on or 'nothing else (a zero equation)'}")
        if len(report.redundant) > listed.size:
            unlisted_bad = sum(not equation.consistent for equation in report.redundant) - sum(
                not report.redundant[k].consistent for k in listed.tolist())
            lines.append(f"  … ({len(report.redundant) - listed.size} more, "
                         + (f"{unlisted_bad} of them NOT satisfied)" if unlisted_bad else "all consistent)"))
    else:
        lines.append("redundant equations: none")
    if report.free_motions:
        moved_by = ", the degrees of freedom that the masses and loads move" if report.under_forces else ""
        lines.append(f"free motions ({len(report.free_motions)}){moved_by}:")
        for k, motion in enumerate(report.free_motions, start=1):
            lines.append(f"  {k}. {motion.bodies}")
            lines.append(f"      moves {motion.coordinates}")
    else:
        lines.append("free motions: none")
    if report.limits:
        lines.append(f"limits: {len(report.limits)} element{'s' * (len(report.limits) != 1)}")
        lines += [f"  {state}" for state in report.limits]
    if report.idle_drivers:
        lines.append(f"drivers moving no point ({len(report.idle_drivers)}): {', '.join(report.idle_drivers)}: at a unit "
                     "rate every named point stands still (a crank of zero length, its points at its pivot?)")  # fmt: skip
    lines.append(_masses_line(report))
    lines += notice_lines(report)
    lines += report.initial_state
    lines.append("verdict: " + ("sound" if report.sound else "; ".join(report.problems)))
    return "\n".join(lines)


def _assembly_lines(report: ModelReport) -> list[str]:
    """The points the assembly moved (the largest first) and the link lengths stated."""
    lines = []
    if report.n_moved < 0:
        lines.append("points moved from the drawing: too many points to list")
    elif report.moves:
        shown = ", ".join(f"{name} {distance:.3g} m" for name, distance in report.moves)
        more = f" … ({report.n_moved - len(report.moves)} more)" if report.n_moved > len(report.moves) else ""
        lines.append(f"points moved from the drawing ({report.n_moved}), the largest first: {shown}{more}")
    if report.lengths:
        lines.append(f"link lengths (exact; the other distances are drawn), m: {len(report.lengths)} bod"
                     + ("ies" if len(report.lengths) != 1 else "y"))
        lines += [f"  {line}" for line in report.lengths]
    return lines


def _masses_line(report: ModelReport) -> str:
    """Total mass, massless moving bodies, loads and gravity: what the forces will rest on."""
    if not report.has_forces:
        return "masses and loads: none (a run computes no forces)"
    if report.n_massless == 0:
        bodies = "every moving body has a mass"
    else:
        listed = ", ".join(report.massless_bodies) + (" …" if report.n_massless > len(report.massless_bodies) else "")
        bodies = f"{report.n_massless} of {report.n_bodies} moving bodies have no mass ({listed})"
    gravity = "no gravity" if report.gravity == (0.0, 0.0) else f"gravity ({report.gravity[0]:g}, {report.gravity[1]:g}) m/s²"
    return (f"masses: total {report.total_mass:.6g} kg; {bodies}; {report.n_loads} load{'s' * (report.n_loads != 1)}; "
            f"{gravity}")


def _number(value: float) -> str:
    return "infinite" if not math.isfinite(value) else f"{value:.4g}"
