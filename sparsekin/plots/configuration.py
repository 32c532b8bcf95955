"""One configuration of a mechanism: the bodies drawn from the points they carry, the
elements on a `~sparsekin.plots.canvas.Canvas`, the labels placed last.  The still drawing,
every frame of an animation and a single frame all draw through `draw_configuration`."""

from __future__ import annotations

import math

import numpy as np

from ..engine.pattern import build_point_map
from ..model.elements import Joint
from ..model.geometry import rotate
from ..model.mechanism import GROUND, Mechanism
from .canvas import SYMBOL_SCALE, Canvas
from .labels import Label, place_labels

#: What a drawing labels: every point and body, the points where joints are, or nothing.
LABEL_CHOICES = ("all", "joints", "none")


def draw_configuration(axes, mechanism: Mechanism, coordinates, *, size: float | None = None,
                       labels: bool | str = True, bodies=None) -> list:  # fmt: skip
    """Draw `mechanism` at `coordinates` on matplotlib `axes`: bodies, elements, labels.

    If the axes scale themselves (matplotlib's default), their limits are first set to
    fit the drawing at equal scales and then kept, so that the labels are placed in the
    final picture.  Axes with fixed limits (an animation's) keep them.

    Parameters
    ----------
    axes : matplotlib.axes.Axes
    mechanism : Mechanism
    coordinates : array_like, shape (3 * n_bodies,)
        ``(x, y, angle)`` of every body frame, as in `KinematicsResult.coordinates`.
    size : float, optional
        Size of the symbols, m (default: `SYMBOL_SCALE` times the extent of the points).
    labels : {"all", "joints", "none"} or bool
        Label every named point and every body (``"all"`` or True, the default), only the
        points where joints are (``"joints"``: the pins, not the markers and bodies of a
        crowded machine), or nothing (``"none"`` or False).
    bodies : sequence of str, optional
        Draw only these bodies, their points, and the joints and drivers between them
        and the ground: a part of a large mechanism (default: all).

    Returns
    -------
    list of matplotlib.artist.Artist
        Everything drawn, to be removed before the next frame of an animation.
    """
    labels = label_choice(labels)
    drawer = _Drawer(mechanism, bodies)
    coordinates = np.asarray(coordinates, dtype=float)
    if size is None:
        size = SYMBOL_SCALE * _extent(drawer.positions(coordinates[None])[0])
    return drawer.draw(axes, coordinates, size, labels=labels)


