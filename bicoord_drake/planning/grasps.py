"""Grasp and place pose candidates per object shape (pure geometry, no plant needed).

A grasp is a pose of the gripper's ``tcp`` frame G in the world: x is the approach direction
(from the wrist out along the fingers), the fingers close along ±y, z = x × y. The TCP sits
midway between the finger pads at the pads' centre, so a grasp puts the TCP where the pads'
centre should be. Every :class:`Grasp` carries a pregrasp (the same orientation, retreated along
-x), the object width between the pads, its pose in the object frame (``X_OG``), and a score:
higher means more natural for an arm whose base is at ``base`` (the wrist roll that needs least
wrist rotation, a forward reach) and a preferred kind (top, rim and handle grasps over side).

Shapes:

- boxes: ``top`` (fingers across either horizontal side that fits the jaw) and ``side``
  (horizontal approach onto a face, fingers across the other horizontal side);
- cylinders: ``top`` and ``side`` around the axis when upright, ``top`` across the diameter when
  lying; spheres: ``top``;
- bowls: ``rim`` (vertical approach, fingers straddling the wall);
- handles (:func:`handle_grasps`): a bar given as a box or cylinder part pose, approached
  perpendicular to its long axis; pots (:func:`pot_handle_grasps`): each lug handle from
  outside, a horizontal approach toward the pot's axis, the pads pinching the handle's plate.

Place poses: :func:`place_pose` turns a target object pose and the grasp transform ``X_GO``
(object in gripper) into the TCP pose; :func:`table_target` / :func:`stack_target` build target
object poses resting on the table or on another object; :func:`place_candidates` tries the
shape's symmetric yaws and ranks the resulting TCP poses like grasps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix

from bicoord_drake.models.embodiment import Embodiment, GripperSpec, Side
from bicoord_drake.models.geometry import Primitive, transform_points
from bicoord_drake.models.objects import (
    BinShape,
    BowlShape,
    BoxShape,
    CompoundShape,
    CylinderShape,
    PotShape,
    SceneObject,
    SphereShape,
)
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.planning.errors import PlanningError

GraspKind = Literal["top", "side", "rim", "handle"]
Shape = BoxShape | CylinderShape | SphereShape | BowlShape

_UP = np.array([0.0, 0.0, 1.0])
#: Middle of the two ALOHA arm bases; the default reference for scoring.
DEFAULT_BASE = np.array([0.0, -0.42, TABLE_TOP])
#: Rim grasps with ``GraspParams.rim_floor``: the least height (m) of wall between the pads.
MIN_RIM_OVERLAP = 0.008

_PRIOR: dict[str, float] = {"top": 1.0, "rim": 1.0, "handle": 1.0, "side": 0.0}


@dataclass(frozen=True)
class GraspParams:
    """Knobs of the candidate generators (lengths in m)."""

    pregrasp_distance: float = 0.08  # retreat of the pregrasp along -approach
    margin: float = 0.008  # clearance per side between an open pad and the object
    tip_clearance: float = 0.005  # fingertips stay this far above the object's bottom
    side_clearance: float = 0.03  # side/handle grasps: TCP at least this high above support_z
    support_z: float = TABLE_TOP  # height of the surface the object rests on
    depth: float | None = None  # top grasps: TCP below the top face; None = pads flush with it
    rim_depth: float = 0.003  # rim grasps: pad top this far below the rim
    rim_lean: bool = False  # rim grasps: approach along a flared wall, pads flat on it
    #: rim grasps: if set, the fingertips also stay this far above the bowl's floor (the top
    #: of its base, `wall` up), the pads standing above the rim if need be (at least
    #: MIN_RIM_OVERLAP of wall between them)
    rim_floor: float | None = None
    n_yaw: int = 8  # samples around round shapes
    allow_from_below: bool = False  # keep approaches that point upward


@dataclass(frozen=True)
class Grasp:
    """One grasp candidate (see the module docstring for the frame convention)."""

    kind: GraspKind
    X_WG: RigidTransform
    X_WPre: RigidTransform
    X_OG: RigidTransform
    width: float  # object width between the pads, m
    score: float

    @property
    def approach(self) -> np.ndarray:
        return self.X_WG.rotation().col(0)

    @property
    def finger_axis(self) -> np.ndarray:
        return self.X_WG.rotation().col(1)

    @property
    def X_GO(self) -> RigidTransform:
        """The object (or handle part) in the gripper frame while held."""
        return self.X_OG.inverse()

    def opening(self, gripper: GripperSpec, margin: float = 0.008) -> float:
        """Opening command that clears the object by `margin` per side (clipped to [0, 1])."""
        half = self.width / 2 + margin
        return float(np.clip(gripper.opening(half), 0.0, 1.0))


@dataclass(frozen=True)
class Place:
    """A place candidate: object pose, TCP pose at release and the pose above it."""

    X_WO: RigidTransform
    X_WG: RigidTransform
    X_WPre: RigidTransform
    score: float


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------


def pose_to_transform(obj: SceneObject) -> RigidTransform:
    """A scene object's initial pose as a RigidTransform (same extrinsic roll-pitch-yaw)."""
    return RigidTransform(obj.pose.matrix())


