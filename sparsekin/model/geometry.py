"""Rigid motion of points fixed in bodies: the one place where R(angle)·s is written in numpy.

A body frame is ``(x, y, angle)``.  A point fixed in the body has local coordinates ``s``
in that frame; its global position is ``r + R(angle) s``, its velocity
``r' + angle' Omega R s`` and its acceleration ``r'' + angle'' Omega R s - angle'² R s``,
where ``Omega`` turns a vector by +90°.  (The numba kernels of `sparsekin.engine._kernels`
write the same products for the constraint equations.)

>>> import numpy as np
>>> frames = np.array([[1.0, 0.0, np.pi / 2]])       # origin (1, 0), turned by 90°
>>> to_global(frames, np.array([[2.0, 0.0]])).round(12).tolist()
[[1.0, 2.0]]
>>> to_local(frames, np.array([[1.0, 2.0]])).round(12).tolist()
[[2.0, 0.0]]
"""

from __future__ import annotations

import numpy as np

__all__ = ["rotate", "to_local", "to_global", "carried_motion", "LocalCoordinates"]


def rotate(vectors: np.ndarray, angles) -> np.ndarray:
    """``R(angle) @ vector`` for each row of `vectors` (shape (n, 2)) and its angle (rad)."""
    cosine, sine = np.cos(angles), np.sin(angles)
    x, y = vectors[..., 0], vectors[..., 1]
    return np.stack([cosine * x - sine * y, sine * x + cosine * y], axis=-1)


def to_local(frames: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Coordinates in the frames ``(x, y, angle)`` (shape (n, 3)) of global points (n, 2)."""
    return rotate(points - frames[:, :2], -frames[:, 2])


class LocalCoordinates:
    """`to_local` for many points on few frames: each frame's cos and sin computed once,
    not once per point (the equations of a million-body model carry several points per body).

    Parameters
    ----------
    frames : ndarray, shape (n, 3)
        ``(x, y, angle)`` of each frame.
    """

    def __init__(self, frames: np.ndarray) -> None:
        self.frames, self.cosine, self.sine = frames, np.cos(frames[:, 2]), np.sin(frames[:, 2])

    def __call__(self, frame: np.ndarray, points: np.ndarray, turn_only: bool = False) -> np.ndarray:
        """``R(angle)ᵀ (p - origin)`` of each point in its frame, indices `frame` (k,), points
        (k, 2); ``R(angle)ᵀ p`` (a vector turned) if `turn_only`.  Shape (k, 2)."""
        if turn_only:
            dx, dy = points[:, 0], points[:, 1]
        else:
            origins = self.frames[frame, :2]
            dx, dy = points[:, 0] - origins[:, 0], points[:, 1] - origins[:, 1]
        cosine, sine = self.cosine[frame], self.sine[frame]
        out = np.empty((frame.size, 2))
        out[:, 0] = cosine * dx + sine * dy
        out[:, 1] = cosine * dy - sine * dx
        return out


def to_global(frames: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Global positions of points with local coordinates `local` (n, 2) in `frames` (n, 3)."""
    return frames[:, :2] + rotate(local, frames[:, 2])


def carried_motion(
    frames: np.ndarray, rates: np.ndarray, accelerations: np.ndarray, local
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration of a point fixed in a moving body.

    Parameters
    ----------
    frames, rates, accelerations : ndarray, shape (..., n_times, 3)
        The body's ``(x, y, angle)`` at each time (m, rad) and its first and second time
        derivatives (any leading dimensions: a sweep's variants).
    local : array_like, shape (2,)
        The point in the body frame, m.

    Returns
    -------
    position, velocity, acceleration : ndarray, shape (..., n_times, 2)
        Global, in m, m/s and m/s².
    """
    turned = rotate(np.asarray(local, dtype=float), frames[..., 2])  # R s, global
    across = np.stack([-turned[..., 1], turned[..., 0]], axis=-1)  # Omega R s
    omega, alpha = rates[..., 2:3], accelerations[..., 2:3]
    position = frames[..., :2] + turned
    velocity = rates[..., :2] + omega * across
    acceleration = accelerations[..., :2] + alpha * across - omega**2 * turned
    return position, velocity, acceleration
