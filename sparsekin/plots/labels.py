"""Labels placed where they overlap no other label and as little of the drawing as they can."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Background of body labels: a pale box, so that lines under the name do not hide it.
LABEL_PAD = 0.15
LABEL_BOX = {"boxstyle": f"round,pad={LABEL_PAD}", "facecolor": "white", "alpha": 0.8, "edgecolor": "none"}

#: Point labels and body labels: font size (points), weight, colour.
POINT_LABEL_STYLE = {"fontsize": 10, "color": "tab:blue"}
BODY_LABEL_STYLE = {"fontsize": 9, "fontweight": "bold", "color": "black"}
#: Directions tried for a label around its anchor, in order of preference: up-right first
#: (where a reader looks for a point's name), then the other diagonals, then the sides.
LABEL_DIRECTIONS = ((1, 1), (-1, 1), (1, -1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1))
#: Distances tried from a label's anchor, points, beyond the symbol drawn at the anchor.
LABEL_DISTANCES = (3.0, 9.0, 16.0, 26.0)
#: What a label pays for each thing it covers.  Another label is forbidden unless every
#: candidate covers one; leaving the axes is nearly so.
LABEL_COSTS = {"label": 1e4, "outside": 1e3, "segment": 3.0, "disc": 5.0, "distance": 0.25, "rank": 0.01,
               "kept": -2.0}  # fmt: skip
#: Above this many labels a drawing is too crowded to read anyway: each label takes its first
#: place without the search (draw_mechanism of task5_chain(100), 1000 bodies and 2300
#: labels: 16.1 s with the search, 8.2 s without; 11.6 s before labels were placed).
MAX_PLACED_LABELS = 200


class Label(NamedTuple):
    """A label to place: its text, its anchor (data coordinates), the radius of the symbol
    drawn at the anchor (m), ``"point"`` or ``"body"``, and for a body drawn as a segment
    the segment's direction (its label goes beside it, not along it)."""

    text: str
    anchor: np.ndarray
    clearance: float
    kind: str
    along: np.ndarray | None = None


def place_labels(axes, labels, segments=(), discs=(), *, kept=None, texts=None) -> list[tuple[Label, int]]:
    """Place `labels` one after the other, each where it covers no label placed before it
    and as little of the drawing as it can, and draw them.

    Each label tries `LABEL_DIRECTIONS` at `LABEL_DISTANCES` beyond the symbol at its
    anchor (a body label first tries its anchor itself), in display pixels, and takes the
    candidate of least cost (`LABEL_COSTS`) (with more than `MAX_PLACED_LABELS` labels,
    each takes its first candidate): a box over a label placed before it is
    forbidden unless every candidate has one, a box leaving the axes nearly so; each
    segment of the drawing it crosses and each disc it touches cost a little; farther
    candidates cost a little more.  This is greedy: a label placed early is never moved
    for a later one.

    Parameters
    ----------
    axes : matplotlib.axes.Axes
        Axes whose limits and position are final.
    labels : sequence of Label
    segments : sequence of array_like, shape (2, 2)
        Lines of the drawing, data coordinates.
    discs : sequence of (x, y, radius)
        Round symbols of the drawing, data coordinates.
    kept : dict, optional
        ``{(kind, text): candidate}`` of a previous frame: such a candidate gets a bonus
        when it is still free, so that labels do not jump between frames of an animation.
    texts : dict, optional
        ``{(kind, text): matplotlib Text}``: labels drawn before, moved instead of drawn
        anew (new ones are added to it).

    Returns
    -------
    list of (Label, int)
        Each label and the candidate it took.
    """
    kept = kept or {}
    texts = {} if texts is None else texts
    crowded = len(labels) > MAX_PLACED_LABELS
    figure = axes.get_figure()
    renderer = figure.canvas.get_renderer()
    to_pixels = axes.transData.transform
    points_to_pixels = figure.dpi / 72.0
    window = axes.get_window_extent()
    segments_px = to_pixels(np.asarray(segments, dtype=float).reshape(-1, 2)).reshape(-1, 4)
    disc_array = np.asarray(discs, dtype=float).reshape(-1, 3)
    discs_px = np.column_stack([to_pixels(disc_array[:, :2]), disc_array[:, 2] * _pixels_per_metre(axes)])
    scale = _pixels_per_metre(axes)
    boxes = np.empty((0, 4))
    placed = []
    for label in labels:
        style = POINT_LABEL_STYLE if label.kind == "point" else BODY_LABEL_STYLE
        key = (label.kind, label.text)
        text = texts.get(key)
        if text is None:  # measured as matplotlib lays it out (line height, not glyph height)
            text = axes.text(*label.anchor, label.text, ha="center", va="center", zorder=6,
                             bbox=LABEL_BOX if label.kind == "body" else None, **style)  # fmt: skip
            extent = text.get_window_extent(renderer)
            pad = 2 * LABEL_PAD * style["fontsize"] * points_to_pixels if label.kind == "body" else 0.0
            text._sparsekin_size = (extent.width + pad, extent.height + pad)
            texts[key] = text
        width, height = text._sparsekin_size
        anchor = to_pixels(np.asarray(label.anchor, dtype=float)[None])[0]
        candidates, offsets = _label_candidates(label, anchor, width, height, label.clearance * scale,
                                                points_to_pixels)  # fmt: skip
        if crowded:
            text.set_position(axes.transData.inverted().transform([candidates[0, :2] + (width / 2, height / 2)])[0])
            placed.append((label, 0))
            continue
        cost = LABEL_COSTS["distance"] * np.hypot(*offsets.T) / points_to_pixels
        cost += LABEL_COSTS["rank"] * np.arange(len(candidates))
        cost += LABEL_COSTS["label"] * _overlaps(candidates, boxes)
        outside = ((candidates[:, 0] < window.x0) | (candidates[:, 1] < window.y0)
                   | (candidates[:, 2] > window.x1) | (candidates[:, 3] > window.y1))  # fmt: skip
        cost += LABEL_COSTS["outside"] * outside
        cost += LABEL_COSTS["segment"] * _segments_crossing(candidates, segments_px)
        cost += LABEL_COSTS["disc"] * _discs_touching(candidates, discs_px, exclude=anchor)
        previous = kept.get((label.kind, label.text))
        if previous is not None and previous < len(cost) and cost[previous] < LABEL_COSTS["outside"]:
            cost[previous] += LABEL_COSTS["kept"]
        choice = int(np.argmin(cost))
        box = candidates[choice]
        boxes = np.vstack([boxes, box])
        centre = axes.transData.inverted().transform([[(box[0] + box[2]) / 2, (box[1] + box[3]) / 2]])[0]
        text.set_position(centre)
        placed.append((label, choice))
    return placed