def arm_base(embodiment: Embodiment, side: Side) -> np.ndarray:
    """World position of an arm's base (the scoring reference for that arm)."""
    return np.array(embodiment.base_pose(side).xyz, dtype=float)


def gripper_frame(approach: np.ndarray, finger_axis: np.ndarray, p: np.ndarray) -> RigidTransform:
    """The TCP pose with x = approach, y = finger axis (orthogonalized), at point p."""
    x = _unit(approach)
    y = _unit(finger_axis - (finger_axis @ x) * x)
    R = np.column_stack([x, y, np.cross(x, y)])
    return RigidTransform(RotationMatrix(R), np.asarray(p, dtype=float))


def turned_onto(R: RotationMatrix, u: np.ndarray, v: np.ndarray) -> RotationMatrix:
    """`R` turned by the smallest rotation that takes unit vector `u` onto unit vector `v`
    (`R` itself when they are parallel; antiparallel vectors have no unique smallest turn and
    are left unturned too)."""
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    axis = np.cross(u, v)
    s = float(np.linalg.norm(axis))
    if s < 1e-12:
        return R
    return RotationMatrix(AngleAxis(math.atan2(s, float(u @ v)), axis / s)) @ R


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v)
    if n < 1e-12:
        raise ValueError("zero-length direction")
    return v / n


