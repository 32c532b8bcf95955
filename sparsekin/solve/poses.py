"""`pose_model`: the model drawn at a solved pose (`sparsekin.model.poses.posed`), checked.

A rough drawing becomes an exact one (the pose at t = 0), and any pose of a run can start a
new model: a run of the posed model from t = 0 is the original run from the pose's time on.
"""

from __future__ import annotations

import numpy as np

from ..engine.assembly import Assembler
from ..engine.discretization import discretize
from ..engine.pattern import build_pattern
from ..errors import ModelError
from ..model.mechanism import Mechanism
from ..model.poses import posed
from .kinematics import solve_kinematics

__all__ = ["pose_model"]

#: A time within this (relative to the run's span, at least 1e-12 s) of a sample is that sample.
SAMPLE_TOLERANCE = 1e-12
#: Largest weighted residual of the posed model at its drawing, and largest change of a
#: point's place in its body (relative to the model size): beyond them the pose was not
#: drawn faithfully.
FAITHFUL_TOLERANCE = 1e-9


def pose_model(result, time: float) -> Mechanism:
    """The model of `result` drawn at its pose at `time` (s), its laws shifted by `time`.

    Parameters
    ----------
    result : KinematicsResult
        A run; at a time between its samples (or when it kept no coordinates) the model is
        solved again up to `time`.
    time : float
        Within the run's span, s.

    Returns
    -------
    Mechanism
        ``save_model`` writes it; `solve_kinematics` of it at ``t`` is the original run at
        ``time + t``.

    Raises
    ------
    ValueError
        If `time` is outside the run.
    ModelError
        If the pose cannot be drawn (a point that two bodies carry is at two places).

    Examples
    --------
    >>> from sparsekin import Body, Linear, Mechanism, Revolute, RotationalDriver, solve_kinematics
    >>> crank = Mechanism(
    ...     points={"O": (0.0, 0.0), "A": (0.1, 0.0)},
    ...     bodies=[Body("crank", origin="O", points=("O", "A"))],
    ...     joints=[Revolute(("crank", "ground"), at="O")],
    ...     drivers=[RotationalDriver(("crank", "ground"), law=Linear(rate=2.0))],
    ... )
    >>> later = pose_model(solve_kinematics(crank, [0.0, 0.5]), 0.5)
    >>> later.bodies[0].angle, later.drivers[0].law
    (1.0, Linear(rate=2.0, start=1.0))
    """
    mechanism, times = result.mechanism, np.asarray(result.times, dtype=float)
    time = float(time)
    span = float(times[-1] - times[0]) if times.size else 0.0
    tolerance = max(SAMPLE_TOLERANCE * max(span, abs(time)), SAMPLE_TOLERANCE)
    if not times.size or not times[0] - tolerance <= time <= times[-1] + tolerance:
        raise ValueError(f"`time` must be within the run, {times[0]:g} to {times[-1]:g} s, got {time!r}.")
    k = int(np.argmin(np.abs(times - time)))
    if abs(times[k] - time) <= tolerance and result.coordinates is not None:
        coordinates = np.asarray(result.coordinates[k], dtype=float)
        time = float(times[k])
    else:  # between samples: solve again up to the pose
        again = solve_kinematics(mechanism, np.append(times[times < time - tolerance], time), points=None, forces=None)
        coordinates = np.asarray(again.coordinates[-1], dtype=float)
    pattern = build_pattern(mechanism)
    model = posed(mechanism, coordinates, time, pattern.driven_initial)
    _check_faithful(pattern, model, coordinates, time)
    return model


def _check_faithful(pattern, model: Mechanism, coordinates: np.ndarray, time: float) -> None:
    """The posed model places every point of every equation where the original did, and
    its drawing satisfies its equations at t = 0."""
    posed_model = discretize(model)
    posed_pattern = posed_model.constraints
    scale = pattern.length_scale
    for original, now in zip(pattern.primitives, posed_pattern.primitives):
        if "local_i" not in original._fields:  # combinations of coordinates: no points
            continue
        if original.row.shape != now.row.shape:
            raise ModelError(f"the pose at t = {time:g} s cannot be drawn faithfully: its equations differ",
                             element="pose")  # fmt: skip
        # entry by entry in the order of their rows (a repeat's and its copies' blocks are laid out apart)
        mine, theirs = np.argsort(original.row, kind="stable"), np.argsort(now.row, kind="stable")
        for field_name in ("local_i", "local_j", "direction"):
            if field_name not in original._fields:
                continue
            gap = np.abs(getattr(original, field_name)[mine] - getattr(now, field_name)[theirs])
            if gap.size and np.max(gap) > FAITHFUL_TOLERANCE * scale:
                raise ModelError(f"the pose at t = {time:g} s cannot be drawn faithfully: the {type(original).__name__} "
                                 f"equations place a point {np.max(gap):.3g} m away from where the run has it",
                                 element="pose")  # fmt: skip
    assembler = Assembler(posed_model)
    assembler.set_time(0.0)
    norm = assembler.fill_residual_jacobian(posed_pattern.initial_coordinates)
    if not norm <= FAITHFUL_TOLERANCE:
        raise ModelError(f"the pose at t = {time:g} s cannot be drawn faithfully: its drawing leaves a residual of "
                         f"{norm:.3g} (relative to the model size)", element="pose")  # fmt: skip
