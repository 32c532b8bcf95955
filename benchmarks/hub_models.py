"""Hub and chain: many copies of Theo Jansen's leg attached to one body, or one after another.

`jansen_machine(count, topology)`: `count` legs (7 bodies each) driven by one crankshaft.

* ``"hub"`` — every leg's crank is welded to the crankshaft body (the obvious file:
  ``count = 1000``, a rigid joint to ``shaft``): a star, every copy's equations touch the
  shaft's three columns.
* ``"chain"`` — each leg's crank is welded to the previous leg's crank (the first to the
  shaft): the same bodies and the same number of equations, in a chain.

The legs are drawn exactly (circle intersections) at a crank angle of 0.3 rad, all at the
same place (their motions coincide; what differs is the sparsity pattern).
"""

from __future__ import annotations

import math

import numpy as np

from sparsekin import Body, Linear, Mechanism, Repeat, Revolute, Rigid, RotationalDriver, Unit

#: The holy numbers (the crank axle at the origin, the rocker pivot at (-a, -l)).
HOLY = dict(a=38.0, b=41.5, c=39.3, d=40.1, e=55.8, f=39.4, g=36.7, h=65.7, i=49.0, j=50.0, k=61.9, l=7.8, m=15.0)
LINKS = {"crank": ("O", "A"), "upper_bar": ("A", "C"), "lower_bar": ("A", "D"), "rocker": ("P", "D"),
         "upper_triangle": ("P", "C", "E"), "outer_bar": ("E", "F"), "leg": ("D", "F", "G")}  # fmt: skip
PINS = (("crank", "upper_bar", "A"), ("crank", "lower_bar", "A"), ("upper_bar", "upper_triangle", "C"),
        ("upper_triangle", "ground", "P"), ("rocker", "ground", "P"), ("lower_bar", "rocker", "D"),
        ("rocker", "leg", "D"), ("upper_triangle", "outer_bar", "E"), ("outer_bar", "leg", "F"))  # fmt: skip


def _meet(p, r, q, s, side):
    """The intersection of the circles (p, r) and (q, s) on `side` of the line p → q."""
    d = math.dist(p, q)
    along = (r * r - s * s + d * d) / (2 * d)
    across = math.sqrt(r * r - along * along)
    ux, uy = (q[0] - p[0]) / d, (q[1] - p[1]) / d
    return (p[0] + along * ux - side * across * uy, p[1] + along * uy + side * across * ux)


def leg_points(angle: float = 0.3) -> dict[str, tuple[float, float]]:
    """The joints of the leg at crank angle `angle` (rad)."""
    n = HOLY
    o, p = (0.0, 0.0), (-n["a"], -n["l"])
    a = (n["m"] * math.cos(angle), n["m"] * math.sin(angle))
    c = _meet(a, n["j"], p, n["b"], -1)
    d = _meet(a, n["k"], p, n["c"], +1)
    e = _meet(p, n["d"], c, n["e"], +1)
    f = _meet(e, n["f"], d, n["g"], -1)
    g = _meet(f, n["h"], d, n["i"], -1)
    return dict(O=o, P=p, A=a, C=c, D=d, E=e, F=f, G=g)


def jansen_machine(count: int, topology: str) -> Mechanism:
    """`count` legs on one crankshaft, as a ``"hub"`` or a ``"chain"`` (see the module)."""
    if topology not in ("hub", "chain"):
        raise ValueError(f"topology must be 'hub' or 'chain', got {topology!r}")
    points = leg_points()
    unit_points = {name: xy for name, xy in points.items() if name != "O"}
    bodies = tuple(Body(name, origin=carried[0] if carried[0] != "O" else (0.0, 0.0), points=tuple(
        p for p in carried if p != "O")) for name, carried in LINKS.items())  # fmt: skip
    weld = Rigid(("crank", "shaft" if topology == "hub" else "prev.crank"))
    joints = (weld, *(Revolute((i, j), at=at) for i, j, at in PINS))
    unit = Unit("leg", points=unit_points, bodies=bodies, joints=joints)
    repeat = Repeat(unit, count=count, prefix="u", first={"prev.crank": "shaft"} if topology == "chain" else {})
    return Mechanism(
        points={"O": (0.0, 0.0)}, bodies=[Body("shaft", origin="O", points=("O",))],
        joints=[Revolute(("shaft", "ground"), at="O")],
        drivers=[RotationalDriver(("shaft", "ground"), law=Linear(rate=1.0))],
        repeats=(repeat,), name=f"{count} Jansen legs, {topology}",
    )  # fmt: skip


def foot_path(times: np.ndarray) -> np.ndarray:
    """The foot of the leg at crank angles 0.3 + times, (n, 2): what every copy's foot does."""
    return np.array([leg_points(0.3 + t)["G"] for t in times])