class _Drawer:
    """Draws one mechanism at any number of configurations, and remembers the label places
    of the last one (an animation keeps a label where it was while it fits there)."""

    def __init__(self, mechanism: Mechanism, bodies=None) -> None:
        self.mechanism = mechanism
        self.point_map = build_point_map(mechanism)
        names = list(self.point_map.names)
        point_body, point_local = self.point_map.arrays()
        elements = (*mechanism.joints, *mechanism.drivers, *mechanism.loads)
        if bodies is None:
            self.body_indices = list(range(mechanism.n_bodies))
            self.elements = elements
            shown = np.ones(len(names), dtype=bool)
        else:  # a part of the mechanism: these bodies, and the elements between them and the ground
            self.body_indices = [self._index(name) for name in bodies]
            allowed = {*bodies, GROUND}
            self.elements = [element for element in elements if _element_bodies(element) <= allowed]
            shown = np.isin(point_body, self.body_indices)
        self.names = [name for name, keep in zip(names, shown) if keep]
        self.point_body, self.point_local = point_body[shown], point_local[shown]
        self.kept_places: dict[tuple[str, str], int] = {}
        self.texts: dict | None = None  # label artists kept from frame to frame (animations)
        self._joint_points: set[str] | None = None

    @property
    def joint_points(self) -> set[str]:
        """The names of the points where the joints drawn are (their point fields)."""
        if self._joint_points is None:
            self._joint_points = {name for joint in self.elements if isinstance(joint, Joint)
                                  for field_name in type(joint).point_fields
                                  for name in _names(getattr(joint, field_name))}  # fmt: skip
        return self._joint_points

    def _index(self, name: str) -> int:
        try:
            index = self.mechanism.body_index(name)
        except KeyError:
            index = -1
        if index < 0:
            raise KeyError(f'unknown body "{name}" to draw (the ground is always drawn)')
        return index

    def origins(self, coordinates: np.ndarray) -> np.ndarray:
        """Frame origins of the bodies drawn, shape (n_configurations, n_drawn, 2)."""
        coordinates = np.asarray(coordinates, dtype=float)
        return coordinates.reshape(coordinates.shape[0], -1, 3)[:, self.body_indices, :2]

    def traced(self, names, coordinates: np.ndarray) -> np.ndarray:
        """Positions of the points `names` (any of the model), shape (n_configurations, len(names), 2)."""
        located = []
        for name in names:
            try:
                located.append(self.point_map.locate(name))
            except KeyError:
                raise KeyError(f'unknown point "{name}" to trace') from None
        body = np.array([b for b, _ in located], dtype=np.int64)
        local = np.array([p for _, p in located], dtype=float).reshape(-1, 2)
        return _point_positions(body, local, coordinates)

    def positions(self, coordinates: np.ndarray) -> np.ndarray:
        """Global positions of the named points, shape (n_configurations, n_points, 2)."""
        return _point_positions(self.point_body, self.point_local, coordinates)

    def draw(self, axes, coordinates: np.ndarray, size: float, labels: str = "all", extra_obstacles=()) -> list:
        before = set(axes.get_children())
        positions = dict(zip(self.names, self.positions(coordinates[None])[0]))
        canvas = Canvas(axes, self.mechanism, coordinates, size)
        for element in self.elements:
            element.draw(canvas)
        bodies = self.mechanism.bodies
        for index in self.body_indices:
            body = bodies[index]
            if body.name not in canvas.drawn_bodies:
                _draw_body(canvas, body, positions, coordinates[3 * index : 3 * index + 3])
        if labels != "none":
            if axes.get_autoscale_on():
                _fit_limits(axes)
            for segment in extra_obstacles:
                canvas.segments.append(segment)
            named = positions if labels == "all" else {n: p for n, p in positions.items() if n in self.joint_points}
            wanted = [Label(name, position, 0.6 * size, "point") for name, position in named.items()]
            if labels == "all":
                wanted += [Label(name, anchor, 0.0, "body", along)
                           for name, (anchor, along) in canvas.body_labels.items()]  # fmt: skip
            placed = place_labels(axes, wanted, canvas.segments, canvas.discs, kept=self.kept_places,
                                  texts=self.texts)  # fmt: skip
            self.kept_places = {(label.kind, label.text): choice for label, choice in placed}
        kept = set(self.texts.values()) if self.texts else set()
        return [artist for artist in axes.get_children() if artist not in before and artist not in kept]


def label_choice(labels: bool | str) -> str:
    """``"all"``, ``"joints"`` or ``"none"`` from a `labels` argument (True is "all", False "none")."""
    if labels is True or labels is False:
        return "all" if labels else "none"
    if labels not in LABEL_CHOICES:
        raise ValueError(f"`labels` must be one of {', '.join(map(repr, LABEL_CHOICES))} or a bool, got {labels!r}.")
    return labels


def _names(value) -> list[str]:
    """The point names in a point field's value (a name, (x, y), a list of either, None)."""
    if value is None or (not isinstance(value, str) and isinstance(value[0], float)):
        return []
    return [value] if isinstance(value, str) else [v for v in value if isinstance(v, str)]


def _element_bodies(element) -> set[str]:
    """The bodies a joint or driver names, from its kind's ``body_fields``."""
    names = set()
    for field_name in type(element).body_fields:
        value = getattr(element, field_name)
        names |= {value} if isinstance(value, str) else set(value)
    return names


