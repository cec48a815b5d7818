"""Reusable, parameterized stage predicates: each factory returns a named :class:`Predicate`.

>>> sub_goal = on_top_of("small", "large") & released("small") & at_rest("small")
>>> sub_goal                                   # doctest: +ELLIPSIS
(on_top_of('small', 'large', ...) & released('small') & at_rest('small', ...))

Geometry comes from the scene: each object's axis-aligned box in its own frame (``local_bounds``)
is placed at the object's current pose. Heights are world z; the table top is
:data:`~bicoord_drake.models.scene.TABLE_TOP`. Combine predicates with ``&``, ``|``, ``~``,
:func:`all_of`, :func:`any_of`, :func:`count_true` and :func:`fraction_true` (partial credit).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.objects import (
    BinShape,
    BowlShape,
    BoxShape,
    CylinderShape,
    PotShape,
    Shape,
    SphereShape,
)
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.models.tools import DustpanCavity
from bicoord_drake.stages.stage import WorldState

#: A gripper commanded at or above this opening counts as open, below it as closed.
OPEN_AT = 0.5
_AXES = {"x": 0, "y": 1, "z": 2}


class Predicate:
    """A named function of a :class:`WorldState` returning a bool (or a fraction in [0, 1]).

    `children`: the predicates it combines; :meth:`reset` reaches every stateful one among them
    (a predicate with memory, like :func:`held_for`, overrides :meth:`reset`).
    """

    __slots__ = ("children", "fn", "name")

    def __init__(
        self,
        fn: Callable[[WorldState], bool | float],
        name: str,
        children: Sequence[Callable] = (),
    ) -> None:
        self.fn = fn
        self.name = name
        self.children = tuple(children)

    def reset(self) -> None:
        """Forget everything seen (the start of an episode): resets every stateful child."""
        for child in self.children:
            reset_predicate(child)

    def __call__(self, state: WorldState) -> bool | float:
        value = self.fn(state)
        return bool(value) if isinstance(value, bool | np.bool_) else float(value)

    def __and__(self, other: Callable) -> Predicate:
        return all_of(self, other)

    def __or__(self, other: Callable) -> Predicate:
        return any_of(self, other)

    def __invert__(self) -> Predicate:
        return not_(self)

    def __repr__(self) -> str:
        return self.name


def reset_predicate(pred: Callable) -> None:
    """Reset a predicate's memory (and its children's) if it has any; plain functions have
    none."""
    reset = getattr(pred, "reset", None)
    if callable(reset):
        reset()


def _name(p: Callable) -> str:
    return getattr(p, "name", getattr(p, "__name__", repr(p)))


# --------------------------------------------------------------------------- geometry
def local_bounds(shape: Shape) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) corners of the shape's axis-aligned box in the object frame (read-only)."""
    return _local_bounds(shape)


@lru_cache(maxsize=256)
def _local_bounds(shape: Shape) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = _bounds(shape)
    lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
    lo.setflags(write=False)
    hi.setflags(write=False)
    return lo, hi


def _bounds(shape: Shape) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(shape, BoxShape):
        half = np.asarray(shape.size) / 2
        return -half, half
    if isinstance(shape, CylinderShape):
        half = np.array([shape.radius, shape.radius, shape.length / 2])
        return -half, half
    if isinstance(shape, SphereShape):
        return -np.full(3, shape.radius), np.full(3, shape.radius)
    if isinstance(shape, BowlShape):
        return np.array([-shape.radius, -shape.radius, 0.0]), np.array(
            [shape.radius, shape.radius, shape.height]
        )
    points = np.concatenate([p.trimesh().bounds for p in shape.primitives()])
    return points.min(axis=0), points.max(axis=0)


def world_corners(state: WorldState, name: str) -> np.ndarray:
    """(8, 3) corners of the object's local box, in world."""
    lo, hi = local_bounds(state.shape(name))
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    return corners @ state.rotation(name).T + state.position(name)


@lru_cache(maxsize=256)
def _hull_points(shape: Shape) -> np.ndarray:
    """Vertices of the convex hull of the shape's primitives (its real extent: a tilted
    compound's bounding-box corners can lie in empty space)."""
    import trimesh

    points = np.concatenate([p.trimesh().vertices for p in shape.primitives()])
    hull = trimesh.convex.convex_hull(points).vertices
    out = np.array(hull, dtype=float)
    out.setflags(write=False)
    return out


def world_hull_points(state: WorldState, name: str) -> np.ndarray:
    """(N, 3) points of the object's real solid (its primitives' convex hull), in world: the
    lowest of them is the object's lowest point however it is turned."""
    return _hull_points(state.shape(name)) @ state.rotation(name).T + state.position(name)


