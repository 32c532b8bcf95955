"""Drivers that move nothing: a crank of zero length runs, but no point moves.

`check_model` asks, at the assembled configuration, what each driven equation does to the
named points when it alone changes at a unit rate (1 m/s or 1 rad/s) and every other
equation holds: the velocity solve ``Phi_q qdot = e_row`` on the equations kept (the
redundant ones left out), then each point's velocity from its body's ``(xdot, ydot,
thetadot)``.  A driver none of whose equations moves a named point by more than
`IDLE_SPEED` times the model's size (per unit rate) drives nothing: a crank whose points
all sit at its pivot turns, and the mechanism stands still.

Checked when the model has no free motion (the velocities are then unique), at most
`MOST_CHECKED_COORDINATES` coordinates (its own sparse LU of the Jacobian: a fraction of a
second there, where the rank analysis of a large model takes seconds) and at most
`MOST_CHECKED_ROWS` driven equations (a solve for each).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from ..engine.pattern import build_point_map
from ..engine.reduced import kept_equations
from ..model.geometry import to_global

__all__ = ["IDLE_SPEED", "MOST_CHECKED_COORDINATES", "MOST_CHECKED_ROWS", "idle_drivers"]

#: A point moving less than this many model sizes per unit rate of a driver stands still.
IDLE_SPEED = 1e-9
#: Models with more driven equations, or more coordinates, than these are not checked.
MOST_CHECKED_ROWS = 256
MOST_CHECKED_COORDINATES = 30_000


def idle_drivers(mechanism, pattern, jacobian, redundant_rows: np.ndarray, coordinates: np.ndarray) -> tuple[str, ...]:
    """The labels of the drivers whose unit rate moves no named point (``drivers[0]
    (rotational crank–ground)``).  Empty when every driver moves a point, or when the check
    does not apply (see the module)."""
    if pattern.n_coordinates > MOST_CHECKED_COORDINATES:  # before any pass over the equations
        return ()
    driven = np.setdiff1d(pattern.driven_row, redundant_rows)
    kept = kept_equations(pattern.n_equations, redundant_rows)
    if not driven.size or driven.size > MOST_CHECKED_ROWS or kept.size != pattern.n_coordinates:
        return ()
    names = build_point_map(mechanism)
    square = sparse.csc_array(sparse.csr_array(jacobian)[kept])
    try:
        lu = splu(square, permc_spec="COLAMD")  # of full rank: the caller found no free motion
    except RuntimeError:
        return ()
    unit_rates = np.zeros((kept.size, driven.size))
    unit_rates[np.searchsorted(kept, driven), np.arange(driven.size)] = 1.0
    rates = lu.solve(unit_rates).reshape(-1, 3, driven.size)  # (body, xdot/ydot/thetadot, driven row)
    body, local = names.arrays()
    moving = body >= 0
    frames = np.asarray(coordinates, dtype=float).reshape(-1, 3)
    arm = to_global(frames[body[moving]], local[moving]) - frames[body[moving], :2]  # origin to point, global
    on_body = rates[body[moving]]
    vx = on_body[:, 0] - on_body[:, 2] * arm[:, 1:2]
    vy = on_body[:, 1] + on_body[:, 2] * arm[:, 0:1]
    fastest = np.hypot(vx, vy).max(axis=0, initial=0.0)  # per driven row
    row_driver = pattern.driven_driver[np.searchsorted(pattern.driven_row, driven)]
    still = [k for k in np.unique(row_driver).tolist() if fastest[row_driver == k].max() <= IDLE_SPEED * pattern.length_scale]
    return tuple(mechanism.element_label("drivers", k) for k in still)
