"""Composite elements: one block of a model file that stands for several hand-written ones.

A composite kind is a frozen dataclass whose fields are its keys in the model file (as the
joints and drivers of `sparsekin.model.elements`), registered with `composite_kind` in
`COMPOSITE_KINDS`.  It is written in ``[[composites]]`` with its ``type`` and declares

=====================  ==============================================================
``type_name``          its ``type`` in the model file
``file_keys``          the keys it accepts (`sparsekin.model._validate.FileKeys`)
``expand``             method: the bodies, joints and drivers it stands for (`Parts`),
                       given the drawn position of a point reference
``describe``           method: a few words for messages
=====================  ==============================================================

The reader (`sparsekin.model.modelfile`) expands every composite of a model or a unit into
its parts before it builds the `Mechanism` or the `Unit`: the parts' bodies follow the
bodies of the file, their joints the joints, their drivers the drivers, in the order of the
composites.  Everything downstream — equations, drawing, ``joints.csv``, ``forces.csv``,
repeats, ``save_model`` (which writes the parts) — sees exactly the elements one would
have written by hand.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from ..errors import ModelError
from . import _validate
from ._validate import FileKeys
from .bodies import Body
from .elements import PointRef, Revolute, Translational, TranslationalDriver, shown_point
from .elements.base import _set, _two_points
from .laws import Law

__all__ = ["COMPOSITE_KINDS", "composite_kind", "Parts", "Cylinder"]

#: The registry of composite kinds, by file ``type``.
COMPOSITE_KINDS: dict[str, type] = {}
_DECLARATION = ("type_name", "file_keys", "expand", "describe")


class Parts(NamedTuple):
    """What a composite stands for, in the order the reader adds them."""

    bodies: tuple[Body, ...]
    joints: tuple
    drivers: tuple


def composite_kind(kind: type) -> type:
    """Class decorator: check the declaration of a composite kind and register it."""
    missing = [name for name in _DECLARATION if not hasattr(kind, name)]
    if missing:
        raise TypeError(f"{kind.__name__} does not declare {', '.join(missing)}")
    if kind.type_name in COMPOSITE_KINDS:
        raise TypeError(f'two composite kinds declare the type "{kind.type_name}"')
    unknown = [key for key in kind.file_keys.keys if key not in kind.__dataclass_fields__]
    if unknown:
        raise TypeError(f"{kind.__name__}.file_keys names {unknown}, which are not fields")
    COMPOSITE_KINDS[kind.type_name] = kind
    return kind


@composite_kind
@dataclass(frozen=True, slots=True)
class Cylinder:
    """A hydraulic cylinder between two bodies: its barrel pinned to ``bodies[0]`` at
    ``points[0]``, its rod pinned to ``bodies[1]`` at ``points[1]``.

    It stands for the six blocks of a hand-written cylinder, named after `name` (N):

    * bodies ``N_barrel`` (origin ``points[0]``, carrying it) and ``N_rod`` (origin
      ``points[1]``, carrying it), frame angle 0;
    * revolutes ``N_barrel_pin`` (``N_barrel``–``bodies[0]`` at ``points[0]``) and
      ``N_rod_pin`` (``N_rod``–``bodies[1]`` at ``points[1]``);
    * the translational joint ``N`` (``N_barrel``–``N_rod``, axis ``points[0]`` →
      ``points[1]``, with the cylinder's `limits`): its stroke, the distance between the
      pins, grows when the cylinder extends;
    * with a `law`, the translational driver ``N_driver`` of joint ``N``, whose force is
      positive when it pushes the pins apart.

    Masses are optional: ``barrel_mass``, ``barrel_inertia`` (kg, kg·m² about the centre
    of mass) and ``barrel_com`` (the centre of mass on the axis, m from ``points[0]``
    towards ``points[1]``); the same for the rod, ``rod_com`` measured from ``points[1]``
    towards ``points[0]``.
    """

    name: str
    bodies: tuple[str, str]
    points: tuple[PointRef, PointRef]
    law: Law | None = None
    limits: tuple[float, float] | None = None
    barrel_mass: float | None = None
    barrel_inertia: float | None = None
    barrel_com: float | None = None
    rod_mass: float | None = None
    rod_inertia: float | None = None
    rod_com: float | None = None

    type_name = "cylinder"
    file_keys = FileKeys(
        required=("name", "bodies", "points"),
        optional=("law", "limits", "barrel_mass", "barrel_inertia", "barrel_com", "rod_mass", "rod_inertia", "rod_com"),
    )  # fmt: skip

    def __post_init__(self) -> None:
        _set(self, "name", _validate.name(self.name, "name"))
        _set(self, "bodies", _validate.two_names(self.bodies, "bodies"))
        _set(self, "points", _two_points(self.points))
        if self.points[0] == self.points[1]:
            raise ModelError(f"the two pins are the same point {shown_point(self.points[0])}; expected "
                             "the barrel's pin and the rod's", element="points")  # fmt: skip
        if self.law is not None and not callable(getattr(self.law, "evaluate", None)):
            raise ModelError(f"expected a law (an object with evaluate(t, initial)), got {type(self.law).__name__}",
                             element="law")  # fmt: skip
        if self.limits is not None:
            _set(self, "limits", _validate.limits(self.limits, "limits"))
        for field_name in ("barrel_mass", "barrel_inertia", "barrel_com", "rod_mass", "rod_inertia", "rod_com"):
            if getattr(self, field_name) is not None:
                _set(self, field_name, _validate.non_negative_float(getattr(self, field_name), field_name))

    def describe(self) -> str:
        return f'cylinder "{self.name}" {self.bodies[0]}.{shown_point(self.points[0])}–' \
               f"{self.bodies[1]}.{shown_point(self.points[1])}"  # fmt: skip

    def expand(self, position: Callable[[PointRef], tuple[float, float]]) -> Parts:
        """The bodies, joints and driver this cylinder stands for (see the class docstring).

        Parameters
        ----------
        position : callable
            The drawn global position (x, y) of a point reference; needed for the centres
            of mass given as distances along the axis.
        """
        name, (base, tip), (pin, rod_pin) = self.name, self.bodies, self.points
        if (self.barrel_com is not None or self.rod_com is not None) and position(pin) == position(rod_pin):
            field_name = "barrel_com" if self.barrel_com is not None else "rod_com"
            raise ModelError(f"the two pins are drawn at the same place {position(pin)}; a centre of mass along "
                             "the axis needs two distinct pins", element=field_name)  # fmt: skip
        barrel, rod = f"{name}_barrel", f"{name}_rod"
        bodies = (
            self._body(barrel, pin, rod_pin, self.barrel_mass, self.barrel_inertia, self.barrel_com, position),
            self._body(rod, rod_pin, pin, self.rod_mass, self.rod_inertia, self.rod_com, position),
        )
        joints = (
            Revolute((barrel, base), at=pin, name=f"{name}_barrel_pin"),
            Revolute((rod, tip), at=rod_pin, name=f"{name}_rod_pin"),
            Translational((barrel, rod), axis=(pin, rod_pin), name=name, limits=self.limits),
        )
        drivers = () if self.law is None else (TranslationalDriver(name, self.law, name=f"{name}_driver"),)
        return Parts(bodies, joints, drivers)

    @staticmethod
    def _body(body_name, own_pin, other_pin, mass, inertia, com, position) -> Body:
        """A barrel or a rod: its origin at its pin, which it carries; its centre of mass
        `com` m from its pin towards the other pin."""
        carried = (own_pin,) if isinstance(own_pin, str) else ()
        at = None
        if com is not None:
            start, end = position(own_pin), position(other_pin)
            length = math.hypot(end[0] - start[0], end[1] - start[1])
            at = (start[0] + com * (end[0] - start[0]) / length, start[1] + com * (end[1] - start[1]) / length)
        return Body(body_name, origin=own_pin, points=carried, mass=mass, inertia=inertia, com=at)