def _fit_limits(axes) -> None:
    """Set the limits to the drawing with margins at equal scales, run the figure's layout
    once, and keep both: the labels are placed in the picture as it will be saved."""
    axes.set_aspect("equal", adjustable="datalim")
    axes.margins(0.08)
    axes.autoscale_view()
    figure = axes.get_figure()
    engine = figure.get_layout_engine()
    if engine is not None:
        engine.execute(figure)
        figure.set_layout_engine("none")
    _freeze_limits(axes)


def _freeze_limits(axes) -> None:
    """Keep the limits that equal scales give in the axes' present box."""
    axes.apply_aspect()
    axes.set_xlim(axes.get_xlim())
    axes.set_ylim(axes.get_ylim())
    axes.set_autoscale_on(False)
    axes.set_aspect("equal", adjustable="box")


def _point_positions(body: np.ndarray, local: np.ndarray, coordinates: np.ndarray) -> np.ndarray:
    """Global positions of points on `body` (-1: the ground) at `local` positions in its
    frame, at each configuration `coordinates` (n_configurations, 3 · n_bodies); shape
    (n_configurations, n_points, 2)."""
    coordinates = np.asarray(coordinates, dtype=float)
    frames = coordinates.reshape(coordinates.shape[0], -1, 3)
    positions = np.empty((coordinates.shape[0], len(body), 2))
    on_ground = body < 0
    positions[:, on_ground] = local[on_ground]
    if (~on_ground).any():
        carried = frames[:, body[~on_ground]]  # (n, k, 3)
        positions[:, ~on_ground] = carried[..., :2] + rotate(local[~on_ground], carried[..., 2])
    return positions


# ---------------------------------------------------------------------- bodies
def _draw_body(canvas: Canvas, body, positions, frame) -> None:
    """A body that no element drew: a polygon through its points, a segment, or a short bar
    from its one point along its frame's x axis (to the side with more room)."""
    from matplotlib.patches import Polygon

    corners = np.array([positions[name] for name in dict.fromkeys(body.points)]).reshape(-1, 2)
    if len(corners) >= 3:
        corners = _around_centroid(corners)
        canvas.add_patch(Polygon(corners, closed=True, facecolor="tab:orange", alpha=0.25, edgecolor="none"))
        canvas.add_patch(Polygon(corners, closed=True, fill=False, edgecolor="black", linewidth=1.5))
        canvas.segments.extend(np.stack([corners, np.roll(corners, -1, axis=0)], axis=1))
        canvas.body_labels[body.name] = (corners.mean(axis=0), None)
        return
    if len(corners) == 2:
        canvas.bar(body.name, corners[0], corners[1])
        return
    origin = corners[0] if len(corners) else frame[:2]
    obstacles = np.array([*positions.values(), *canvas.ground_marks]).reshape(-1, 2)
    along = _roomier_direction(origin, frame[2], 4.0 * canvas.size, obstacles)
    canvas.cylinder(body.name, origin, origin + 4.0 * canvas.size * along)


def _roomier_direction(origin, angle: float, length: float, obstacles: np.ndarray) -> np.ndarray:
    """Of ±(cos angle, sin angle), the one whose end at `length` is farther from `obstacles`."""
    along = np.array([math.cos(angle), math.sin(angle)])
    others = obstacles[np.hypot(*(obstacles - origin).T) > 1e-9 * length]

    def clearance(direction: np.ndarray) -> float:
        return float(np.min(np.hypot(*(others - (origin + length * direction)).T), initial=np.inf))

    return along if clearance(along) >= clearance(-along) else -along


def _around_centroid(corners: np.ndarray) -> np.ndarray:
    """The corners ordered by angle about their centroid: a polygon that does not cross itself."""
    relative = corners - corners.mean(axis=0)
    return corners[np.argsort(np.arctan2(relative[:, 1], relative[:, 0]))]


def _extent(positions) -> float:
    """Largest side of the bounding box of `positions` (1 m when they all coincide)."""
    array = np.array(list(positions), dtype=float).reshape(-1, 2)
    extent = float(np.ptp(array, axis=0).max()) if len(array) else 0.0
    return extent if extent > 0.0 else 1.0