def bottom_z(state: WorldState, name: str) -> float:
    """Lowest world height of the object's box."""
    return float(world_corners(state, name)[:, 2].min())


def top_z(state: WorldState, name: str) -> float:
    """Highest world height of the object's box."""
    return float(world_corners(state, name)[:, 2].max())


def lowest_z(state: WorldState, name: str) -> float:
    """Lowest world height of the object itself: exact for a cylinder at any roll about its
    axis and for a sphere (their boxes' corners reach lower), the box's corners otherwise."""
    shape = state.shape(name)
    if isinstance(shape, CylinderShape):
        a_z = min(abs(float(state.rotation(name)[2, 2])), 1.0)
        drop = shape.length / 2 * a_z + shape.radius * math.sqrt(1.0 - a_z * a_z)
        return float(state.position(name)[2] - drop)
    if isinstance(shape, SphereShape):
        return float(state.position(name)[2] - shape.radius)
    return bottom_z(state, name)


def centre(state: WorldState, name: str) -> np.ndarray:
    """World position of the centre of the object's box."""
    lo, hi = local_bounds(state.shape(name))
    return state.rotation(name) @ ((lo + hi) / 2) + state.position(name)


def tilt(state: WorldState, name: str, axis: str = "z") -> float:
    """Angle (rad) between the object's `axis` and world +z."""
    a = state.rotation(name)[:, _AXES[axis]]
    return float(math.acos(np.clip(a[2], -1.0, 1.0)))


def xy_distance(state: WorldState, name: str, target_xy: Sequence[float]) -> float:
    return float(np.linalg.norm(centre(state, name)[:2] - np.asarray(target_xy, dtype=float)))


# --------------------------------------------------------------------------- predicates
def lifted(obj: str, height: float = 0.03, reference: str = "initial") -> Predicate:
    """`obj` raised by at least `height`: its frame above its initial height (``"initial"``), or
    its bottom above the table top (``"table"``)."""
    if reference not in ("initial", "table"):
        raise ValueError("reference must be 'initial' or 'table'")

    def check(s: WorldState) -> bool:
        if reference == "table":
            return bottom_z(s, obj) >= TABLE_TOP + height
        return s.position(obj)[2] - s.initial_pose(obj)[2] >= height

    return Predicate(check, f"lifted({obj!r}, height={height}, reference={reference!r})")


def on_top_of(a: str, b: str, xy_tol: float = 0.02, z_tol: float = 0.01) -> Predicate:
    """`a` rests on `b`: centres within `xy_tol` in xy, a's bottom within `z_tol` of b's top."""

    def check(s: WorldState) -> bool:
        near = np.linalg.norm(centre(s, a)[:2] - centre(s, b)[:2]) <= xy_tol
        return bool(near and abs(bottom_z(s, a) - top_z(s, b)) <= z_tol)

    return Predicate(check, f"on_top_of({a!r}, {b!r}, xy_tol={xy_tol}, z_tol={z_tol})")


def rests_on(a: str, b: str, xy_tol: float = 0.02, z_tol: float = 0.006) -> Predicate:
    """`a` lies on `b`: centres within `xy_tol` in xy, a's lowest point (:func:`lowest_z`: a
    lying roller's surface, not its box) within `z_tol` of b's top."""

    def check(s: WorldState) -> bool:
        near = np.linalg.norm(centre(s, a)[:2] - centre(s, b)[:2]) <= xy_tol
        return bool(near and abs(lowest_z(s, a) - top_z(s, b)) <= z_tol)

    return Predicate(check, f"rests_on({a!r}, {b!r}, xy_tol={xy_tol}, z_tol={z_tol})")


def spans(beam: str, supports: Sequence[str], z_tol: float = 0.006) -> Predicate:
    """`beam` lies across every one of `supports` (a bridge on its piers): each support's top
    face centre is under the beam's footprint (within its length and width, in the beam's
    frame) and the beam's lowest point is within `z_tol` of each support's top. A beam with one
    end on the table, beside a support or hovering over it does not span it."""
    supports = tuple(supports)
    if not supports:
        raise ValueError("spans needs at least one support")

    def check(s: WorldState) -> bool:
        lo, hi = local_bounds(s.shape(beam))
        R, p = s.rotation(beam), s.position(beam)
        bottom = lowest_z(s, beam)
        for b in supports:
            top = top_z(s, b)
            if abs(bottom - top) > z_tol:
                return False
            c = centre(s, b)
            local = R.T @ (np.array([c[0], c[1], top]) - p)
            horizontal = [i for i in range(3) if abs(R[2, i]) < math.sqrt(0.5)]
            if not all(lo[i] <= local[i] <= hi[i] for i in horizontal):
                return False
        return True

    names = ", ".join(map(repr, supports))
    return Predicate(check, f"spans({beam!r}, [{names}], z_tol={z_tol})")


