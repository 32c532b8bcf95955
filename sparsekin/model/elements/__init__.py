"""Joints, drivers and loads: every kind declared once, in this package.

A kind is a frozen dataclass whose fields are its keys in the model file, registered with
`joint_kind` or `driver_kind`.  Its declaration says everything the rest of the package
needs of it; the model checks, the pattern builder, the model-file reader and writer,
the drawing, the joint outputs and the generated element reference all iterate over the
registries `JOINT_KINDS` and `DRIVER_KINDS`:

=====================  ==============================================================
``type_name``          its ``type`` in the model file
``file_keys``          the keys it accepts (`sparsekin.model._validate.FileKeys`)
``equation_names``     one name per equation, in row order (their number is
                       ``n_equations``)
``equations``          classmethod: its equations as blocks of the primitives of
                       `sparsekin.model.primitives`, for all elements of the kind at once,
                       read from their `Columns`
``output_names``       its own coordinate and two derivatives (``joints.csv`` column
                       suffixes), or ``()`` if it has none
``outputs``            classmethod: the primitive that measures its own coordinate
``body_fields``,       fields naming bodies, points and joints, which the mechanism
``point_fields``,      checks (and which a unit's copies rename)
``joint_fields``
``check``              method: checks that need the whole mechanism (optional)
``describe``           method: a few words for messages
``draw``               method: its drawing, on a `sparsekin.plots.Canvas`
``law_fields``         drivers only: the field holding the law of each equation, in
                       row order (default ``("law",)``)
``force_names``        drivers only: the ``forces.csv`` column suffix of each
                       equation's force (default ``("force",)``)
``reaction_point``     joints only, classmethod: the point about which the reaction's
                       torque is taken, and the body of the joint that carries it
                       (default: the frame origin of ``bodies[0]``)
``reaction_torque``    joints only: whether ``forces.csv`` has the reaction's torque
=====================  ==============================================================

Loads (`LOAD_KINDS`, registered with `load_kind`) declare ``type_name``, ``file_keys``,
``loads`` (classmethod: their blocks of the primitive loads of `sparsekin.model.loads`, read
from their `Columns`, whose ``rows`` are then the index of each load's first law),
``n_laws`` and ``laws()`` (the law of each component), ``describe`` and ``draw``.

The package has one module per job: `~sparsekin.model.elements.base` holds the registries,
the decorators, the base classes and the helpers the declarations share; `joints`, `drivers`
and `loads` declare the kinds.  A new kind is a class in one of them (or in a new module that
imports `joint_kind`, `driver_kind` or `load_kind` from here and is imported below, so that it
registers itself).  The guide ``docs/adding-an-element.md`` walks through adding a kind.

Equation builders receive the elements of one kind as `Columns`: one array per field,
an entry per element (the model's own elements, or a unit's over all its copies at once;
`sparsekin.engine.columns`), with the first row of each element, the stored index of each body
named (the ground is ``columns.ground``), the drawn positions of points and the drawn
body frames.  Blocks are written in the global coordinates of the drawn configuration;
joints hold the values their equations have there.
"""

from __future__ import annotations

from .base import (
    COORDINATE_NAMES,
    DRIVER_KINDS,
    GROUND,
    JOINT_KINDS,
    LOAD_KINDS,
    Columns,
    Driver,
    Joint,
    Load,
    PointRef,
    driver_kind,
    joint_kind,
    load_kind,
    shown_point,
)

# Importing the declaring modules registers their kinds; the registries keep the order of
# declaration: joints (which `drivers` imports first), drivers, loads.
from .drivers import (
    AbsoluteDriver,
    DistanceDriver,
    PathDriver,
    RotationalDriver,
    TranslationalDriver,
)
from .joints import Gear, PinInSlot, RackPinion, Revolute, Rigid, Translational
from .loads import Actuator, Force, RotationalSpring, Spring, Torque

__all__ = [
    "COORDINATE_NAMES",
    "PointRef",
    "Columns",
    "Joint",
    "Driver",
    "shown_point",
    "DRIVER_KINDS",
    "GROUND",
    "JOINT_KINDS",
    "LOAD_KINDS",
    "AbsoluteDriver",
    "Actuator",
    "DistanceDriver",
    "Force",
    "Gear",
    "Load",
    "PathDriver",
    "PinInSlot",
    "RackPinion",
    "Revolute",
    "Rigid",
    "RotationalDriver",
    "RotationalSpring",
    "Spring",
    "Torque",
    "Translational",
    "TranslationalDriver",
    "driver_kind",
    "joint_kind",
    "load_kind",
]
