"""The canvas on which joints, drivers and loads draw themselves, as their kinds declare."""

from __future__ import annotations

import math

import numpy as np

from ..model.geometry import rotate, to_global
from ..model.mechanism import GROUND, Mechanism

#: Size of symbols (joints, ground marks, one-point bodies) relative to the model's extent.
SYMBOL_SCALE = 0.025
#: Length of the cylinder and of the rod of an actuator drawn from one-point bodies, as a
#: fraction of the actuator's drawn length: they overlap by 0.4 of it at the start and part
#: only when it extends by 40 %.
CYLINDER_FRACTION = 0.7


class Canvas:
    """What an element kind draws with: positions at one configuration, and symbols.

    Each kind of `sparsekin.model.elements` declares ``draw(self, canvas)`` in terms of these
    methods, so that it never touches matplotlib.  The canvas also records what is drawn
    where (`segments`, `discs`), for the labels to avoid, and which bodies the elements
    drew themselves (`drawn_bodies`: a cylinder and its rod, a slider block), which are
    then not drawn again from their points.

    Parameters
    ----------
    axes : matplotlib Axes
    mechanism : Mechanism
    coordinates : ndarray, shape (n_coordinates,)
        The configuration drawn.
    size : float
        Size of symbols, m.

    Attributes
    ----------
    size : float
    ground_marks : list of ndarray
        Where the hatched ground symbols are.
    segments : list of ndarray, shape (2, 2)
        Lines drawn, global.
    discs : list of (x, y, radius)
        Round symbols drawn, global.
    drawn_bodies : set of str
        Bodies drawn by an element.
    body_labels : dict
        Body name -> (label anchor, direction of the body's segment or None).
    """

    def __init__(self, axes, mechanism: Mechanism, coordinates: np.ndarray, size: float) -> None:
        self.axes, self.size = axes, size
        self._mechanism = mechanism
        self._drawn = mechanism.frames()
        self._now = np.asarray(coordinates, dtype=float).reshape(-1, 3)
        self.ground_marks: list[np.ndarray] = []
        self.segments: list[np.ndarray] = []
        self.discs: list[tuple[float, float, float]] = []
        self.drawn_bodies: set[str] = set()
        self.body_labels: dict[str, tuple[np.ndarray, np.ndarray | None]] = {}
        self._fixed = not axes.get_autoscale_on()

    # ------------------------------------------------------------------ where things are
    def point(self, body: str, reference) -> np.ndarray:
        """Where the point of `body` that starts at `reference` (a name or (x, y)) is now."""
        start = np.asarray(self._mechanism.position(reference), dtype=float)
        if body == GROUND:
            return start
        index = self._mechanism.body_index(body)
        local = self._mechanism.local_points(np.array([index]), start[None], self._drawn)
        return to_global(self._now[index : index + 1], local)[0]

    def drawn_point(self, reference) -> np.ndarray:
        """Where the point `reference` is in the model's drawing (the initial configuration)."""
        return np.asarray(self._mechanism.position(reference), dtype=float)

    def direction(self, body: str, vector) -> np.ndarray:
        """The unit vector fixed in `body` that was `vector` in the drawing, now."""
        vector = np.asarray(vector, dtype=float) / np.hypot(*vector)
        if body == GROUND:
            return vector
        index = self._mechanism.body_index(body)
        return rotate(vector, self._now[index, 2] - self._drawn[index, 2])

    def origin(self, body: str) -> np.ndarray:
        """The frame origin of `body` now."""
        return np.zeros(2) if body == GROUND else self._now[self._mechanism.body_index(body), :2].copy()

    def pivot(self, body: str, other: str) -> np.ndarray:
        """Where a revolute joins `body` to `other` now; the frame origin of `body` if none does."""
        for joint in self._mechanism.joints:
            if joint.type_name == "revolute" and set(joint.bodies) == {body, other}:
                return self.point(body, joint.at)
        return self.origin(body)

    def single_point(self, body: str) -> bool:
        """Whether `body` is a moving body that carries at most one named point (a cylinder,
        a rod, a slider block), which an element may draw."""
        if body == GROUND:
            return False
        return len(set(self._mechanism.bodies[self._mechanism.body_index(body)].points)) <= 1

    # ------------------------------------------------------------------ symbols
    def pin(self, position, grounded: bool) -> None:
        """A small circle; on the ground, also a hatched triangle below it."""
        from matplotlib.patches import Circle, Polygon

        x, y = position
        size = self.size
        if grounded:
            triangle = [(x, y), (x - 1.2 * size, y - 2.0 * size), (x + 1.2 * size, y - 2.0 * size)]
            self.add_patch(Polygon(triangle, closed=True, facecolor="lightgray", edgecolor="black",
                                        hatch="///", linewidth=1.0, zorder=3))  # fmt: skip
            self.ground_marks.append(np.array([x, y - 1.5 * size]))
            self.discs.append((x, y - 1.4 * size, 1.1 * size))
        self.add_patch(Circle((x, y), 0.6 * size, facecolor="white", edgecolor="black", linewidth=1.2, zorder=4))
        self.discs.append((x, y, 0.6 * size))

    def slide(self, guide: str, slider: str, start, end, direction=None, limits=None) -> None:
        """A translational joint: `slider` slides along a line fixed in `guide`.

        `start` is the reference of the point of `guide` the line goes through, `end` the
        point of `slider` on it; the line runs along `direction` (drawn, global) or, when
        it is None, from `start` to `end` as drawn.  The slider's point is then at
        ``start + stroke · direction``.  One-point bodies are drawn here, with lengths fixed
        in them: a one-point guide is a cylinder from `start` towards `end`, and a
        one-point slider on it the rod from `end` back into it.  On any other guide the
        line is dashed, over the stroke's `limits` when given, and the slider is a block
        (a square) at its point.
        """
        drawn_start, drawn_end = self.drawn_point(start), self.drawn_point(end)
        length = float(np.hypot(*(drawn_end - drawn_start)))
        along = self.direction(guide, direction if direction is not None else drawn_end - drawn_start)
        here, there = self.point(guide, start), self.point(slider, end)
        if self.single_point(guide):
            reach = CYLINDER_FRACTION * length if length > 0.0 else 6.0 * self.size
            centred = 0.5 if length == 0.0 else 0.0  # an `at`/`direction` joint: drawn about its point
            self.cylinder(guide, here - centred * reach * along, here + (1.0 - centred) * reach * along)
            if self.single_point(slider):
                self.rod(slider, there + centred * reach * along, there - (1.0 - centred) * reach * along)
            return
        if limits is not None:
            low, high = limits
        elif length > 0.0:
            low, high = -0.15 * length, 1.15 * length
        else:
            low, high = -6.0 * self.size, 6.0 * self.size
        self._dashed(here + low * along, here + high * along)
        if self.single_point(slider):
            self.block(slider, there, along)
        else:
            self._square(there, along, zorder=3.5)

    def slider(self, start, end) -> None:
        """A dashed line from `start` to `end` with a small square at its middle, turned with it."""
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        self._dashed(start, end)
        self._square((start + end) / 2, end - start, zorder=3.5)

    def cylinder(self, body: str, start, end) -> None:
        """`body` drawn as a thick grey bar from `start` to `end` (a hydraulic cylinder)."""
        self._body_segment(body, start, end, color="dimgray", linewidth=6.0)

    def rod(self, body: str, start, end) -> None:
        """`body` drawn as a thin dark bar from `start` to `end` (a piston rod)."""
        self._body_segment(body, start, end, color="#303030", linewidth=2.5)

    def bar(self, body: str, start, end) -> None:
        """`body` drawn as a black line from `start` to `end` (a two-point link)."""
        self._body_segment(body, start, end, color="black", linewidth=2.0, claim=False)

    def block(self, body: str, position, along) -> None:
        """`body` drawn as a slider block at `position`, turned along `along`."""
        self._square(position, along, zorder=3.5, scale=1.4)
        self.drawn_bodies.add(body)
        self.body_labels[body] = (np.asarray(position, dtype=float), None)

    def slot(self, centre, along, limits=None) -> None:
        """A slot: two parallel lines along `along` about `centre`, over `limits` (m) if given."""
        low, high = limits if limits is not None else (-6.0 * self.size, 6.0 * self.size)
        across = 0.8 * self.size * np.array([-along[1], along[0]])
        for side in (across, -across):
            ends = np.array([centre + low * along + side, centre + high * along + side])
            self.add_line(ends[:, 0], ends[:, 1], color="tab:green", linewidth=1.5, zorder=2)
            self.segments.append(ends)

    def weld(self, position) -> None:
        """A small filled square: two bodies welded together."""
        from matplotlib.patches import Rectangle

        self.add_patch(Rectangle(np.asarray(position) - 0.5 * self.size, self.size, self.size,
                                      facecolor="black", zorder=4))  # fmt: skip
        self.discs.append((*np.asarray(position, dtype=float), 0.7 * self.size))

    def circle(self, centre, radius: float) -> None:
        """A dash-dotted circle: a gear's or a pinion's pitch circle."""
        from matplotlib.patches import Circle

        self.add_patch(Circle(tuple(centre), radius, fill=False, edgecolor="tab:purple", linestyle="-.",
                                   linewidth=1.2, zorder=2))  # fmt: skip

    def line(self, start, end) -> None:
        """A dash-dotted line: a rack's pitch line."""
        self.add_line(*np.transpose([start, end]), linestyle="-.", color="tab:purple", linewidth=1.2, zorder=2)
        self.segments.append(np.array([start, end], dtype=float))

    def actuator(self, start, end, drawn_length: float | None = None) -> None:
        """A linear actuator between two points: a thick cylinder from `start`, a thin rod to `end`.

        With its `drawn_length` (the distance in the model's drawing), the cylinder and the
        rod keep their lengths as the actuator extends; without, the cylinder covers 55 %
        of the present length.
        """
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        length = float(np.hypot(*(end - start)))
        along = (end - start) / length if length > 0.0 else np.zeros(2)
        reach = CYLINDER_FRACTION * drawn_length if drawn_length else 0.55 * length
        self.add_line(*np.transpose([start, start + reach * along]), color="dimgray", linewidth=6.0,
                      solid_capstyle="butt", zorder=2)  # fmt: skip
        rod_start = end - reach * along if drawn_length else start
        self.add_line(*np.transpose([rod_start, end]), color="#303030", linewidth=2.5, zorder=2.5)
        self.segments.append(np.array([start, end]))

    def arrow(self, position, direction) -> None:
        """An arrow ending at `position` along `direction` (a force applied there); none for a
        zero direction."""
        from matplotlib.patches import FancyArrowPatch

        direction = np.asarray(direction, dtype=float)
        length = float(np.hypot(*direction))
        if length == 0.0:
            return
        head = np.asarray(position, dtype=float)
        tail = head - 5.0 * self.size * direction / length
        self.add_patch(FancyArrowPatch(tuple(tail), tuple(head), arrowstyle="-|>", mutation_scale=12, color="tab:red",
                                       linewidth=1.8, zorder=5))  # fmt: skip
        self.segments.append(np.array([tail, head]))

    def turn(self, centre) -> None:
        """A curved arrow about `centre`: a torque."""
        from matplotlib.patches import FancyArrowPatch

        x, y = centre
        radius = 2.0 * self.size
        self.add_patch(FancyArrowPatch((x + radius, y), (x, y + radius), connectionstyle="arc3,rad=0.5",
                                       arrowstyle="-|>", mutation_scale=12, color="tab:red", linewidth=1.5,
                                       zorder=5))  # fmt: skip
        self.discs.append((x, y, radius))

    def spring(self, start, end) -> None:
        """A zigzag between two points: a spring-damper."""
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        along = end - start
        length = float(np.hypot(*along))
        if length == 0.0:
            return
        across = 0.8 * self.size * np.array([-along[1], along[0]]) / length
        fractions = np.linspace(0.2, 0.8, 13)
        zigzag = start + fractions[:, None] * along + np.where(np.arange(13) % 2, 1.0, -1.0)[:, None] * across
        zigzag[[0, -1]] = start + fractions[[0, -1], None] * along
        line = np.vstack([start, zigzag, end])
        self.add_line(line[:, 0], line[:, 1], color="tab:brown", linewidth=1.2, zorder=2)
        self.segments.append(np.array([start, end]))

    def target(self, position) -> None:
        """A cross in a circle: a point whose path is prescribed."""
        from matplotlib.patches import Circle

        x, y = position
        size = self.size
        self.add_patch(Circle((x, y), 1.2 * size, fill=False, edgecolor="tab:red", linewidth=1.5, zorder=4))
        self.add_line([x - 1.6 * size, x + 1.6 * size], [y, y], color="tab:red", linewidth=1.0, zorder=4)
        self.add_line([x, x], [y - 1.6 * size, y + 1.6 * size], color="tab:red", linewidth=1.0, zorder=4)
        self.discs.append((x, y, 1.6 * size))

    # ------------------------------------------------------------------ matplotlib
    def add_patch(self, patch) -> None:
        """Add a matplotlib patch; on axes with fixed limits, without updating the data limits
        (a third of the time of an animation frame went there)."""
        if self._fixed:
            self.axes.add_artist(patch)
        else:
            self.axes.add_patch(patch)

    def add_line(self, xs, ys, **style) -> None:
        """Add a line through `xs`, `ys` with matplotlib `style` (``Line2D`` keywords)."""
        from matplotlib.lines import Line2D

        if self._fixed:
            self.axes.add_artist(Line2D(xs, ys, **style))
        else:
            self.axes.add_line(Line2D(xs, ys, **style))

    # ------------------------------------------------------------------ helpers
    def _body_segment(self, body: str, start, end, *, color: str, linewidth: float, claim: bool = True) -> None:
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        self.add_line(*np.transpose([start, end]), color=color, linewidth=linewidth, solid_capstyle="butt",
                       zorder=2.2 if linewidth > 3 else 2.4)  # fmt: skip
        self.segments.append(np.array([start, end]))
        if claim:
            self.drawn_bodies.add(body)
        self.body_labels[body] = ((start + end) / 2, end - start)

    def _dashed(self, start, end) -> None:
        self.add_line(*np.transpose([start, end]), linestyle="--", color="tab:green", linewidth=1.2, zorder=2)
        self.segments.append(np.array([start, end], dtype=float))

    def _square(self, centre, along, zorder: float, scale: float = 1.0) -> None:
        """A square turned along `along`; under the revolute circles, so a pin there stays visible."""
        from matplotlib.patches import Rectangle

        half = 0.9 * scale * self.size
        angle = math.degrees(math.atan2(along[1], along[0]))
        self.add_patch(Rectangle(np.asarray(centre) - half, 2 * half, 2 * half, angle=angle,
                                      rotation_point="center", facecolor="white", edgecolor="tab:green",
                                      linewidth=1.5, zorder=zorder))  # fmt: skip
        self.discs.append((*np.asarray(centre, dtype=float), 1.2 * half))
