"""What a kinematic analysis returns: `KinematicsResult`, a `Motion` and its run's statistics.

The motion and everything derived from it (points, own coordinates of joints and drivers,
forces, tables) is `sparsekin.results.motion.Motion`; the counters and the path are
`sparsekin.results.stats.RunStats` (`KinematicsResult.stats`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..engine.outputs import LimitState, element_index, limit_states, own_coordinates  # noqa: F401 (re-exported)
from .motion import CoordinateMotion, DriverForce, Motion, PointMotion, Reaction
from .stats import RunStats, RunStatsFields

__all__ = ["KinematicsResult", "run_summary", "Motion", "RunStats", "PointMotion", "CoordinateMotion", "DriverForce", "Reaction",
           "LimitState", "element_index", "own_coordinates", "limit_states"]


@dataclass(frozen=True, eq=False)
class KinematicsResult(Motion, RunStatsFields):
    """Positions, velocities and accelerations of every body at every time, and how they were solved.

    A `Motion` (its accessors: `point`, `joint`, `driver`, `driver_force`, `reaction`,
    `to_dataframe`, `to_xarray`) with the fields of `RunStats` (`stats`).

    Attributes
    ----------
    times, coordinates, velocities, accelerations, complete, mechanism
        See `Motion`; likewise ``recorded_points``, ``point_tracks``, ``recorded_joints``,
        ``joint_tracks``, ``force_labels``, ``force_units``, ``force_tracks``,
        ``quasi_static`` and ``store``.
    newton_iterations : ndarray of int, shape (n_times,)
        Newton corrections at each time (over all its sub-steps when the step to it was
        subdivided).
    n_factorizations, n_solves : int
        Factorizations of the Jacobian and linear solves in the whole run.
    n_subdivisions : int
        How many times a step was halved (a Newton failure, or a suspected jump to
        another assembly branch); 0 on a well-sampled run.
    redundant_equations : tuple of str
        The equations left out as redundant (empty for most models).
    n_refactorizations : int
        Numeric refactorizations on a fixed pattern (``linear_solver="refactor"``).
    linear_solver : str
        The path that solved the run: ``"compiled"`` (the compiled dense loop all the
        way), ``"compiled+dense"`` (the Python loop took over from it), ``"dense"``,
        ``"refactor"``, ``"reuse"`` (``"auto"`` found the refactorization's fill-in
        heavy at the first sample and reused its factorization across samples),
        ``"superlu"``, or ``"none"`` for a model with nothing to solve (no body, no equation).
    """

    def __repr__(self) -> str:
        """A summary (`run_summary`): the model, the samples, the path and what was recorded."""
        return run_summary(self)


def run_summary(result) -> str:
    """A summary of a result, like xarray's: its class, the model, the samples, the path
    (`RunStatsFields`) and what was recorded with its shape (not the arrays themselves)."""
    times = np.asarray(result.times[:1]), np.asarray(result.times[-1:])
    span = f"t = {times[0][0]:g} … {times[1][0]:g} s" if result.n_times else "no sample"
    state = "complete" if result.complete else "stopped early"
    lines = [
        f"<{type(result).__name__} {result.mechanism.name!r}: {result.n_times} samples, {span}, {state}>",
        (f"  model:        {_count(result.mechanism.n_bodies, 'body', 'bodies')}, "
         f"{_count(len(result.mechanism.joints), 'joint')}, {_count(len(result.mechanism.drivers), 'driver')}"),
        (f"  path:         {result.linear_solver}: {result.n_factorizations} factorizations, {result.n_solves} solves, "
         f"{int(np.sum(result.newton_iterations))} Newton corrections, {result.n_subdivisions} halved steps"),
        "  recorded:",
    ]
    if result.coordinates is not None:
        shape = tuple(result.coordinates.shape)
        lines.append(f"    coordinates  {shape}  coordinates, velocities, accelerations (x, y, angle per body)")
    if result.recorded_points:
        lines.append(f"    points       {tuple(result.point_tracks.shape)}  {_listed(result.recorded_points)} "
                     f"× (x, y, vx, vy, ax, ay)")  # fmt: skip
    if result.recorded_joints:
        shown = [result.mechanism.joints[k].name or f"joints[{k}]" for k in result.recorded_joints[:LISTED_NAMES]]
        joints = _listed(shown, total=len(result.recorded_joints))  # a copy's joint is built on demand
        lines.append(f"    joints       {tuple(result.joint_tracks.shape)}  {joints} × (value, rate, accel)")
    if result.force_labels:
        forces = "quasi-static " * result.quasi_static
        lines.append(f"    forces       {tuple(result.force_tracks.shape)}  {forces}{_listed(result.force_labels)}")
    if lines[-1] == "  recorded:":
        lines[-1] += " nothing but the times"
    if result.redundant_equations:
        lines.append(f"  left out:     {_listed(result.redundant_equations)} (redundant)")
    if result.store is not None:
        lines.append(f"  store:        {result.store}")
    return "\n".join(lines)


#: Most names listed in `KinematicsResult`'s summary per kind of record: a line each, whatever the model's size.
LISTED_NAMES = 4


def _count(number: int, word: str, plural: str | None = None) -> str:
    return f"{number} {word if number == 1 else plural or word + 's'}"


def _listed(names, total: int | None = None) -> str:
    """``A, B, C, D … (12)``: the first `LISTED_NAMES` names, and how many there are
    (`total`, when `names` holds the first ones only)."""
    names = list(names)
    total = len(names) if total is None else total
    shown = ", ".join(names[:LISTED_NAMES])
    return shown if total <= LISTED_NAMES else f"{shown} … ({total})"