def above(a: str, b: str, xy_tol: float = 0.04, min_dz: float = 0.02) -> Predicate:
    """`a` over `b` (e.g. a nested bowl): frames within `xy_tol` in xy, a at least `min_dz`
    higher."""

    def check(s: WorldState) -> bool:
        d = s.position(a) - s.position(b)
        return bool(np.linalg.norm(d[:2]) <= xy_tol and d[2] >= min_dz)

    return Predicate(check, f"above({a!r}, {b!r}, xy_tol={xy_tol}, min_dz={min_dz})")


def on_table(obj: str, z_tol: float = 0.01, support_z: float = TABLE_TOP) -> Predicate:
    """`obj`'s bottom within `z_tol` of the support height (default: the table top)."""
    return Predicate(
        lambda s: abs(bottom_z(s, obj) - support_z) <= z_tol, f"on_table({obj!r}, z_tol={z_tol})"
    )


@dataclass(frozen=True)
class Cavity:
    """The open inside of a container, in its own frame (z up through the opening).

    ``kind="round"``: a solid of revolution about the frame's z axis whose inner wall runs from
    `floor_radius` at the inner floor to `rim_radius` at the rim. ``kind="box"``: an inner box of
    half-extents `half_xy` (x, y). `floor` and `rim` are heights in the container frame.
    """

    kind: Literal["round", "box"]
    floor: float
    rim: float
    floor_radius: float = 0.0
    rim_radius: float = 0.0
    half_xy: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if self.kind not in ("round", "box"):
            raise ValueError(f"cavity kind must be 'round' or 'box', got {self.kind!r}")
        if not self.rim > self.floor:
            raise ValueError(f"cavity rim {self.rim} must be above its floor {self.floor}")
        size = (self.floor_radius, self.rim_radius) if self.kind == "round" else self.half_xy
        if min(size) <= 0:
            raise ValueError(f"a {self.kind} cavity needs positive inner sizes, got {size}")

    def contains_xy(self, p: np.ndarray, margin: float = 0.0) -> bool:
        """Is the container-frame point `p` within the inner wall (shrunk by `margin`)?"""
        if self.kind == "box":
            return bool(np.all(np.abs(p[:2]) <= np.asarray(self.half_xy) - margin))
        f = float(np.clip((p[2] - self.floor) / (self.rim - self.floor), 0.0, 1.0))
        radius = self.floor_radius + f * (self.rim_radius - self.floor_radius)
        return bool(np.hypot(p[0], p[1]) <= radius - margin)


def cavity_of(shape: Shape) -> Cavity:
    """The cavity of a container shape: a :class:`BowlShape`'s or a :class:`PotShape`'s inner
    wall, floor and rim; a :class:`BinShape`'s inner box above its floor. Other shapes
    (compounds, boxes) are containers only with an explicit :class:`Cavity`."""
    if isinstance(shape, BinShape):
        return Cavity(
            kind="box", floor=shape.floor_thickness, rim=shape.size[2], half_xy=shape.inner_half
        )
    if isinstance(shape, PotShape):
        inner = shape.radius - shape.wall
        return Cavity(
            kind="round", floor=shape.wall, rim=shape.height, floor_radius=inner, rim_radius=inner
        )
    if isinstance(shape, BowlShape):
        return Cavity(
            kind="round",
            floor=shape.wall,
            rim=shape.height,
            floor_radius=shape.base_radius - shape.wall,
            rim_radius=shape.radius - shape.wall,
        )
    raise ValueError(
        f"a {shape.kind} shape has no known inside: pass cavity=Cavity(...) to inside()"
    )


def inside(
    obj: str,
    container: str,
    margin: float = 0.0,
    z_above: float = 0.0,
    *,
    cavity: Cavity | None = None,
    max_tilt: float = math.radians(45),
    floor_tol: float = 0.005,
) -> Predicate:
    """`obj` in `container`: judged in the container's frame against its real inside
    (:class:`Cavity`, default :func:`cavity_of` its shape).

    Holds when the container stands within `max_tilt` (rad) of upright (an upside-down or
    tipped container holds nothing), the object's centre lies within the inner wall shrunk by
    `margin` at its height and no higher than the rim + `z_above` (the stated allowance: e.g.
    a second object lying on the first), and the object's lowest point (of its real solid,
    :func:`world_hull_points`, not of its bounding box, whose corners a tilted compound swings
    through empty space) is no more than `floor_tol` below the inner floor (resting in it, not
    under it or on the table beside it).
    """

    def check(s: WorldState) -> bool:
        cav = cavity if cavity is not None else cavity_of(s.shape(container))
        if tilt(s, container) > max_tilt:
            return False
        R_WC, p_WC = s.rotation(container), s.position(container)
        p = R_WC.T @ (centre(s, obj) - p_WC)
        lowest = float(((world_hull_points(s, obj) - p_WC) @ R_WC)[:, 2].min())
        return bool(
            cav.contains_xy(p, margin)
            and p[2] <= cav.rim + z_above
            and lowest >= cav.floor - floor_tol
        )

    return Predicate(check, f"inside({obj!r}, {container!r}, margin={margin}, z_above={z_above})")


