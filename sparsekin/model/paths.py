"""The grammar of parameter paths, shared by a repeat's `vary` and a sweep's ``--vary``.

A path names one number (or one point) of a model or of a unit: a law parameter of a
driver (``drivers[0].law.phase``, ``drivers.NAME.law_x.amplitude``), a point
(``points.M``) or a body's drawn angle (``bodies.NAME.angle``).  One regular expression
per form, here, so that the reader of units and the sweeps parse the same language.
"""

from __future__ import annotations

import re

__all__ = ["DRIVER_PATH", "POINT_PATH", "BODY_ANGLE_PATH"]

#: ``drivers[i].FIELD.KEY`` or ``drivers.NAME.FIELD.KEY``, FIELD ``law``, ``law_x`` or ``law_y``;
#: groups: index, name, field, key.
DRIVER_PATH = re.compile(r"drivers(?:\[(\d+)\]|\.([^.\[\]]+))\.(law(?:_x|_y)?)\.(\w+)")
#: ``points.NAME``; group: the name (which may hold dots: ``points.u3.Q``).
POINT_PATH = re.compile(r"points\.(.+)")
#: ``bodies.NAME.angle``; group: the body's name.
BODY_ANGLE_PATH = re.compile(r"bodies\.([^.\[\]]+)\.angle")
