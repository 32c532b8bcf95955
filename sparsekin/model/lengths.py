"""Exact link lengths on an approximate drawing: the shape each body with `lengths` takes.

A body that states distances between its points (`Body.lengths`) takes the positions of its
points nearest (least squares) to the drawing that meet those distances exactly:

    minimise  Σ |p_i − d_i|²   over the body's points p_i (drawn at d_i)
    such that |p_a − p_b| = L_ab   for every stated length.

`nearest_points` solves it by the projection iteration of constrained least squares: at
each iterate the constraints are linearised, ``c + J Δ = 0``, and Δ is the smallest change
that brings ``p + Δ`` nearest the drawing on them,

    Δ = (d − p) − Jᵀ (J Jᵀ)⁺ (J (d − p) + c),

whose fixed points are exactly the stationary points of the problem (c = 0 and d − p in
the row space of J).  From the drawing it converges in a few iterations when the drawing
is near the lengths (a drawing read off a plan), many bodies at once.  Lengths that
contradict each other (a triangle that cannot close) leave a residual: a `ModelError`
naming the body.

The body's frame stays on its origin point when the body lists it (the origin moves with
its point), else on the drawn origin; its angle is the drawn one.  Points that a body does
not list keep their drawn local coordinates.  `BodyShapes` holds the local positions that
result, and `BodyShapes.correct` puts them in place of the drawn ones wherever an equation
places a point on such a body (`sparsekin.model.primitives.pack`).
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from .geometry import to_local

__all__ = ["BodyShapes", "NO_SHAPES", "nearest_points", "body_shapes", "LENGTH_TOLERANCE"]

#: Largest relative error of a stated length after the shape is found: beyond it the lengths
#: contradict each other.
LENGTH_TOLERANCE = 1e-12
#: Iterations of the projection before the lengths are declared contradictory.
MAX_ITERATIONS = 60


def nearest_points(drawn: np.ndarray, first: np.ndarray, second: np.ndarray, lengths: np.ndarray):
    """The points nearest the drawing that meet the lengths, many bodies of one shape at once.

    Parameters
    ----------
    drawn : ndarray, shape (m, n, 2)
        The drawn points of m bodies with n points each, m.
    first, second : ndarray of int, shape (c,)
        The two points of each stated length (indices among the n).
    lengths : ndarray, shape (c,)
        The lengths, m.

    Returns
    -------
    points : ndarray, shape (m, n, 2)
    error : ndarray, shape (m,)
        The largest relative error of a length (≤ `LENGTH_TOLERANCE` when they are met).

    Examples
    --------
    >>> drawn = np.array([[[0.0, 0.0], [1.1, 0.0]]])
    >>> points, error = nearest_points(drawn, np.array([0]), np.array([1]), np.array([1.0]))
    >>> points.round(12).tolist(), bool(error[0] < 1e-12)
    ([[[0.05, 0.0], [1.05, 0.0]]], True)
    """
    m, n = drawn.shape[:2]
    c = lengths.size
    centre = drawn[:, :1].copy()  # solved about the first point: no cancellation far from the origin
    drawn = drawn - centre
    points = drawn.copy()
    rows = np.arange(c)
    scale = np.max(lengths)
    for _ in range(MAX_ITERATIONS):
        across = points[:, first] - points[:, second]  # (m, c, 2)
        distance = np.hypot(across[..., 0], across[..., 1])
        residual = distance - lengths
        error = np.max(np.abs(residual) / lengths, axis=1, initial=0.0)
        away = (drawn - points).reshape(m, 2 * n)
        unit = across / np.where(distance > 0.0, distance, 1.0)[..., None]
        jacobian = np.zeros((m, c, n, 2))
        jacobian[:, rows, first] = unit
        jacobian[:, rows, second] -= unit
        jacobian = jacobian.reshape(m, c, 2 * n)
        projected = np.einsum("mcj,mj->mc", jacobian, away) + residual
        gram = np.einsum("mcj,mdj->mcd", jacobian, jacobian)
        multipliers = np.einsum("mcd,md->mc", np.linalg.pinv(gram, rcond=1e-12), projected)
        change = away - np.einsum("mcj,mc->mj", jacobian, multipliers)
        points += change.reshape(m, n, 2)
        if np.all(error <= 0.01 * LENGTH_TOLERANCE) and np.max(np.abs(change), initial=0.0) <= 1e-14 * scale:
            break
    across = points[:, first] - points[:, second]
    error = np.max(np.abs(np.hypot(across[..., 0], across[..., 1]) - lengths) / lengths, axis=1, initial=0.0)
    return points + centre, error


class BodyShapes:
    """The local positions of the points of the bodies with `lengths`.

    Attributes
    ----------
    body : ndarray of int, shape (k,)
        The body (its index in the mechanism) of each entry.
    drawn : ndarray, shape (k, 2)
        The point's drawn global position, m.
    local : ndarray, shape (k, 2)
        Its position in the body's frame, meeting the lengths, m.
    lengths : list of (str, tuple)
        For `check`: each body with lengths (by its name, a repeat's unit body once, as
        ``units.UNIT.bodies.NAME``) and its stated lengths with the drawn distances.
    """

    def __init__(self, body, drawn, local, lengths) -> None:
        order = np.lexsort((drawn[:, 1], drawn[:, 0], body))
        self.body, self.drawn, self.local = body[order], drawn[order], local[order]
        self.lengths = lengths

    def __bool__(self) -> bool:
        return bool(self.body.size)

    def find(self, body: np.ndarray, points: np.ndarray) -> np.ndarray:
        """The entry of each (body, drawn point) pair; -1 where the body does not list it."""
        if not self.body.size or not body.size:
            return np.full(body.size, -1, dtype=np.int64)
        k = self.body.size
        keys_body = np.concatenate([self.body, body])
        keys_x = np.concatenate([self.drawn[:, 0], points[:, 0]])
        keys_y = np.concatenate([self.drawn[:, 1], points[:, 1]])
        query = np.concatenate([np.zeros(k, dtype=bool), np.ones(body.size, dtype=bool)])
        order = np.lexsort((query, keys_y, keys_x, keys_body))  # an entry just before equal queries
        table_position = np.where(~query[order], order, -1)
        last_entry = np.maximum.accumulate(table_position)  # the last table entry at or before each place
        found = np.full(body.size, -1, dtype=np.int64)
        asked = order[query[order]] - k
        candidate = last_entry[query[order]]
        valid = candidate >= 0
        same = np.zeros(asked.size, dtype=bool)
        same[valid] = ((self.body[candidate[valid]] == body[asked[valid]])
                       & (self.drawn[candidate[valid], 0] == points[asked[valid], 0])
                       & (self.drawn[candidate[valid], 1] == points[asked[valid], 1]))  # fmt: skip
        found[asked[same]] = candidate[same]
        return found

    def local_points(self, frames: np.ndarray, bodies: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Where the points that start at `points` (k, 2, drawn) sit in the frames of `bodies`
        (k,; rows of the drawn `frames`): their drawn local coordinates, or their body's
        shape's."""
        local = to_local(frames[bodies], points)
        self.correct(bodies, points, local)
        return local

    def correct(self, frame: np.ndarray, points: np.ndarray, local: np.ndarray) -> None:
        """Put the shapes' local positions into `local` (k, 2) for the points `points` (drawn,
        global) placed on bodies `frame`: the points a body lists take their shape's position;
        the others keep their drawn local coordinates."""
        if not self:
            return
        found = self.find(np.asarray(frame), np.asarray(points))
        listed = found >= 0
        local[listed] = self.local[found[listed]]