def stands_in(
    obj: str,
    container: str,
    gap: float = 0.008,
    max_tilt: float = math.radians(10),
    *,
    cavity: Cavity | None = None,
) -> Predicate:
    """`obj` stands upright on the floor of `container` (a cup on a plate): :func:`inside` it,
    its bottom at most `gap` above the container's inner floor, and both within `max_tilt` of
    upright."""

    def check(s: WorldState) -> bool:
        cav = cavity if cavity is not None else cavity_of(s.shape(container))
        if tilt(s, obj) > max_tilt or tilt(s, container) > max_tilt:
            return False
        R_WC, p_WC = s.rotation(container), s.position(container)
        lowest = float(((world_corners(s, obj) - p_WC) @ R_WC)[:, 2].min())
        return bool(lowest <= cav.floor + gap and contained(s))

    contained = inside(obj, container, z_above=math.inf, cavity=cavity, max_tilt=max_tilt)
    return Predicate(check, f"stands_in({obj!r}, {container!r}, gap={gap})")


def released(obj: str, open_at: float = OPEN_AT, tools: Sequence[str] = ()) -> Predicate:
    """Both grippers commanded open (opening >= `open_at`) and no robot body (finger, palm,
    wrist, link) touching `obj`. A task whose arm keeps a tool in hand to the end names it in
    `tools`: a gripper closed on one of them (its fingers touching it) counts as having let go
    of `obj` - it still may not touch `obj`."""
    tools = tuple(tools)

    def let_go(s: WorldState, side: str) -> bool:
        if s.opening(side) >= open_at:
            return True
        return any(side in s.fingers_touching(tool) for tool in tools)

    def check(s: WorldState) -> bool:
        return all(let_go(s, side) for side in SIDES) and not s.touching(obj)

    label = f"released({obj!r})" if not tools else f"released({obj!r}, tools={list(tools)})"
    return Predicate(check, label)


def held_by(obj: str, side: str = "any", closed_below: float = OPEN_AT) -> Predicate:
    """`obj` touched by the fingers of a closed gripper (a palm or a wrist against it is not a
    hold): `side` is 'left', 'right', 'both' or 'any'."""
    if side not in (*SIDES, "both", "any"):
        raise ValueError("side must be 'left', 'right', 'both' or 'any'")
    sides = {"left": ("left",), "right": ("right",), "both": SIDES}

    def holds(s: WorldState, arm: str) -> bool:
        return arm in s.fingers_touching(obj) and s.opening(arm) < closed_below

    def check(s: WorldState) -> bool:
        if side == "any":
            return holds(s, "left") or holds(s, "right")
        return all(holds(s, arm) for arm in sides[side])

    return Predicate(check, f"held_by({obj!r}, {side!r})")


def untouched(obj: str) -> Predicate:
    """No body of either arm (finger, palm, wrist, link) touches `obj`, whatever the grippers
    are commanded to do: one arm has let go of a placement while the other still holds
    something."""
    return Predicate(lambda s: not s.touching(obj), f"untouched({obj!r})")


def not_touched_by(obj: str, side: str) -> Predicate:
    """No body of the `side` arm ('left' or 'right': its fingers, palm, wrist or links)
    touches `obj`, whatever the other arm does: the arm that handed an object over has let go
    of it, or the arm that set one down has left it."""
    if side not in SIDES:
        raise ValueError(f"side must be one of {SIDES}, got {side!r}")
    return Predicate(lambda s: side not in s.touching(obj), f"not_touched_by({obj!r}, {side!r})")


def stacked(
    objects: Sequence[str],
    xy_tol: float = 0.02,
    z_tol: float = 0.01,
    max_tilt: float = math.radians(15),
    support_z: float = TABLE_TOP,
) -> Predicate:
    """A tower of blocks, bottom first: the first of `objects` on the support
    (:func:`on_table`), each next one resting on the one below it (:func:`on_top_of`), every
    one lying on a face (some axis within `max_tilt` of vertical). A toppled, leaning or
    shifted block, or one left beside the tower, breaks it."""
    objects = tuple(objects)
    if len(objects) < 2:
        raise ValueError(f"stacked needs at least two objects, got {list(objects)}")
    parts = [on_table(objects[0], z_tol, support_z)] + [
        on_top_of(a, b, xy_tol, z_tol) for b, a in zip(objects[:-1], objects[1:], strict=False)
    ]

    def on_a_face(s: WorldState, name: str) -> bool:
        tilts = [tilt(s, name, axis) for axis in _AXES]
        return min(min(t, math.pi - t) for t in tilts) <= max_tilt

    return Predicate(
        lambda s: all(on_a_face(s, o) for o in objects) and all(p(s) for p in parts),
        f"stacked({', '.join(map(repr, objects))}, xy_tol={xy_tol}, z_tol={z_tol})",
    )


