"""Points carried by several bodies that no joint connects there.

A point listed by two bodies is drawn on both; unless a joint ties the two bodies at that
point (a revolute there, say), the bodies may part and the point is then two points, of
which the outputs show the first body's.  That is nearly always a forgotten joint.
`unjoined_points` finds them in the model's own bodies and in each unit (once, not once
per copy); `load_model` warns about them (`UnjoinedPointWarning`) and ``sparsekin check``
lists them.

Two bodies count as connected at a point P when a chain of joints links them, each joint
naming P in one of its point fields (a revolute's ``at``, a translational joint's axis
points) or having three equations (a rigid joint, which leaves no relative motion), the
ground included: two bodies both pinned to the ground at P are connected there.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

from ..errors import UnjoinedPointWarning

__all__ = ["UnjoinedPoint", "unjoined_points", "warn_unjoined_points"]

#: Most unjoined points named in one warning: the warning stays one readable line.
LISTED_POINTS = 4


class UnjoinedPoint(NamedTuple):
    """A point carried by bodies that fall into several groups no joint connects there.

    Attributes
    ----------
    point : str
    groups : tuple of tuple of str
        The carrying bodies, grouped by the joints at the point (at least two groups).
    where : str
        ``""`` for the model's own bodies, ``"units.NAME"`` for a unit's.
    """

    point: str
    groups: tuple[tuple[str, ...], ...]
    where: str

    def __str__(self) -> str:
        groups = " and ".join("+".join(group) for group in self.groups)
        unit = f" in {self.where}" if self.where else ""
        return f'point "{self.point}"{unit} is carried by {groups}, which no joint connects there'


def unjoined_points(mechanism) -> list[UnjoinedPoint]:
    """Every point of `mechanism` carried by bodies that no joint connects at that point."""
    found = _unjoined(mechanism.own("bodies"), mechanism.own("joints"), "")
    seen = set()
    for copies in mechanism.copies:
        unit = copies.unit
        if id(unit) not in seen:
            seen.add(id(unit))
            found += _unjoined(unit.bodies, unit.joints, f"units.{unit.name}")
    return found


def warn_unjoined_points(mechanism, source: str = "", stacklevel: int = 2) -> None:
    """One `UnjoinedPointWarning` naming the unjoined points of `mechanism`, if any, after
    ``source: `` (a file name) when given."""
    found = unjoined_points(mechanism)
    if found:
        listed = "; ".join(str(point) for point in found[:LISTED_POINTS])
        more = f" (and {len(found) - LISTED_POINTS} more)" if len(found) > LISTED_POINTS else ""
        prefix = f"{source}: " if source else ""
        warnings.warn(f"{prefix}{listed}{more}: add a joint there, or list the point on one body only",
                      UnjoinedPointWarning, stacklevel=stacklevel + 1)  # fmt: skip


def _unjoined(bodies, joints, where: str) -> list[UnjoinedPoint]:
    carriers: dict[str, list[str]] = {}
    for body in bodies:
        for point in dict.fromkeys(body.points):  # a body that lists a point twice carries it once
            carriers.setdefault(point, []).append(body.name)
    shared = {point: names for point, names in carriers.items() if len(names) > 1}
    if not shared:
        return []
    shared_on: dict[str, list[str]] = {}  # body -> the shared points it carries
    for point, names in shared.items():
        for name in names:
            shared_on.setdefault(name, []).append(point)
    parent: dict[tuple[str, str], tuple[str, str]] = {}

    def root(node):
        while node in parent:
            above = parent[node]
            if above in parent:  # path halving: the trees stay shallow
                parent[node] = above = parent[above]
            node = above
        return node

    for joint in joints:
        declaration = type(joint)
        if "bodies" not in declaration.body_fields:
            continue
        first, second = joint.bodies
        if declaration.n_equations == 3 and not declaration.point_fields:  # welded: joined everywhere
            points = list(dict.fromkeys([*shared_on.get(first, ()), *shared_on.get(second, ())]))
        else:
            points = []
            for field_name in declaration.point_fields:
                value = getattr(joint, field_name)
                references = (value,) if isinstance(value, str) or value is None else value
                points += [reference for reference in references if isinstance(reference, str) and reference in shared]
        for point in points:
            low, high = root((point, first)), root((point, second))
            if low != high:
                parent[low] = high
    found = []
    for point, names in shared.items():
        groups: dict[tuple[str, str], list[str]] = {}
        for name in names:
            groups.setdefault(root((point, name)), []).append(name)
        if len(groups) > 1:
            found.append(UnjoinedPoint(point, tuple(tuple(group) for group in groups.values()), where))
    return found