def _pixels_per_metre(axes) -> float:
    (x0, _), (x1, _) = axes.transData.transform([[0.0, 0.0], [1.0, 0.0]])
    return abs(x1 - x0)


def _label_candidates(label: Label, anchor, width, height, clearance, points_to_pixels):
    """Boxes ``(x0, y0, x1, y1)`` in pixels of every candidate place, and their offsets."""
    directions = np.array(LABEL_DIRECTIONS, dtype=float)
    if label.along is not None:  # a body drawn as a segment: its name beside it, on either side
        across = np.array([-label.along[1], label.along[0]]) / max(np.hypot(*label.along), 1e-300)
        directions = np.vstack([across, -across, directions])
    directions /= np.hypot(*directions.T)[:, None]
    offsets = [np.zeros((1, 2))] if label.kind == "body" and label.along is None else []  # inside a polygon
    for distance in LABEL_DISTANCES:
        offsets.append(directions * (clearance + distance * points_to_pixels))
    offsets = np.vstack(offsets)
    # the box touches the candidate point on the side facing the anchor
    shift_x = np.where(offsets[:, 0] > 1e-9, 0.0, np.where(offsets[:, 0] < -1e-9, -width, -width / 2))
    shift_y = np.where(offsets[:, 1] > 1e-9, 0.0, np.where(offsets[:, 1] < -1e-9, -height, -height / 2))
    x0 = anchor[0] + offsets[:, 0] + shift_x
    y0 = anchor[1] + offsets[:, 1] + shift_y
    return np.column_stack([x0, y0, x0 + width, y0 + height]), offsets


def _overlaps(candidates: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Number of `boxes` each candidate box overlaps (touching edges do not count)."""
    if not len(boxes):
        return np.zeros(len(candidates))
    c, b = candidates[:, None, :], boxes[None, :, :]
    overlap = (c[..., 0] < b[..., 2]) & (b[..., 0] < c[..., 2]) & (c[..., 1] < b[..., 3]) & (b[..., 1] < c[..., 3])
    return overlap.sum(axis=1)


def _segments_crossing(boxes: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Number of segments ``(x0, y0, x1, y1)`` that meet each box (Liang–Barsky clipping)."""
    if not len(segments):
        return np.zeros(len(boxes))
    start, delta = segments[None, :, :2], segments[None, :, 2:] - segments[None, :, :2]
    low, high = boxes[:, None, :2], boxes[:, None, 2:]
    shape = (len(boxes), len(segments))
    enter, leave, meets = np.zeros(shape), np.ones(shape), np.ones(shape, dtype=bool)
    for axis in (0, 1):
        d = delta[..., axis]
        parallel = np.abs(d) < 1e-12
        meets &= ~parallel | ((start[..., axis] >= low[..., axis]) & (start[..., axis] <= high[..., axis]))
        with np.errstate(divide="ignore", invalid="ignore"):
            t_low = (low[..., axis] - start[..., axis]) / d
            t_high = (high[..., axis] - start[..., axis]) / d
        first, second = np.minimum(t_low, t_high), np.maximum(t_low, t_high)
        enter = np.where(parallel, enter, np.maximum(enter, first))
        leave = np.where(parallel, leave, np.minimum(leave, second))
    return (meets & (enter <= leave)).sum(axis=1)


def _discs_touching(boxes: np.ndarray, discs: np.ndarray, exclude) -> np.ndarray:
    """Number of discs ``(x, y, radius)`` each box touches, leaving out a disc at `exclude`."""
    if not len(discs):
        return np.zeros(len(boxes))
    discs = discs[np.hypot(*(discs[:, :2] - exclude).T) > 0.5]
    nearest = np.clip(discs[None, :, :2], boxes[:, None, :2], boxes[:, None, 2:])
    return (np.hypot(*(nearest - discs[None, :, :2]).transpose(2, 0, 1)) < discs[None, :, 2]).sum(axis=1)