def upright(obj: str, max_tilt: float = math.radians(15), axis: str = "z") -> Predicate:
    """The right way up: the object's `axis` within `max_tilt` (rad) of world +z. A pot, bowl,
    cup or plate rim-down, or a microphone head-down, is not upright; for shapes that are the
    same either way up (a cube, a pier) use :func:`vertical`."""

    def check(s: WorldState) -> bool:
        return tilt(s, obj, axis) <= max_tilt

    return Predicate(check, f"upright({obj!r}, max_tilt={max_tilt:.3g}, axis={axis!r})")


def vertical(obj: str, max_tilt: float = math.radians(15), axis: str = "z") -> Predicate:
    """The object's `axis` within `max_tilt` (rad) of vertical, either way up: for shapes
    symmetric under a flip (a cube, a pier, a long block stood on either end)."""

    def check(s: WorldState) -> bool:
        t = tilt(s, obj, axis)
        return min(t, math.pi - t) <= max_tilt

    return Predicate(check, f"vertical({obj!r}, max_tilt={max_tilt:.3g}, axis={axis!r})")


def level(obj: str, axis: str = "x", max_tilt: float = math.radians(15)) -> Predicate:
    """The object's `axis` within `max_tilt` (rad) of horizontal (e.g. a roller held level)."""
    return Predicate(
        lambda s: abs(math.pi / 2 - tilt(s, obj, axis)) <= max_tilt,
        f"level({obj!r}, axis={axis!r}, max_tilt={max_tilt:.3g})",
    )


def at_rest(obj: str, linear_tol: float = 0.01, angular_tol: float = 0.1) -> Predicate:
    """Speed below `linear_tol` (m/s) and angular speed below `angular_tol` (rad/s), from the
    velocities in the world state (see :class:`WorldState`)."""

    def check(s: WorldState) -> bool:
        v = s.velocity(obj)
        return bool(np.linalg.norm(v[:3]) <= linear_tol and np.linalg.norm(v[3:]) <= angular_tol)

    return Predicate(check, f"at_rest({obj!r}, linear_tol={linear_tol}, angular_tol={angular_tol})")


class HeldFor(Predicate):
    """Stateful: `pred` has held in full, without a break, for at least `seconds` of world time
    (see :func:`held_for`)."""

    __slots__ = ("_last", "_since", "pred", "seconds")

    def __init__(self, pred: Callable, seconds: float) -> None:
        if seconds < 0:
            raise ValueError(f"seconds must be >= 0, got {seconds}")
        super().__init__(self._check, f"held_for({_name(pred)}, {seconds:g} s)", (pred,))
        self.pred, self.seconds = pred, float(seconds)
        self.reset()

    def reset(self) -> None:
        super().reset()
        self._since: float | None = None
        self._last = -math.inf

    def _check(self, s: WorldState) -> bool:
        if s.time < self._last:
            raise ValueError(
                f"{self.name}: time went back from {self._last} to {s.time} without a reset "
                "(StageMonitor.reset() starts a new episode)"
            )
        self._last = s.time
        if float(self.pred(s)) < 1.0:
            self._since = None
            return False
        if self._since is None:
            self._since = s.time
        return s.time - self._since >= self.seconds - 1e-9


def held_for(pred: Callable, seconds: float) -> HeldFor:
    """`pred` held in full at every update for the last `seconds` (world time), e.g. objects
    at rest for 0.3 s, or a placement still there 1 s later. Stateful: its memory is cleared by
    :meth:`~bicoord_drake.stages.monitor.StageMonitor.reset` at the start of every episode."""
    return HeldFor(pred, seconds)


#: How long placed objects must stay at rest before a placement counts (s).
SETTLED_FOR = 0.3


def hands_free(objects: Sequence[str], open_at: float = OPEN_AT) -> Predicate:
    """Both grippers commanded open and no robot body touching any of `objects`."""
    objects = tuple(objects)

    def check(s: WorldState) -> bool:
        opened = all(s.opening(side) >= open_at for side in SIDES)
        return opened and not any(s.touching(o) for o in objects)

    return Predicate(check, f"hands_free({', '.join(map(repr, objects))})")


