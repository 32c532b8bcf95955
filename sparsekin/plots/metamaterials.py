"""Figures of lattice metamaterials: how a lattice's width and height follow its opening.

A mechanism-based metamaterial is read by its effective strains: the width and the height
of the lattice (distances between the frame origins of two bodies across it — the centres
of its first and last squares, say), their relative changes
ε_x = ln(w / w0) and ε_y = ln(h / h0), and Poisson's ratio ν = −dε_y / dε_x.  For the
rotating squares both dimensions scale with cos θ + sin θ: the two curves are one and
ν = −1 at every opening θ; rectangles of unequal sides give another ν at every θ.

matplotlib is needed (``pip install "sparsekin[plot]"``), as for every figure of
`sparsekin.plots`.

>>> import numpy as np
>>> import sparsekin as sk
>>> from sparsekin.testset import rotating_squares
>>> result = sk.solve_kinematics(rotating_squares(2), np.linspace(0.0, 3.0, 31))
>>> size = lattice_size(result, ("s0_0.sq", "s1_0.sq"), ("s0_0.sq", "s0_1.sq"), "s0_0.sq")
>>> moving = np.isfinite(size.poisson_ratio)          # NaN where the driver turns back
>>> bool(np.allclose(size.width, size.height)), bool(np.allclose(size.poisson_ratio[moving], -1.0))
(True, True)
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..results.kinematics import KinematicsResult
from .common import _new_figure, _save

__all__ = ["LatticeSize", "lattice_size", "plot_lattice_size"]

#: Samples whose strain rate ε_x' is below this share of its largest are left out of ν:
#: there the lattice turns back (θ' = 0) and ν is 0/0.
STILL_SHARE = 0.05


class LatticeSize(NamedTuple):
    """A lattice's size over an analysis (arrays of shape (n_times,)).

    Attributes
    ----------
    opening : ndarray
        The opening angle, |angle| of the chosen body, rad.
    width, height : ndarray
        The x distance and the y distance between the frame origins of the chosen pairs of bodies, m.
    poisson_ratio : ndarray
        −dε_y / dε_x from the samples (central differences in time); NaN where the lattice
        is (nearly) still, `STILL_SHARE`.
    """

    opening: np.ndarray
    width: np.ndarray
    height: np.ndarray
    poisson_ratio: np.ndarray


def lattice_size(result: KinematicsResult, across: tuple[str, str], up: tuple[str, str], body: str) -> LatticeSize:
    """The width, height and Poisson's ratio of a lattice over `result`.

    Parameters
    ----------
    result : KinematicsResult
    across : (str, str)
        Two bodies whose frame origins' x distance is the width (say the first and the
        last square of row 0).
    up : (str, str)
        Two bodies whose frame origins' y distance is the height.
    body : str
        The body whose |angle| is the opening angle.
    """
    if result.coordinates is None:
        raise ValueError("`result` must keep the coordinates (solve_kinematics(..., coordinates=True)).")

    def coordinate(name: str, k: int) -> np.ndarray:
        return result.coordinates[:, 3 * result.mechanism.body_index(name) + k]

    width = coordinate(across[1], 0) - coordinate(across[0], 0)
    height = coordinate(up[1], 1) - coordinate(up[0], 1)
    opening = np.abs(coordinate(body, 2))
    rate_x = np.gradient(np.log(np.abs(width)), result.times)
    rate_y = np.gradient(np.log(np.abs(height)), result.times)
    moving = np.abs(rate_x) > STILL_SHARE * np.abs(rate_x).max(initial=0.0)
    ratio = np.full(width.shape, np.nan)
    ratio[moving] = -rate_y[moving] / rate_x[moving]
    return LatticeSize(opening, width, height, ratio)


def plot_lattice_size(result: KinematicsResult, across: tuple[str, str], up: tuple[str, str], body: str,
                      path) -> Path:  # fmt: skip
    """Plot a lattice's width and height against its opening angle, and its Poisson's ratio.

    Left: width and height relative to their values at the first sample (the same curve
    for an isotropic auxetic such as the rotating squares). Right: ν = −dε_y/dε_x against
    the opening angle. Arguments as `lattice_size`; the figure is written to `path` (PNG).

    Returns
    -------
    Path
        The file written.
    """
    size = lattice_size(result, across, up, body)
    figure, (sizes, ratio) = _new_figure((10.0, 4.2), columns=2)
    order = np.argsort(size.opening, kind="stable")
    opening = size.opening[order]
    sizes.plot(opening, size.width[order] / size.width[0], label="width / width at t = 0", linewidth=3.0, alpha=0.6)
    sizes.plot(opening, size.height[order] / size.height[0], "--", label="height / height at t = 0", color="black")
    sizes.set_xlabel("opening angle θ (rad)")
    sizes.set_ylabel("relative size")
    sizes.set_title(f"{result.mechanism.name}: the lattice's size")
    sizes.legend()
    sizes.grid(True, alpha=0.3)
    ratio.plot(opening, size.poisson_ratio[order], ".", markersize=4)
    ratio.set_xlabel("opening angle θ (rad)")
    ratio.set_ylabel("Poisson's ratio −dε_y / dε_x")
    ratio.set_title("Poisson's ratio from the samples")
    finite = size.poisson_ratio[np.isfinite(size.poisson_ratio)]
    if finite.size and np.ptp(finite) < 1e-6 * max(1.0, np.abs(finite).max()):
        centre = float(np.median(finite))
        ratio.set_ylim(centre - 0.5, centre + 0.5)  # a constant ratio: a readable band around it
    ratio.grid(True, alpha=0.3)
    return _save(figure, Path(path))
