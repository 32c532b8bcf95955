"""The model made arrays, once: `Discretization` and `discretize`.

Every analysis turns a `Mechanism` into arrays for the kernels: the constraint pattern
(`ConstraintPattern`), the drivers' laws (`DriverLaws`), the masses and loads
(`sparsekin.engine.forces.LoadPattern`), where each named point rides (`PointMap`) and the
own coordinates of elements (`OutputPattern`).  A `Discretization` holds them all, the
constraints built at once and the others when first asked for, and is what the layers
above take instead of a mechanism and its pattern.

A sweep over law parameters shares one constraint pattern among its variants:
``discretize(variant, constraints=shared)`` checks that `shared` fits `variant` (the same
bodies, equations per element and drawing) and packs the variant's own laws.

>>> from sparsekin.testset import task5
>>> model = discretize(task5())
>>> model.constraints.n_coordinates, model.constraints.n_equations
(30, 30)
>>> model.points.locate("K")[0]  # K rides on the first body
0
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..model.laws import fill_laws
from ..model.mechanism import Mechanism
from .forces import LoadPattern, build_load_pattern
from .pattern import (
    ConstraintPattern,
    OutputPattern,
    PointMap,
    build_output_pattern,
    build_pattern,
    build_point_map,
    pack_element_laws,
    per_element,
)

__all__ = ["Discretization", "DriverLaws", "discretize"]


class DriverLaws:
    """The laws of every driven row (`ConstraintPattern.driven_row`), evaluated together.

    Built-in laws are evaluated in one numba call over a `sparsekin.model.laws.LawTable`, so
    that a model with 10^5 drivers costs one call per time; other law objects are called
    one by one.
    """

    def __init__(self, mechanism: Mechanism, initial: np.ndarray) -> None:
        self.table, self._others, self.n_laws = pack_element_laws(mechanism, "drivers", initial)
        self._initial = initial

    def evaluate(self, t: float, value: np.ndarray, rate: np.ndarray, acceleration: np.ndarray) -> None:
        """Fill the value and time derivatives of every law at time `t` (s)."""
        fill_laws(self.table, float(t), value, rate, acceleration)
        for k, law in self._others:
            value[k], rate[k], acceleration[k] = law.evaluate(t, float(self._initial[k]))


@dataclass(frozen=True, eq=False)
class Discretization:
    """Every array view of one mechanism (build it with `discretize`).

    Attributes
    ----------
    mechanism : Mechanism
    constraints : ConstraintPattern
        The joints' and drivers' equations on their fixed CSR pattern.
    driver_laws : DriverLaws
        The drivers' laws, packed for the driven rows (lazy).
    loads : LoadPattern
        The bodies' masses, gravity and the loads (lazy).
    points : PointMap
        Where each named point rides (lazy).
    outputs : OutputPattern
        The own coordinate of every joint and driver that has one (lazy; `output_rows`
        builds the rows of chosen elements).
    """

    mechanism: Mechanism
    constraints: ConstraintPattern

    @cached_property
    def driver_laws(self) -> DriverLaws:
        return DriverLaws(self.mechanism, self.constraints.driven_initial)

    @cached_property
    def loads(self) -> LoadPattern:
        return build_load_pattern(self.mechanism)

    @cached_property
    def points(self) -> PointMap:
        return build_point_map(self.mechanism)

    @cached_property
    def outputs(self) -> OutputPattern:
        return build_output_pattern(self.mechanism)

    def output_rows(self, joints=(), drivers=()) -> OutputPattern:
        """The own coordinates of the joints and drivers of these indices, in that order."""
        return build_output_pattern(self.mechanism, joints=tuple(joints), drivers=tuple(drivers))

    @property
    def n_coordinates(self) -> int:
        return self.constraints.n_coordinates


def discretize(mechanism: Mechanism, constraints: ConstraintPattern | None = None) -> Discretization:
    """The arrays of `mechanism`, with `constraints` (``build_pattern`` of a mechanism with the
    same bodies, equations and drawing, only driver-law parameters differing) if given.

    Raises
    ------
    TypeError
        If `mechanism` is not a Mechanism.
    ValueError
        If `constraints` is not the pattern of a mechanism like `mechanism`.
    """
    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}.")
    if constraints is None:
        constraints = build_pattern(mechanism)
    else:
        _check_pattern(constraints, mechanism)
    return Discretization(mechanism, constraints)


def _check_pattern(pattern, mechanism: Mechanism) -> None:
    """`pattern` must be that of a mechanism with the bodies, equations and drawing of `mechanism`."""
    if not isinstance(pattern, ConstraintPattern):
        got = type(pattern).__name__
        raise ValueError(f"`pattern` must be a ConstraintPattern (build_pattern), got {got}.")
    if (pattern.n_bodies, pattern.n_equations) != (mechanism.n_bodies, mechanism.n_equations):
        why = (f"it has {pattern.n_bodies} bodies and {pattern.n_equations} equations, `mechanism` "
               f"{mechanism.n_bodies} and {mechanism.n_equations}")  # fmt: skip
    else:
        counts = np.concatenate([per_element(mechanism, kind, lambda element: element.n_equations)
                                 for kind in ("joints", "drivers")])  # fmt: skip
        if counts.size + 1 != pattern.element_first_row.size or not np.array_equal(
            np.diff(pattern.element_first_row), counts
        ):  # fmt: skip
            why = "its joints and drivers have other numbers of equations"
        elif not np.array_equal(pattern.initial_coordinates, mechanism.frames().ravel()):
            why = "its bodies are drawn elsewhere"
        else:
            return
    raise ValueError(f"`pattern` must be the ConstraintPattern of a mechanism like `mechanism`: {why}.")