def settled(
    objects: Sequence[str],
    seconds: float = SETTLED_FOR,
    linear_tol: float = 0.01,
    angular_tol: float = 0.1,
) -> HeldFor:
    """Every one of `objects` at rest (:func:`at_rest`), without a break, for `seconds`."""
    return held_for(all_of(*[at_rest(o, linear_tol, angular_tol) for o in objects]), seconds)


def spaced(a: str, b: str, distance: float, tol: float = 0.02) -> Predicate:
    """The xy distance between the centres of `a` and `b` within `tol` of `distance` (e.g.
    two piers set a beam's length apart)."""

    def check(s: WorldState) -> bool:
        d = float(np.linalg.norm(centre(s, a)[:2] - centre(s, b)[:2]))
        return abs(d - distance) <= tol

    return Predicate(check, f"spaced({a!r}, {b!r}, {distance:.3f}, tol={tol})")


def within_xy(obj: str, target_xy: Sequence[float], tol: float = 0.02) -> Predicate:
    """The object's centre within `tol` of a world (x, y)."""
    xy = tuple(float(v) for v in target_xy)
    return Predicate(lambda s: xy_distance(s, obj, xy) <= tol, f"within_xy({obj!r}, {xy}, {tol})")


def filled_cells(
    state: WorldState,
    objects: Sequence[str],
    cells_xy: Sequence[Sequence[float]],
    tol: float = 0.01,
    z_tol: float = 0.01,
    support_z: float = TABLE_TOP,
) -> int:
    """How many cells hold an object resting on the support with its centre within `tol`."""
    resting = [o for o in objects if abs(bottom_z(state, o) - support_z) <= z_tol]
    xy = np.array([centre(state, o)[:2] for o in resting]).reshape(-1, 2)
    cells = np.asarray(cells_xy, dtype=float).reshape(-1, 2)
    if not len(xy):
        return 0
    dist = np.linalg.norm(cells[:, None, :] - xy[None, :, :], axis=2)
    return int(np.sum(dist.min(axis=1) <= tol))


def cells_filled(
    objects: Sequence[str],
    cells_xy: Sequence[Sequence[float]],
    k: int,
    tol: float = 0.01,
    z_tol: float = 0.01,
    support_z: float = TABLE_TOP,
) -> Predicate:
    """At least `k` of the cells are filled (see :func:`filled_cells`)."""
    objects, cells = tuple(objects), tuple(tuple(c) for c in cells_xy)
    return Predicate(
        lambda s: filled_cells(s, objects, cells, tol, z_tol, support_z) >= k,
        f"cells_filled({k} of {len(cells)}, tol={tol})",
    )


# --------------------------------------------------------------------------- combinators
def all_of(*preds: Callable) -> Predicate:
    """True when every predicate holds in full."""
    return Predicate(
        lambda s: min([float(p(s)) for p in preds]) >= 1.0,
        "(" + " & ".join(_name(p) for p in preds) + ")",
        preds,
    )


def any_of(*preds: Callable) -> Predicate:
    """True when at least one predicate holds in full."""
    return Predicate(
        lambda s: max([float(p(s)) for p in preds]) >= 1.0,  # every one sees every state
        "(" + " | ".join(_name(p) for p in preds) + ")",
        preds,
    )


def not_(pred: Callable) -> Predicate:
    """True when the predicate does not hold in full."""
    return Predicate(lambda s: float(pred(s)) < 1.0, f"~{_name(pred)}", (pred,))


def count_true(preds: Sequence[Callable], k: int) -> Predicate:
    """True when at least `k` of the predicates hold."""
    preds = tuple(preds)
    return Predicate(
        lambda s: sum([float(p(s)) >= 1.0 for p in preds]) >= k,
        f"count_true({k} of [{', '.join(_name(p) for p in preds)}])",
        preds,
    )


def fraction_true(preds: Sequence[Callable]) -> Predicate:
    """Partial credit: the fraction of predicates that hold (the stage counts at 1)."""
    preds = tuple(preds)
    return Predicate(
        lambda s: sum([float(p(s)) >= 1.0 for p in preds]) / len(preds),
        f"fraction_true([{', '.join(_name(p) for p in preds)}])",
        preds,
    )