def _perp_basis(n: np.ndarray, hint: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors u, w with (u, w, n) right-handed; u follows `hint` when possible."""
    u = hint - (hint @ n) * n
    if np.linalg.norm(u) < 1e-6:
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u = _unit(u)
    return u, np.cross(n, u)


def naturalness(X_WG: RigidTransform, base: np.ndarray | None = None) -> float:
    """How natural a TCP pose is for an arm based at `base` facing +y, in [-1.5, 1.5].

    The roll term (±1) compares the gripper z with the z an arm reaching from `base` has without
    turning its wrist (for a top-down grasp: pointing away from the base; for a forward approach:
    up). The reach term (±0.5) rewards approaching horizontally away from the base.
    """
    b = DEFAULT_BASE if base is None else np.asarray(base, dtype=float)
    R = X_WG.rotation().matrix()
    x, z = R[:, 0], R[:, 2]
    radial = X_WG.translation() - b
    radial[2] = 0.0
    r = radial / np.linalg.norm(radial) if np.linalg.norm(radial) > 1e-6 else np.array([0, 1, 0.0])
    z_nat = np.cross(np.cross(r, _UP), x)
    roll = float(z @ z_nat / np.linalg.norm(z_nat)) if np.linalg.norm(z_nat) > 1e-6 else 0.0
    return roll + 0.5 * float(x @ r)


def _make(
    kind: GraspKind,
    X_WO: RigidTransform,
    approach: np.ndarray,
    finger_axis: np.ndarray,
    p: np.ndarray,
    width: float,
    gripper: GripperSpec,
    params: GraspParams,
    base: np.ndarray | None,
) -> Grasp | None:
    """A candidate, or None if the jaw cannot hold `width` or the approach points up."""
    if width + 2 * params.margin > 2 * gripper.finger_max or width < 2 * gripper.finger_min:
        return None
    X_WG = gripper_frame(approach, finger_axis, p)
    x = X_WG.rotation().col(0)
    if not params.allow_from_below and x[2] > 0.25:
        return None
    X_WPre = RigidTransform(X_WG.rotation(), X_WG.translation() - params.pregrasp_distance * x)
    max_gap = 2 * gripper.finger_max
    score = _PRIOR[kind] + naturalness(X_WG, base) + 0.25 * (1 - width / max_gap)
    return Grasp(kind, X_WG, X_WPre, X_WO.inverse() @ X_WG, float(width), float(score))


def pitched(grasp: Grasp, X_WO: RigidTransform, angle: float) -> Grasp:
    """`grasp` (a horizontal approach) with its approach tilted `angle` (rad) down about its
    jaw axis through the TCP: the pads stay on the same faces, the wrist rises behind them.
    The pregrasp keeps its distance, along the new approach."""
    if angle == 0.0:
        return grasp
    R = grasp.X_WG.rotation()
    x = R.col(0)
    k = np.cross(_UP, x)
    if np.linalg.norm(k) < 1e-9:
        raise PlanningError("no_grasp", "a vertical approach has no pitch down")
    turn = RotationMatrix(AngleAxis(angle, k / np.linalg.norm(k)))
    return turned(grasp, X_WO, turn)


def turned(grasp: Grasp, X_WO: RigidTransform, turn: RotationMatrix) -> Grasp:
    """`grasp` turned by `turn` (a rotation in the world frame) about its TCP: the grip point
    stays, the pregrasp keeps its distance, along the new approach."""
    p = grasp.X_WG.translation()
    X_WG = RigidTransform(turn @ grasp.X_WG.rotation(), p)
    d = float(np.linalg.norm(p - grasp.X_WPre.translation()))
    X_WPre = RigidTransform(X_WG.rotation(), p - d * X_WG.rotation().col(0))
    return Grasp(grasp.kind, X_WG, X_WPre, X_WO.inverse() @ X_WG, grasp.width, grasp.score)


def slid(grasp: Grasp, X_WO: RigidTransform, offset: float) -> Grasp:
    """`grasp` moved `offset` (m) along its z axis (across both the approach and the jaw axis:
    along the object, between the same two faces), orientation and pregrasp distance kept.
    A wide hand whose housing meets a neighbour at the object's middle may find room nearer
    one end."""
    if offset == 0.0:
        return grasp
    shift = offset * grasp.X_WG.rotation().col(2)
    X_WG = RigidTransform(grasp.X_WG.rotation(), grasp.X_WG.translation() + shift)
    X_WPre = RigidTransform(grasp.X_WPre.rotation(), grasp.X_WPre.translation() + shift)
    return Grasp(grasp.kind, X_WG, X_WPre, X_WO.inverse() @ X_WG, grasp.width, grasp.score)


def slid_grasps(
    grasps: Sequence[Grasp],
    X_WO: RigidTransform,
    points_O: np.ndarray,
    slides: Sequence[float],
    keep: float,
) -> list[Grasp]:
    """`grasps` slid (:func:`slid`) by each of `slides` (m), smaller first, either way, where
    the object (`points_O`, (N, 3) points of it in its frame) still reaches `keep` (m, e.g.
    the pads' height) past the slid TCP at both ends along the slide."""
    pts_W = transform_points(X_WO, points_O)
    out = []
    for s in slides:
        for g in grasps:
            along = (pts_W - g.X_WG.translation()) @ g.X_WG.rotation().col(2)
            for offset in (s, -s):
                if along.min() + keep <= offset <= along.max() - keep:
                    out.append(slid(g, X_WO, offset))
    return out


def _top_depth(height: float, gripper: GripperSpec, params: GraspParams) -> float | None:
    """TCP depth below the top face for a top grasp, or None if the object is too flat."""
    half_pad = gripper.pad_length / 2
    if params.depth is not None:
        return params.depth
    deepest = height - half_pad - params.tip_clearance
    depth = min(half_pad, deepest)
    return depth if depth >= min(0.005, height / 2) else None


def _side_height(
    centre: np.ndarray, n_up: np.ndarray, half_up: float, gripper: GripperSpec, params: GraspParams
) -> np.ndarray | None:
    """TCP for a horizontal approach: at the centre, raised along the object's up axis until
    the gripper clears the support (pads stay on the object); None if impossible."""
    need = params.support_z + params.side_clearance - centre[2]
    if need <= 0:
        return centre
    if n_up[2] < 1e-3:
        return None
    shift = need / n_up[2]
    if shift > half_up - gripper.pad_height / 2:
        return None
    return centre + shift * n_up


def _rank(grasps: Sequence[Grasp | None]) -> list[Grasp]:
    return sorted((g for g in grasps if g is not None), key=lambda g: -g.score)


# --------------------------------------------------------------------------------------------
# Per-shape generators
# --------------------------------------------------------------------------------------------


def box_grasps(
    X_WO: RigidTransform,
    shape: BoxShape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    kinds: Sequence[GraspKind] = ("top", "side"),
    params: GraspParams = GraspParams(),
) -> list[Grasp]:
    """Top and side grasps of a box, best first. The face most aligned with world +z is the top."""
    R = X_WO.rotation().matrix()
    c = X_WO.translation()
    half = np.asarray(shape.size, dtype=float) / 2
    up = int(np.argmax(np.abs(R[2])))
    n = R[:, up] * np.sign(R[2, up])
    others = [i for i in range(3) if i != up]
    out: list[Grasp | None] = []
    if "top" in kinds:
        depth = _top_depth(2 * half[up], gripper, params)
        if depth is not None:
            p = c + n * (half[up] - depth)
            for f in others:
                for s in (1.0, -1.0):
                    out.append(
                        _make("top", X_WO, -n, s * R[:, f], p, 2 * half[f], gripper, params, base)
                    )
    if "side" in kinds:
        centre = _side_height(c, n, half[up], gripper, params)
        for i in others if centre is not None else []:
            j = others[0] if i == others[1] else others[1]
            depth = min(gripper.pad_length / 2, half[i])
            for si in (1.0, -1.0):
                p = centre + si * R[:, i] * (half[i] - depth)
                for sj in (1.0, -1.0):
                    f = sj * R[:, j]
                    out.append(
                        _make("side", X_WO, -si * R[:, i], f, p, 2 * half[j], gripper, params, base)
                    )
    return _rank(out)


def cylinder_grasps(
    X_WO: RigidTransform,
    shape: CylinderShape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    kinds: Sequence[GraspKind] = ("top", "side"),
    params: GraspParams = GraspParams(),
) -> list[Grasp]:
    """Grasps across a cylinder's diameter, best first.

    Upright (axis within 45° of vertical): ``top`` at `n_yaw` finger directions and ``side`` at
    `n_yaw` azimuths (fingers tangent, TCP on the axis). Lying: ``top`` from above at the middle,
    fingers horizontal across the diameter.
    """
    R = X_WO.rotation().matrix()
    c = X_WO.translation()
    axis = R[:, 2]
    r, half_len = shape.radius, shape.length / 2
    width = 2 * r
    out: list[Grasp | None] = []
    yaws = 2 * np.pi * np.arange(params.n_yaw) / params.n_yaw
    if abs(axis[2]) >= np.cos(np.pi / 4):
        n = axis * np.sign(axis[2])
        u, w = _perp_basis(n, R[:, 0])
        if "top" in kinds:
            depth = _top_depth(2 * half_len, gripper, params)
            if depth is not None:
                p = c + n * (half_len - depth)
                for a in yaws:
                    f = np.cos(a) * u + np.sin(a) * w
                    out.append(_make("top", X_WO, -n, f, p, width, gripper, params, base))
        if "side" in kinds:
            centre = _side_height(c, n, half_len, gripper, params)
            for a in yaws if centre is not None else []:
                radial = np.cos(a) * u + np.sin(a) * w
                tangent = np.cross(n, radial)
                for s in (1.0, -1.0):
                    out.append(
                        _make(
                            "side", X_WO, -radial, s * tangent, centre, width, gripper, params, base
                        )
                    )
    elif "top" in kinds:
        n = _unit(_UP - (_UP @ axis) * axis)
        depth = _top_depth(width, gripper, params)
        if depth is not None:
            p = c + n * (r - depth)
            across = np.cross(axis, n)
            for s in (1.0, -1.0):
                out.append(_make("top", X_WO, -n, s * across, p, width, gripper, params, base))
    return _rank(out)


def sphere_grasps(
    X_WO: RigidTransform,
    shape: SphereShape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    params: GraspParams = GraspParams(),
) -> list[Grasp]:
    """Top-down grasps across a sphere at `n_yaw` finger directions, best first."""
    c = X_WO.translation()
    width = 2 * shape.radius
    depth = _top_depth(width, gripper, params)
    if depth is None:
        return []
    p = c + _UP * (shape.radius - depth)
    out = []
    for a in 2 * np.pi * np.arange(params.n_yaw) / params.n_yaw:
        f = np.array([np.cos(a), np.sin(a), 0.0])
        out.append(_make("top", X_WO, -_UP, f, p, width, gripper, params, base))
    return _rank(out)


def bowl_rim_grasps(
    X_WO: RigidTransform,
    shape: BowlShape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    params: GraspParams = GraspParams(),
) -> list[Grasp]:
    """Rim grasps of a bowl at `n_yaw` azimuths, best first.

    The approach is along the bowl's -axis (down for an upright bowl); the fingers straddle the
    wall radially. The pads sit `rim_depth` below the rim; since the wall leans outward, the TCP
    follows the wall's mid-surface at the pads' height and the width covers the lean over the pad
    length. With ``params.rim_lean`` the approach runs down the wall's slant instead (tipped
    outward by the wall's lean), so the pads lie flat on the wall and hold it upright. With
    ``params.rim_floor`` the fingertips stay that far above the floor, the pads higher if need be.
    """
    R = X_WO.rotation().matrix()
    o = X_WO.translation()
    n = R[:, 2]
    u, w = _perp_basis(n, R[:, 0])
    h = shape.height
    tilt = float(np.arctan2(shape.radius - shape.base_radius, h))
    pad = gripper.pad_length
    depth = min(params.rim_depth + pad / 2, h - pad / 2 - params.tip_clearance)
    if params.rim_floor is not None:
        # The inside finger's tip clears the floor (a tip pressed into the base holds the
        # bowl by that tip, not the pads by the wall, and can carry it off after the release);
        # in a bowl shallower than the pads they then stand above the rim.
        depth = min(depth, h - shape.wall - params.rim_floor - pad / 2)
        if depth + pad / 2 < MIN_RIM_OVERLAP:
            return []
    elif depth <= 0:
        return []
    z = h - depth
    # Mid-surface of the wall: radius - wall/2 at the rim, leaning in by tan(tilt) per metre down.
    r_mid = shape.radius - shape.wall / 2 - (h - z) * np.tan(tilt)
    width = shape.wall / np.cos(tilt) + pad * np.tan(tilt)
    if params.rim_lean:  # pads parallel to the wall: they grip it flat across its thickness
        width = shape.wall
    out = []
    for a in 2 * np.pi * np.arange(params.n_yaw) / params.n_yaw:
        radial = np.cos(a) * u + np.sin(a) * w
        p = o + n * z + radial * r_mid
        approach, across = -n, radial
        if params.rim_lean:  # down the wall: tipped outward at the top by the wall's lean
            approach = -np.cos(tilt) * n - np.sin(tilt) * radial
            across = np.cos(tilt) * radial - np.sin(tilt) * n
        for s in (1.0, -1.0):
            out.append(_make("rim", X_WO, approach, s * across, p, width, gripper, params, base))
    return _rank(out)


def handle_grasps(
    X_WH: RigidTransform,
    shape: BoxShape | CylinderShape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    params: GraspParams = GraspParams(),
) -> list[Grasp]:
    """Grasps of a handle bar (a box or cylinder part with pose `X_WH`), best first.

    The approach is perpendicular to the bar's long axis (a box's longest side, a cylinder's
    axis) and the fingers close across its thickness; the pads are centred on the bar's middle.
    ``X_OG`` of the result is relative to the handle part frame H.
    """
    R = X_WH.rotation().matrix()
    c = X_WH.translation()
    out: list[Grasp | None] = []
    if isinstance(shape, CylinderShape):
        axis = R[:, 2]
        u, w = _perp_basis(axis, R[:, 0])
        for a in 2 * np.pi * np.arange(params.n_yaw) / params.n_yaw:
            radial = np.cos(a) * u + np.sin(a) * w
            across = np.cross(axis, radial)
            for s in (1.0, -1.0):
                g = _make(
                    "handle", X_WH, -radial, s * across, c, 2 * shape.radius, gripper, params, base
                )
                out.append(g)
        return _rank(out)
    half = np.asarray(shape.size, dtype=float) / 2
    long_axis = int(np.argmax(half))
    others = [i for i in range(3) if i != long_axis]
    for i in others:
        j = others[0] if i == others[1] else others[1]
        inset = max(half[i] - gripper.pad_length / 2, 0.0)
        for si in (1.0, -1.0):
            p = c + si * R[:, i] * inset
            for sj in (1.0, -1.0):
                f = sj * R[:, j]
                g = _make("handle", X_WH, -si * R[:, i], f, p, 2 * half[j], gripper, params, base)
                out.append(g)
    return _rank(out)


def grasp_candidates(
    obj: SceneObject,
    gripper: GripperSpec,
    *,
    X_WO: RigidTransform | None = None,
    base: np.ndarray | None = None,
    kinds: Sequence[GraspKind] | None = None,
    params: GraspParams = GraspParams(),
    parts: Sequence[int] | None = None,
) -> list[Grasp]:
    """All grasp candidates of a scene object (at `X_WO`, default its initial pose), best first.

    A :class:`CompoundShape` is grasped by its parts (`parts`: indices into ``shape.parts``,
    default all; see :func:`compound_grasps`). ``PlanningError('no_grasp')`` when none fits the
    gripper.
    """
    X = pose_to_transform(obj) if X_WO is None else X_WO
    shape = obj.shape
    if isinstance(shape, CompoundShape):
        grasps = compound_grasps(X, shape, gripper, base=base, params=params, parts=parts)
    elif isinstance(shape, PotShape):
        grasps = pot_handle_grasps(X, shape, gripper, base=base, params=params)
    elif parts is not None:
        raise ValueError(f"parts= applies to compound shapes, not {shape.kind}")
    else:
        grasps = _shape_grasps(X, shape, gripper, base, params)
    if kinds is not None:
        grasps = [g for g in grasps if g.kind in kinds]
    if not grasps:
        raise PlanningError("no_grasp", f"no grasp of {obj.name!r} ({shape.kind}) fits the gripper")
    return grasps


def _shape_grasps(X_WO, shape, gripper, base, params) -> list[Grasp]:
    if isinstance(shape, BoxShape):
        return box_grasps(X_WO, shape, gripper, base=base, params=params)
    if isinstance(shape, CylinderShape):
        return cylinder_grasps(X_WO, shape, gripper, base=base, params=params)
    if isinstance(shape, SphereShape):
        return sphere_grasps(X_WO, shape, gripper, base=base, params=params)
    if not all(hasattr(shape, a) for a in ("height", "radius", "base_radius")):
        # e.g. a pen (its task passes grasps of its own): no generated grasp, a typed failure
        raise PlanningError("no_grasp", f"no grasps are generated for a {shape.kind} shape")
    return bowl_rim_grasps(X_WO, shape, gripper, base=base, params=params)


def pot_handle_grasps(
    X_WO: RigidTransform,
    shape: PotShape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    params: GraspParams = GraspParams(),
    handles: Sequence[float] = (-1.0, 1.0),
) -> list[Grasp]:
    """Horizontal grasps of a pot's lug handles (`handles`: -1 for the one on the pot's -x,
    +1 for +x), best first: the approach points from outside toward the pot's axis (within
    45 degrees of horizontal), the fingers close on the handle plate's top and bottom faces.
    ``X_OG`` is relative to the pot's frame, so holding a handle holds the pot."""
    X_OW = X_WO.inverse()
    out = []
    for sign in handles:
        part, X_WH = _pot_handle(X_WO, shape, sign)
        outward = sign * X_WO.rotation().col(0)
        for g in handle_grasps(X_WH, part_shape(part), gripper, base=base, params=params):
            if g.approach @ outward > -np.cos(np.pi / 4) or abs(g.approach[2]) > 0.5:
                continue
            out.append(Grasp(g.kind, g.X_WG, g.X_WPre, X_OW @ g.X_WG, g.width, g.score))
    return sorted(out, key=lambda g: -g.score)


#: How far (rad) :func:`pot_handle_grasps_across` tilts its approach down from horizontal.
ACROSS_PITCH = 0.3


def pot_handle_grasps_across(
    X_WO: RigidTransform,
    shape: PotShape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    params: GraspParams = GraspParams(),
    handles: Sequence[float] = (-1.0, 1.0),
    pitch: float = ACROSS_PITCH,
) -> list[Grasp]:
    """Grasps of a pot's lug handles that close across the plate's width (the pads on its
    two side faces, the jaw axis horizontal), best first: the approach points from outside
    toward the pot's axis, tilted `pitch` (rad) down about the jaw axis (:func:`pitched`: the
    wrist rises behind the handle, over what stands beside the pot), the pads as far out on
    the plate as they fit. For a hand too long along its finger axis to stand vertical at the
    handle's height (the plate-face grasps of :func:`pot_handle_grasps`). ``X_OG`` is
    relative to the pot's frame."""
    X_OW = X_WO.inverse()
    out = []
    for sign in handles:
        part, X_WH = _pot_handle(X_WO, shape, sign)
        R = X_WH.rotation().matrix()
        half = np.asarray(part.size, dtype=float) / 2
        outward = sign * R[:, 0]
        p = X_WH.translation() + outward * max(half[0] - gripper.pad_length / 2, 0.0)
        for s in (1.0, -1.0):
            g = _make("handle", X_WH, -outward, s * R[:, 1], p, 2 * half[1], gripper, params, base)
            if g is not None:
                g = pitched(g, X_WO, pitch)
                out.append(Grasp(g.kind, g.X_WG, g.X_WPre, X_OW @ g.X_WG, g.width, g.score))
    return sorted(out, key=lambda g: -g.score)


def _pot_handle(
    X_WO: RigidTransform, shape: PotShape, sign: float
) -> tuple[Primitive, RigidTransform]:
    """The lug handle on the pot's -x (`sign` -1) or +x (+1) side and its pose in the world."""
    if sign not in (-1.0, 1.0):
        raise ValueError(f"a pot handle is -1 or +1, not {sign}")
    part = shape.primitives()[shape.handle_indices()[0 if sign < 0 else 1]]
    return part, X_WO @ RigidTransform(part.pose.matrix())


def part_shape(part: Primitive) -> BoxShape | CylinderShape | SphereShape:
    """The shape of one part of a compound (a capsule is grasped like its cylinder)."""
    if part.kind == "box":
        return BoxShape(size=part.size)
    if part.kind == "sphere":
        return SphereShape(radius=part.size[0])
    return CylinderShape(radius=part.size[0], length=part.size[1])


def compound_grasps(
    X_WO: RigidTransform,
    shape: CompoundShape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    params: GraspParams = GraspParams(),
    parts: Sequence[int] | None = None,
) -> list[Grasp]:
    """Grasps of the parts of a compound object at `X_WO`, best first, with ``X_OG`` in the
    object's frame (so holding any of them holds the object).

    Each part is grasped as if alone: a grasp near another part may touch it. Choose the parts
    meant for the hand with `parts` (indices into ``shape.parts``)."""
    indices = range(len(shape.parts)) if parts is None else parts
    X_OW = X_WO.inverse()
    grasps = []
    for index in indices:
        if not 0 <= index < len(shape.parts):
            raise ValueError(f"part {index} out of range: the shape has {len(shape.parts)} parts")
        part = shape.parts[index]
        X_WP = X_WO @ RigidTransform(part.pose.matrix())
        for g in _shape_grasps(X_WP, part_shape(part), gripper, base, params):
            grasps.append(Grasp(g.kind, g.X_WG, g.X_WPre, X_OW @ g.X_WG, g.width, g.score))
    return sorted(grasps, key=lambda g: -g.score)


def bounding_box_grasps(
    X_WO: RigidTransform,
    shape: Shape,
    gripper: GripperSpec,
    *,
    base: np.ndarray | None = None,
    kinds: Sequence[GraspKind] = ("top",),
    params: GraspParams = GraspParams(),
) -> list[Grasp]:
    """Grasps of a small compound object (a toy car, a domed box) as if it were its bounding
    box, best first, with ``X_OG`` in the object's frame: the jaw closes across the whole
    object, so the pads meet whichever parts stick out furthest (the car's body, the dome's
    base) instead of one part chosen alone."""
    lo = np.min([p.trimesh().bounds[0] for p in shape.primitives()], axis=0)
    hi = np.max([p.trimesh().bounds[1] for p in shape.primitives()], axis=0)
    X_OB = RigidTransform((lo + hi) / 2)
    box = BoxShape(size=tuple(float(v) for v in hi - lo))
    X_OW = X_WO.inverse()
    out = []
    for g in box_grasps(X_WO @ X_OB, box, gripper, base=base, kinds=kinds, params=params):
        out.append(Grasp(g.kind, g.X_WG, g.X_WPre, X_OW @ g.X_WG, g.width, g.score))
    return out


# --------------------------------------------------------------------------------------------
# Place poses
# --------------------------------------------------------------------------------------------


def bottom_offset(shape: Shape) -> float:
    """Height of the object frame above the object's bottom when upright."""
    if isinstance(shape, BoxShape):
        return shape.size[2] / 2
    if isinstance(shape, CylinderShape):
        return shape.length / 2
    if isinstance(shape, SphereShape):
        return shape.radius
    return 0.0  # bowl: frame at the base underside


def top_offset(shape: Shape) -> float:
    """Height of the object's top above its frame when upright."""
    if isinstance(shape, BowlShape):
        return shape.height
    if isinstance(shape, BinShape):
        return shape.size[2]
    return bottom_offset(shape)


def place_pose(X_GO: RigidTransform, X_WO: RigidTransform) -> RigidTransform:
    """TCP pose that puts an object held with `X_GO` (object in gripper) at `X_WO`."""
    return X_WO @ X_GO.inverse()


def table_target(
    xy: Sequence[float],
    shape: Shape,
    yaw: float = 0.0,
    *,
    support_z: float = TABLE_TOP,
    clearance: float = 0.002,
) -> RigidTransform:
    """Upright object pose resting `clearance` above a surface at height `support_z`."""
    z = support_z + bottom_offset(shape) + clearance
    return RigidTransform(RotationMatrix.MakeZRotation(yaw), [xy[0], xy[1], z])


def stack_target(
    X_WS: RigidTransform,
    support: Shape,
    held: Shape,
    yaw: float | None = None,
    *,
    clearance: float = 0.002,
    offset_xy: Sequence[float] = (0.0, 0.0),
) -> RigidTransform:
    """Upright pose of `held` on top of an upright `support` object at `X_WS`.

    `yaw` defaults to the support's yaw; `offset_xy` shifts it in the world from the centre.
    For a bowl support the object rests on the inside of its base.
    """
    p = X_WS.translation()
    if isinstance(support, BowlShape):
        surface = p[2] + support.wall
    else:
        surface = p[2] + top_offset(support)
    if yaw is None:
        R = X_WS.rotation().matrix()
        yaw = float(np.arctan2(R[1, 0], R[0, 0]))
    xy = (p[0] + offset_xy[0], p[1] + offset_xy[1])
    return table_target(xy, held, yaw, support_z=surface, clearance=clearance)


def symmetric_yaws(shape: Shape, n_round: int = 8) -> list[float]:
    """Yaw offsets under which an upright shape looks the same (round shapes: `n_round`)."""
    if isinstance(shape, BoxShape):
        square = abs(shape.size[0] - shape.size[1]) < 1e-9
        return [k * np.pi / 2 for k in range(4)] if square else [0.0, np.pi]
    return [2 * np.pi * k / n_round for k in range(n_round)]


def place_candidates(
    X_GO: RigidTransform,
    X_WO_target: RigidTransform,
    shape: Shape | None = None,
    *,
    base: np.ndarray | None = None,
    lift: float = 0.08,
    yaws: Sequence[float] | None = None,
) -> list[Place]:
    """Place candidates for a held object, best first.

    The target is turned about the world z through its centre by each of `yaws` (default: the
    shape's symmetric yaws, or none without a shape); the pre-place pose is `lift` straight above.
    """
    offsets = list(yaws) if yaws is not None else (symmetric_yaws(shape) if shape else [0.0])
    out = []
    for a in offsets:
        X_WO = RigidTransform(
            RotationMatrix.MakeZRotation(a) @ X_WO_target.rotation(), X_WO_target.translation()
        )
        X_WG = place_pose(X_GO, X_WO)
        X_WPre = RigidTransform(X_WG.rotation(), X_WG.translation() + lift * _UP)
        out.append(Place(X_WO, X_WG, X_WPre, naturalness(X_WG, base)))
    return sorted(out, key=lambda c: -c.score)
