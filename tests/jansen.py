"""Theo Jansen's leg from its thirteen "holy numbers", shared by tests and benchmarks.

`jansen_points` computes every joint from the crank angle by intersecting circles, one
loop closure at a time (the independent reference); `jansen_leg` is the leg as a model
given by its link lengths on a rounded drawing; `jansen_machine` puts many legs on one
crankshaft, welded to it (a hub) or one to the next (a chain).
"""

from __future__ import annotations

import numpy as np

from sparsekin import Body, Linear, Mechanism, Repeat, Revolute, Rigid, RotationalDriver, Unit

#: The crank angle (rad) at which the legs are drawn.
DRAWN_AT = 0.3

#: The holy numbers (the crank axle at the origin, the rocker pivot at (-a, -l)).
HOLY = {"a": 38.0, "b": 41.5, "c": 39.3, "d": 40.1, "e": 55.8, "f": 39.4, "g": 36.7, "h": 65.7, "i": 49.0, "j": 50.0,
        "k": 61.9, "l": 7.8, "m": 15.0}
#: The links: body name -> (points, the holy letters of its lengths between them).
LINKS = {
    "crank": (("O", "A"), (("O", "A", "m"),)),
    "upper_bar": (("A", "C"), (("A", "C", "j"),)),
    "lower_bar": (("A", "D"), (("A", "D", "k"),)),
    "rocker": (("P", "D"), (("P", "D", "c"),)),
    "upper_triangle": (("P", "C", "E"), (("P", "C", "b"), ("C", "E", "e"), ("P", "E", "d"))),
    "outer_bar": (("E", "F"), (("E", "F", "f"),)),
    "leg": (("D", "F", "G"), (("D", "F", "g"), ("F", "G", "h"), ("D", "G", "i"))),
}
PINS = (("crank", "ground", "O"), ("crank", "upper_bar", "A"), ("crank", "lower_bar", "A"),
        ("upper_bar", "upper_triangle", "C"), ("upper_triangle", "ground", "P"), ("rocker", "ground", "P"),
        ("lower_bar", "rocker", "D"), ("rocker", "leg", "D"), ("upper_triangle", "outer_bar", "E"),
        ("outer_bar", "leg", "F"))  # fmt: skip


def _circles(centre_1, radius_1, centre_2, radius_2, side):
    """The intersection of two circles left of the line from centre 1 to centre 2 (side
    +1) or right of it (side -1): the law of cosines, written out."""
    dx, dy = centre_2[..., 0] - centre_1[..., 0], centre_2[..., 1] - centre_1[..., 1]
    distance = np.hypot(dx, dy)
    along = (radius_1**2 - radius_2**2 + distance**2) / (2 * distance)
    across = np.sqrt(radius_1**2 - along**2)
    ux, uy = dx / distance, dy / distance
    return np.stack([centre_1[..., 0] + along * ux - side * across * uy,
                     centre_1[..., 1] + along * uy + side * across * ux], axis=-1)  # fmt: skip


def jansen_points(crank_angle):
    """Every joint of the leg at crank angles `crank_angle` (rad), each (n, 2)."""
    n = HOLY
    theta = np.atleast_1d(np.asarray(crank_angle, dtype=float))
    o = np.zeros((theta.size, 2))
    p = np.tile([-n["a"], -n["l"]], (theta.size, 1))
    a = np.stack([n["m"] * np.cos(theta), n["m"] * np.sin(theta)], axis=-1)
    c = _circles(a, n["j"], p, n["b"], -1)  # above the line crank–pivot
    d = _circles(a, n["k"], p, n["c"], +1)  # below it
    e = _circles(p, n["d"], c, n["e"], +1)  # outside, to the left
    f = _circles(e, n["f"], d, n["g"], -1)
    g = _circles(f, n["h"], d, n["i"], -1)
    return {"O": o, "P": p, "A": a, "C": c, "D": d, "E": e, "F": f, "G": g}


def jansen_leg(drawn_at: float = DRAWN_AT, rounding: float = 1.0, phase: float = 0.0, rate: float = 1.0) -> Mechanism:
    """The leg with its exact lengths, drawn at crank angle `drawn_at`, the moving points
    rounded to multiples of `rounding`; the crank turns at `rate` from `phase` past its
    drawn direction."""
    exact = {name: xy[0] for name, xy in jansen_points(drawn_at).items()}
    points = {name: (tuple(float(v) for v in xy) if name in ("O", "P")
                     else tuple(float(rounding * round(v / rounding)) for v in xy)) for name, xy in exact.items()}  # fmt: skip
    bodies = [Body(name, origin=carried[0], points=carried,
                   lengths=tuple((p, q, HOLY[letter]) for p, q, letter in lengths))
              for name, (carried, lengths) in LINKS.items()]  # fmt: skip
    joints = [Revolute((i, j), at=at) for i, j, at in PINS]
    law = Linear(rate=rate, start=phase)
    return Mechanism(points=points, bodies=bodies, joints=joints,
                     drivers=[RotationalDriver(("crank", "ground"), law=law)], name="jansen-leg")  # fmt: skip


def jansen_machine(count: int, topology: str) -> Mechanism:
    """`count` legs (7 bodies each) driven by one crankshaft, drawn exactly at `DRAWN_AT`,
    all at the same place (their motions coincide; what differs is the sparsity pattern).

    ``"hub"``: every leg's crank is welded to the crankshaft body (the obvious file:
    ``count = 1000``, a rigid joint to ``shaft``), a star; ``"chain"``: each leg's crank is
    welded to the previous leg's (the first to the shaft): the same bodies and equations."""
    if topology not in ("hub", "chain"):
        raise ValueError(f"topology must be 'hub' or 'chain', got {topology!r}")
    points = {name: tuple(float(v) for v in xy[0]) for name, xy in jansen_points(DRAWN_AT).items()}
    unit_points = {name: xy for name, xy in points.items() if name != "O"}
    bodies = tuple(Body(name, origin=carried[0] if carried[0] != "O" else (0.0, 0.0), points=tuple(
        p for p in carried if p != "O")) for name, (carried, _) in LINKS.items())  # fmt: skip
    weld = Rigid(("crank", "shaft" if topology == "hub" else "prev.crank"))  # the crank turns with the shaft
    joints = (weld, *(Revolute((i, j), at=at) for i, j, at in PINS if at != "O"))
    unit = Unit("leg", points=unit_points, bodies=bodies, joints=joints)
    repeat = Repeat(unit, count=count, prefix="u", first={"prev.crank": "shaft"} if topology == "chain" else {})
    return Mechanism(
        points={"O": (0.0, 0.0)}, bodies=[Body("shaft", origin="O", points=("O",))],
        joints=[Revolute(("shaft", "ground"), at="O")],
        drivers=[RotationalDriver(("shaft", "ground"), law=Linear(rate=1.0))],
        repeats=(repeat,), name=f"{count} Jansen legs, {topology}",
    )  # fmt: skip