# --------------------------------------------------------------------------- footprints
def _hull_2d(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of (N, 2) points (monotone chain)."""
    pts = sorted({(float(x), float(y)) for x, y in points})
    if len(pts) < 3:
        return np.array(pts)

    def half(seq):
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 1e-12:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def footprint(state: WorldState, name: str) -> np.ndarray:
    """The object's footprint on the xy plane: the convex hull of its box corners seen from
    above, counter-clockwise (K, 2)."""
    return _hull_2d(world_corners(state, name)[:, :2])


def footprint_gap(a: np.ndarray, b: np.ndarray) -> float:
    """Separation (m) of two convex polygons along the best separating edge normal: positive
    when they are apart by that much, zero or negative when they overlap."""
    best = -math.inf
    for poly in (a, b):
        for p, q in zip(poly, np.roll(poly, -1, axis=0), strict=True):
            edge = q - p
            n = np.array([edge[1], -edge[0]]) / max(float(np.linalg.norm(edge)), 1e-12)
            pa, pb = a @ n, b @ n
            best = max(best, float(pb.min() - pa.max()), float(pa.min() - pb.max()))
    return best


def clear_of(obj: str, support: str, margin: float = 0.0) -> Predicate:
    """No part of `obj` is over `support`: their footprints seen from above (box corners,
    any orientation) are at least `margin` apart - e.g. a block pulled out from a platform.
    A block still partly over the platform, or lying on it, is not clear of it."""

    def check(s: WorldState) -> bool:
        return footprint_gap(footprint(s, obj), footprint(s, support)) >= margin

    return Predicate(check, f"clear_of({obj!r}, {support!r}, margin={margin})")


# ----------------------------------------------------------------- pushed out, lying on a face
def beyond(obj: str, bound: float, axis: str = "x", below: bool = True) -> Predicate:
    """The centre of `obj`'s box is past `bound` (m, world) along `axis`: below it (`below`)
    or above it (a cube pushed out of a tunnel's far end)."""
    i = _AXES[axis]

    def check(s: WorldState) -> bool:
        c = float(centre(s, obj)[i])
        return c < bound if below else c > bound

    side = "<" if below else ">"
    return Predicate(check, f"beyond({obj!r}, {axis} {side} {bound:g})")


def on_a_face(obj: str, max_tilt: float = math.radians(15)) -> Predicate:
    """One of the object's box axes within `max_tilt` of vertical: a box lies on a face
    (whichever), not tipped onto an edge or a corner."""

    def check(s: WorldState) -> bool:
        tilts = [tilt(s, obj, axis) for axis in _AXES]
        return min(min(t, math.pi - t) for t in tilts) <= max_tilt

    return Predicate(check, f"on_a_face({obj!r}, max_tilt={max_tilt:.3g})")


# --------------------------------------------------------------------------- pens (collect_pens)
def tip_in(
    obj: str,
    container: str,
    max_tilt: float,
    *,
    cavity: Cavity | None = None,
    floor_tol: float = 0.005,
    container_tilt: float = math.radians(45),
) -> Predicate:
    """`obj` (a shape with a ``tip_point()``, e.g. a pen) stands tip first in `container`:
    its tip lies inside the container's real cavity (:func:`cavity_of`) - within the inner
    wall, below the rim, no more than `floor_tol` below the inner floor - and its axis (tip to
    back, the object's z) is within `max_tilt` of upright (the most the container lets it
    lean, e.g. :func:`bicoord_drake.models.pens.max_lean`). A pen lying across the opening,
    upside down, beside the holder or with only its back end inside does not count."""

    def check(s: WorldState) -> bool:
        shape = s.shape(obj)
        if not hasattr(shape, "tip_point"):
            raise ValueError(f"{obj!r} is a {shape.kind}: it has no tip")
        cav = cavity if cavity is not None else cavity_of(s.shape(container))
        if tilt(s, container) > container_tilt or tilt(s, obj) > max_tilt:
            return False
        R_WC, p_WC = s.rotation(container), s.position(container)
        tip_W = s.rotation(obj) @ shape.tip_point() + s.position(obj)
        p = R_WC.T @ (tip_W - p_WC)
        return bool(cav.contains_xy(p) and cav.floor - floor_tol <= p[2] <= cav.rim)

    return Predicate(check, f"tip_in({obj!r}, {container!r}, max_tilt={max_tilt:.3g})")


# --------------------------------------------------------------------------- latches, places
class Latched(Predicate):
    """Stateful: `pred` has held in full at some update since the last reset (see
    :func:`latched`)."""

    __slots__ = ("_seen", "pred")

    def __init__(self, pred: Callable) -> None:
        super().__init__(self._check, f"latched({_name(pred)})", (pred,))
        self.pred = pred
        self.reset()

    def reset(self) -> None:
        super().reset()
        self._seen = False

    def _check(self, s: WorldState) -> bool:
        if float(self.pred(s)) >= 1.0:
            self._seen = True
        return self._seen


def latched(pred: Callable) -> Latched:
    """`pred` held in full at some update of this episode (a cube that has been lifted off a
    tower stays "taken" while it is carried down). Stateful: the monitor's reset clears it."""
    return Latched(pred)


def near_start(obj: str, tol: float = 0.01) -> Predicate:
    """The object's centre within `tol` (m, in 3-D) of where it started (a block left in its
    tower while the one above it is taken away)."""

    def check(s: WorldState) -> bool:
        return bool(np.linalg.norm(s.position(obj) - s.initial_pose(obj)[:3]) <= tol)

    return Predicate(check, f"near_start({obj!r}, tol={tol})")


def within_square(obj: str, center_xy: Sequence[float], half: float, yaw: float = 0.0) -> Predicate:
    """The object's centre inside the square of half side `half` (m) around `center_xy`, its
    sides turned by `yaw` (rad) from the world axes (a block on a marked square)."""
    c = np.array([float(v) for v in center_xy])
    R = np.array([[math.cos(yaw), math.sin(yaw)], [-math.sin(yaw), math.cos(yaw)]])

    def check(s: WorldState) -> bool:
        d = R @ (centre(s, obj)[:2] - c)
        return bool(np.max(np.abs(d)) <= half)

    return Predicate(check, f"within_square({obj!r}, {tuple(c.tolist())}, half={half})")


def weighted(preds: Sequence[Callable], weights: Sequence[float]) -> Predicate:
    """Partial credit with weights: the weighted share of predicates that hold in full (the
    stage counts at 1), e.g. 0.125 per block on its mark and 0.25 per finished tower."""
    preds, w = tuple(preds), np.asarray(weights, dtype=float)
    if len(preds) != len(w) or not len(w) or np.any(w <= 0):
        raise ValueError("weighted needs one positive weight per predicate")
    return Predicate(
        lambda s: float(np.dot([float(p(s)) >= 1.0 for p in preds], w) / w.sum()),
        f"weighted([{', '.join(_name(p) for p in preds)}], {w.tolist()})",
        preds,
    )


def slid_open(obj: str, distance: float) -> Predicate:
    """A sliding object (a drawer) is out at least `distance` (m) along its slide: its
    measured joint position (``WorldState.joint_position``), not its pose alone."""

    def check(s: WorldState) -> bool:
        return bool(s.joint_position(obj) >= distance)

    return Predicate(check, f"slid_open({obj!r}, {distance})")


def slid_closed(obj: str, tol: float) -> Predicate:
    """A sliding object (a drawer) is within `tol` (m) of closed (joint position 0)."""

    def check(s: WorldState) -> bool:
        return bool(s.joint_position(obj) <= tol)

    return Predicate(check, f"slid_closed({obj!r}, {tol})")


def stands_upright_at(
    obj: str,
    center_xy: Sequence[float],
    tol: float = 0.03,
    *,
    axis: str = "z",
    max_tilt: float = math.radians(15),
    z_tol: float = 0.01,
) -> Predicate:
    """`obj` stands on the table on an end: its `axis` (a long cuboid's length) within
    `max_tilt` of vertical (either end down), its lowest corner at the table top, its centre
    within `tol` (m, xy) of `center_xy`, no robot body touching it (the other gripper may hold
    something else) and
    at rest. A lying, toppled, leaning, hovering or still-held object, or one beside the
    point, does not count."""
    parts = (
        vertical(obj, max_tilt, axis),
        on_table(obj, z_tol),
        within_xy(obj, center_xy, tol),
        untouched(obj),
        at_rest(obj),
    )
    return Predicate(
        lambda s: all(float(p(s)) >= 1.0 for p in parts),
        f"stands_upright_at({obj!r}, {tuple(float(v) for v in center_xy)}, tol={tol})",
        parts,
    )


def in_pan(
    obj: str,
    pan: str,
    cavity: DustpanCavity,
    *,
    margin: float = 0.003,
    rest_gap: float = 0.008,
    max_tilt: float = math.radians(30),
) -> Predicate:
    """`obj` lies in a dustpan (:func:`~bicoord_drake.models.tools.dustpan_cavity`): judged in
    the pan's frame, the pan within `max_tilt` of level, every point of the object's real
    solid within the pan's walls and front edge (`margin` of slack) and below the side walls'
    top, and its lowest point on the floor (no more than `rest_gap` above it, and not below
    it): resting on the pan, not on the pedestal beside it, not hanging over the front edge,
    not held up in the air over the pan."""

    def check(s: WorldState) -> bool:
        if tilt(s, pan) > max_tilt:
            return False
        pts = (world_hull_points(s, obj) - s.position(pan)) @ s.rotation(pan)
        x0, x1 = cavity.x_range
        lowest = float(pts[:, 2].min())
        return bool(
            pts[:, 0].min() >= x0 - margin
            and pts[:, 0].max() <= x1 + margin
            and np.abs(pts[:, 1]).max() <= cavity.half_y + margin
            and cavity.floor - margin <= lowest <= cavity.floor + rest_gap
            and float(s.rotation(pan)[:, 2] @ (centre(s, obj) - s.position(pan))) <= cavity.rim
        )

    return Predicate(check, f"in_pan({obj!r}, {pan!r})")