def body_shapes(mechanism) -> BodyShapes:
    """The `BodyShapes` of `mechanism`'s bodies with lengths (empty if none has any).

    A repeat's unit body is solved once when every copy draws it alike (translated), else
    copy by copy, all copies at once.

    Raises
    ------
    ModelError
        If the lengths of a body contradict each other.
    """
    entries, stated = [], []
    frames = None
    for index, body in enumerate(mechanism.own("bodies")):
        if not body.lengths:
            continue
        frames = mechanism.frames() if frames is None else frames
        drawn = mechanism.positions(body.points)[None]
        origin_listed = isinstance(body.origin, str) and body.origin in body.points
        local = _shape(drawn, body, f"bodies.{body.name}", frames[index : index + 1], origin_listed)
        entries.append((np.array([index]), drawn[0], local))
        stated.append((f"bodies.{body.name}", _stated(body, drawn[0])))
    for copies in mechanism.copies:
        for e, body in enumerate(copies.unit.bodies):
            if not body.lengths:
                continue
            frames = mechanism.frames() if frames is None else frames
            where = f"{copies.label}: units.{copies.unit.name}.bodies.{body.name}"
            ks = np.arange(copies.count, dtype=np.int64)
            slots = copies.slot("bodies", ks, e)
            ks, slots = ks[slots >= 0], slots[slots >= 0]
            indices = copies.first_body + slots
            drawn = copies.reference_positions(list(body.points), ks)  # (m, n, 2)
            relative = drawn - drawn[:, :1]
            angles = frames[indices, 2]
            # alike to the rounding of the drawn coordinates (copies far along a chain round more)
            size = max(float(np.abs(relative).max(initial=0.0)), float(np.abs(drawn).max(initial=0.0)), 1e-3)
            alike = bool(np.all(np.abs(relative - relative[:1]) <= 1e-12 * size) and np.all(angles == angles[0]))
            shape_frames = frames[indices]
            origin_listed = isinstance(body.origin, str) and body.origin in body.points
            if alike:  # one shape, translated
                local = _shape(drawn[:1], body, where, shape_frames[:1], origin_listed)
                local = np.broadcast_to(local, (ks.size, *local.shape[1:]))
            else:
                local = _shape(drawn, body, where, shape_frames, origin_listed)
            entries.append((indices, drawn.reshape(-1, 2), local.reshape(-1, 2)))
            stated.append((f"units.{copies.unit.name}.bodies.{body.name}", _stated(body, drawn[0])))
    if not entries:
        return NO_SHAPES
    bodies = np.concatenate([np.repeat(index, drawn.shape[0] // index.size) for index, drawn, _ in entries])
    drawn = np.concatenate([drawn for _, drawn, _ in entries])
    local = np.concatenate([local.reshape(-1, 2) for _, _, local in entries])
    return BodyShapes(bodies, drawn, local, stated)


def _shape(drawn: np.ndarray, body, where: str, frames: np.ndarray, origin_listed: bool):
    """The local positions (m, n, 2) of the points of `body` drawn at `drawn` (m, n, 2) in
    frames (m, 3): meeting its lengths, in a frame on its moved origin point if it lists it."""
    names = list(body.points)
    first = np.array([names.index(a) for a, _, _ in body.lengths])
    second = np.array([names.index(b) for _, b, _ in body.lengths])
    lengths = np.array([length for _, _, length in body.lengths])
    points, error = nearest_points(drawn, first, second, lengths)
    if np.any(error > LENGTH_TOLERANCE):
        raise ModelError(_contradiction(body, drawn[int(np.argmax(error))]), element=where)
    origins = frames[:, :2].copy()
    if origin_listed:
        o = names.index(body.origin)
        origins += points[:, o] - drawn[:, o]
    moved = np.concatenate([origins, frames[:, 2:]], axis=1)
    m, n = drawn.shape[:2]
    local = to_local(np.repeat(moved, n, axis=0), points.reshape(-1, 2)).reshape(m, n, 2)
    return local


def _contradiction(body, drawn: np.ndarray) -> str:
    """Why the lengths of `body` cannot all hold: a triangle that cannot close if there is one."""
    given = {frozenset((a, b)): length for a, b, length in body.lengths}
    names = list(body.points)
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            for c in range(b + 1, len(names)):
                sides = [given.get(frozenset(pair)) for pair in ((names[a], names[b]), (names[b], names[c]),
                                                                   (names[a], names[c]))]
                if None not in sides and 2 * max(sides) > sum(sides):
                    return (f"the lengths {names[a]}–{names[b]} {sides[0]:g}, {names[b]}–{names[c]} {sides[1]:g} and "
                            f"{names[a]}–{names[c]} {sides[2]:g} cannot close a triangle (the longest exceeds the "
                            "sum of the others)")
    listed = ", ".join(f"{a}–{b} {length:g}" for a, b, length in body.lengths)
    return f"the lengths contradict each other: no placement of the points meets {listed}"


def _stated(body, drawn: np.ndarray) -> tuple[tuple[str, str, float, float], ...]:
    """Each stated length with its drawn distance: ``(P, Q, length, drawn)``."""
    names = list(body.points)
    return tuple((a, b, length, float(np.hypot(*(drawn[names.index(a)] - drawn[names.index(b)]))))
                 for a, b, length in body.lengths)


#: The shapes of a mechanism without lengths.
NO_SHAPES = BodyShapes(np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros((0, 2)), [])
