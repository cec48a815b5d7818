"""Room for the hand: how far the hand at a TCP pose stays from the rest of the planning world.

The hand is the embodiment's :meth:`~bicoord_drake.models.embodiment.ArmSpec.hand_boxes`
(boxes in the TCP frame, derived from the gripper link's collision primitives and the
fingers). The world is sampled once per question: the surfaces of the scene's colliding
objects (points about 1 cm apart), the other arm's hand and what it holds, and the table top.
The answer is a cheap lower-level ranking aid, not a collision check: the IK and the path
planner still check every pose against the full model. Skills use it to try first the grasps
and place yaws whose hand clears its neighbours (a wide hand needs room along its finger axis),
instead of spending their tries on poses the IK cannot make collision-free.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from functools import lru_cache

import numpy as np
import trimesh
from pydrake.math import RigidTransform

from bicoord_drake.models.embodiment import other_side
from bicoord_drake.models.geometry import transform_points
from bicoord_drake.models.scene import TABLE_TOP

#: Spacing (m) of the surface points an obstacle is sampled with.
SAMPLE_SPACING = 0.01


@lru_cache(maxsize=256)
def _primitive_points(prim) -> np.ndarray:
    mesh = prim.trimesh()
    vertices, _ = trimesh.remesh.subdivide_to_size(
        mesh.vertices, mesh.faces, max_edge=SAMPLE_SPACING, max_iter=20
    )
    return np.asarray(vertices, dtype=float)


def shape_points(shape) -> np.ndarray:
    """Points on the surface of a shape (its frame), about SAMPLE_SPACING apart."""
    return np.vstack([_primitive_points(p) for p in shape.primitives()])


def box_points(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Points on the surface of an axis-aligned box (its frame), about SAMPLE_SPACING apart."""
    prim_mesh = trimesh.creation.box(extents=hi - lo)
    prim_mesh.apply_translation((lo + hi) / 2)
    vertices, _ = trimesh.remesh.subdivide_to_size(
        prim_mesh.vertices, prim_mesh.faces, max_edge=2 * SAMPLE_SPACING, max_iter=20
    )
    return np.asarray(vertices, dtype=float)


def _corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.array(
        [[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])]
    )


def points_to_boxes(points_T: np.ndarray, boxes) -> float:
    """Least distance (m) from points (in the boxes' frame) to any of the boxes; inf if no
    points; 0 if a point lies inside a box."""
    if len(points_T) == 0:
        return float("inf")
    best = float("inf")
    for lo, hi in boxes:
        gap = np.maximum(np.maximum(lo - points_T, points_T - hi), 0.0)
        best = min(best, float(np.min(np.linalg.norm(gap, axis=1))))
    return best


def hands_gap(boxes, X_a: RigidTransform, X_b: RigidTransform) -> float:
    """Least distance (m) between two hands of one kind (`boxes` in the TCP frame, as
    ``ArmSpec.hand_boxes``) at TCP poses `X_a` and `X_b`, from surface points of the first
    (about 2 * SAMPLE_SPACING apart); 0 where they overlap."""
    points = np.vstack([box_points(lo, hi) for lo, hi in boxes])
    return points_to_boxes(transform_points(X_b.inverse() @ X_a, points), boxes)


def side_pitch(
    boxes, tcp_height: float, floor: float, step: float = 0.0436, limit: float = 0.524
) -> float | None:
    """The least pitch (rad, multiples of `step` up to `limit`; 0 first) of a side grasp whose
    TCP is `tcp_height` (m) above the support that keeps the hand (`boxes` in the TCP frame, as
    ``ArmSpec.hand_boxes``) `floor` (m) above it when the object is set down: the approach
    tilted down about the jaw axis, so that what lies behind the fingers rises. None if no
    pitch up to `limit` does."""
    corners = np.vstack([_corners(lo, hi) for lo, hi in boxes])
    for k in range(int(round(limit / step)) + 1):
        a = k * step
        z = tcp_height - corners[:, 0] * np.sin(a) + corners[:, 2] * np.cos(a)
        if float(np.min(z)) >= floor - MARGIN_TOL:
            return a
    return None


def hand_floor(boxes, X_WT: RigidTransform, z: float) -> float:
    """How far (m) the hand (`boxes` in the TCP frame, as ``ArmSpec.hand_boxes``) at TCP pose
    `X_WT` stays above the horizontal plane at height `z` (negative: it reaches below)."""
    corners = np.vstack([_corners(lo, hi) for lo, hi in boxes])
    return float(np.min(transform_points(X_WT, corners)[:, 2]) - z)


class HandRoom:
    """The room around the hand of `side` with the model at joint angles `q`: objects in
    `exclude` (the object being grasped, what is ignored) and what `side` holds are left out."""

    def __init__(self, model, side: str, q: np.ndarray, exclude: Iterable[str] = ()) -> None:
        self.boxes = model.hand_boxes
        skip = set(exclude)
        held = model.held.get(side)
        if held is not None:
            skip.add(held.name)
        other = other_side(side)
        other_held = model.held.get(other)
        env = []
        for obj in model.scene.objects:
            if not obj.collide or obj.name in skip:
                continue
            if other_held is not None and obj.name == other_held.name:
                continue
            env.append(transform_points(model.object_pose(obj.name), shape_points(obj.shape)))
        self.env = np.vstack(env) if env else np.zeros((0, 3))
        X_WO = model.tcp_pose(q, other)
        arm = [transform_points(X_WO, box_points(lo, hi)) for lo, hi in self.boxes]
        if other_held is not None:
            X = model.held_pose(other, q)
            arm.append(transform_points(X, shape_points(model.object(other_held.name).shape)))
        self.arm = np.vstack(arm)
        self._corners = [_corners(lo, hi) for lo, hi in self.boxes]

    def distances(self, X_WT: RigidTransform) -> tuple[float, float]:
        """(distance to the environment and the table, distance to the other arm's hand and
        what it holds), m, of the hand at TCP pose `X_WT`."""
        X_TW = X_WT.inverse()
        d_env = points_to_boxes(transform_points(X_TW, self.env), self.boxes)
        lowest = min(float(np.min(transform_points(X_WT, c)[:, 2])) for c in self._corners)
        d_env = min(d_env, lowest - TABLE_TOP)
        d_arm = points_to_boxes(transform_points(X_TW, self.arm), self.boxes)
        return d_env, d_arm

    def margin(self, poses: Sequence[RigidTransform], env_need: float, arm_need: float) -> float:
        """The least excess (m) of the distances over what is needed, over `poses`."""
        out = float("inf")
        for X in poses:
            d_env, d_arm = self.distances(X)
            out = min(out, d_env - env_need, d_arm - arm_need)
        return out


#: A margin this far below zero (m) still counts as room: the hand samples and boxes are
#: approximate, and a grasp whose fingertips stop exactly the clearance above the table
#: reads a rounding error short of it.
MARGIN_TOL = 1e-4


def roomy_first(items: Sequence, margins: Sequence[float]) -> list:
    """`items` (best first) with those whose margin is negative (beyond MARGIN_TOL) moved
    behind the others, the crowded ones by decreasing margin; order is kept otherwise."""
    pairs = list(zip(items, margins, strict=True))
    ok = [it for it, m in pairs if m >= -MARGIN_TOL]
    crowded = [(m, i, it) for i, (it, m) in enumerate(pairs) if m < -MARGIN_TOL]
    crowded.sort(key=lambda t: (-t[0], t[1]))
    return ok + [it for _, _, it in crowded]
