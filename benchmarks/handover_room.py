"""How much room a robot's hands have at handover_block_with_bowls' meeting (geometry only).

At the meeting the right hand holds the catching bowl by its rim under the pouring bowl's
spout lip, and the left holds the pouring bowl by its rim on the far side. The stage allows the
lip anywhere within ``ALIGN_XY`` of the catching bowl's axis and ``ALIGN_Z`` above its rim.
This script searches those layouts - the lip's offset from the catching bowl's axis (a grid
over the allowed disc), the rim's drop below the lip, the azimuth of the right hand's grip, the
spout's yaw, the left hand's grip and two rim-grasp depths - and reports, per robot, the
largest clearance it finds between

- the right hand and the pouring bowl, the two hands, the left hand and the catching bowl,

among the layouts whose right hand also stays out of the cube's fall (a column from the lip
down to the rim, 3 cm along the pour direction). The hands are the embodiment's own extent
(``ArmSpec.hand_boxes``: the boxes around its gripper link and its closed fingers), so no
inverse kinematics is involved: a layout with too little room here has no plan whatever the
arm does, and the expert plans with a 2 cm arm clearance.

    python benchmarks/handover_room.py --embodiment franka_pair
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np
from pydrake.all import AngleAxis, RigidTransform, RotationMatrix

import bicoord_drake.tasks.handover_block_with_bowls as task
from bicoord_drake.models.geometry import transform_points
from bicoord_drake.models.objects import BowlShape
from bicoord_drake.models.robots import EMBODIMENTS, get_embodiment
from bicoord_drake.planning.clearance import box_points, points_to_boxes, shape_points
from bicoord_drake.planning.grasps import GraspParams, bowl_rim_grasps

DROPS = (0.04, 0.07, 0.09, 0.097)  # rim below the lip, m (ALIGN_Z is 0.03 .. 0.10)
OFFSET_STEP = 0.015  # grid of the lip's offset from the catching bowl's axis, m
AZIMUTHS = np.radians(np.arange(-180, 180, 15))  # the right hand's grip around the bowl
RIM_DEPTHS = (0.003, 0.015)  # pad top below the rim, m
FALL_ALONG = 0.03  # the cube's column runs this far along the pour direction, m
PATH_MARGIN = 0.005  # the hand keeps this far from the column, m
TILTS = np.radians([0, 20, 40, 60, 80])  # samples of the pour (POUR_ANGLE is 80 deg)


def _pour_turns(X_WP: RigidTransform) -> list[RigidTransform]:
    """World motions of the pour at TILTS: turns about the horizontal axis through the lip,
    across the spout's direction (as the expert's pour)."""
    d = X_WP.rotation().col(0)
    axis = np.cross([0.0, 0.0, 1.0], d)
    axis /= np.linalg.norm(axis)
    lip = X_WP @ task.LIP_POINT
    turns = []
    for angle in TILTS:
        R = RotationMatrix(AngleAxis(angle, axis))
        turns.append(RigidTransform(R, lip - R @ lip))
    return turns


def _fall_column(lip: np.ndarray, drop: float) -> np.ndarray:
    """Points filling the cube's path: from the lip down to the catching rim, FALL_ALONG
    along the pour direction, as wide as the cube's diagonal."""
    half = task.CUBE * np.sqrt(2) / 2
    out = []
    for s, dz in itertools.product(np.linspace(0, FALL_ALONG, 4), np.linspace(0, drop, 6)):
        centre = lip + s * task.POUR_DIRECTION - [0, 0, dz]
        for a in np.linspace(0, 2 * np.pi, 8, endpoint=False):
            out.append(centre + half * np.array([np.cos(a), np.sin(a), 0.0]))
        out.append(centre)
    return np.array(out)


def room(embodiment_name: str, keep_fall_clear: bool = True) -> dict:
    """The best layout for `embodiment_name` (clearances in m, layout choices); with
    `keep_fall_clear` False the cube's fall is not looked at."""
    arm = get_embodiment(embodiment_name).arm
    gripper = arm.gripper
    identity = RigidTransform()
    pour_points = shape_points(task.pour_bowl_shape())
    catch_points = shape_points(task.CATCH_BOWL)
    proxy = BowlShape(
        radius=task.POUR_RADIUS,
        base_radius=task.POUR_RADIUS,
        height=task.POUR_HEIGHT,
        wall=task.POUR_WALL,
    )
    left_grasps = [
        g
        for g in bowl_rim_grasps(
            identity, proxy, gripper, params=GraspParams(tip_clearance=task.POUR_BASE + 0.003)
        )
        if task.GRIP_AZIMUTH[0]
        <= np.arctan2(g.X_WG.translation()[1], g.X_WG.translation()[0])
        <= task.GRIP_AZIMUTH[1]
    ]
    r_max = task.ALIGN_XY - 0.005
    grid = np.arange(-r_max, r_max + 1e-9, OFFSET_STEP)
    offsets = [np.array([x, y]) for x in grid for y in grid if np.hypot(x, y) <= r_max]
    best = {"clearance": -np.inf}
    for depth in RIM_DEPTHS:
        boxes = arm.hand_boxes(gripper.opening_for_gap(task.CATCH_BOWL.wall))
        hand_points = np.vstack([box_points(lo, hi) for lo, hi in boxes])
        rights = bowl_rim_grasps(
            identity, task.CATCH_BOWL, gripper, params=GraspParams(rim_depth=depth, n_yaw=1)
        )
        for yaw in task.SPOUT_YAWS:
            R = RotationMatrix.MakeZRotation(task.POUR_YAW + yaw)
            X_WP = RigidTransform(R, task.LIP_AT - R @ task.LIP_POINT)
            turns = _pour_turns(X_WP)
            pour_W = [transform_points(T @ X_WP, pour_points) for T in turns]
            left_tcps = [[T @ X_WP @ g.X_WG for T in turns] for g in left_grasps]
            for drop in DROPS:
                column = _fall_column(task.LIP_AT, drop)
                for offset, azimuth, grasp in itertools.product(offsets, AZIMUTHS, rights[:1]):
                    p = grasp.X_WG.translation()
                    turn = azimuth - np.arctan2(p[1], p[0])
                    centre = task.LIP_AT - [*offset, drop + task.CATCH_BOWL.height]
                    X_WB = RigidTransform(RotationMatrix.MakeZRotation(turn), centre)
                    X_TW = (X_WB @ grasp.X_WG).inverse()
                    if (
                        keep_fall_clear
                        and points_to_boxes(transform_points(X_TW, column), boxes) < PATH_MARGIN
                    ):
                        continue
                    d_pour = min(
                        points_to_boxes(transform_points(X_TW, pts), boxes) for pts in pour_W
                    )
                    if d_pour <= best["clearance"]:
                        continue
                    catch_W = transform_points(X_WB, catch_points)
                    for X_WLs in left_tcps:
                        d_hands = min(
                            points_to_boxes(transform_points(X_TW @ X_WL, hand_points), boxes)
                            for X_WL in X_WLs
                        )
                        d_catch = min(
                            points_to_boxes(transform_points(X_WL.inverse(), catch_W), boxes)
                            for X_WL in X_WLs
                        )
                        clearance = min(d_pour, d_hands, d_catch)
                        if clearance > best["clearance"]:
                            best = {
                                "clearance": clearance,
                                "right_hand_pour_bowl": d_pour,
                                "hands": d_hands,
                                "left_hand_catch_bowl": d_catch,
                                "lip_offset_cm": tuple(round(float(v) * 100, 1) for v in offset),
                                "drop_cm": round(drop * 100, 1),
                                "grip_azimuth_deg": round(float(np.degrees(azimuth))),
                                "spout_yaw": yaw,
                                "rim_depth_cm": round(depth * 100, 1),
                            }
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--embodiment",
        action="append",
        choices=sorted(EMBODIMENTS),
        help="robot(s) to check (default: all registered)",
    )
    args = parser.parse_args()
    for name, fall in itertools.product(args.embodiment or sorted(EMBODIMENTS), (True, False)):
        best = room(name, fall)
        what = "cube's fall kept clear" if fall else "cube's fall not looked at"
        if not np.isfinite(best["clearance"]):
            print(f"{name} ({what}): no layout")
            continue
        print(f"{name} ({what}): best clearance {best['clearance'] * 100:.1f} cm")
        for key, value in best.items():
            if key != "clearance":
                shown = (
                    f"{value * 100:.1f} cm"
                    if isinstance(value, float)
                    and key in ("right_hand_pour_bowl", "hands", "left_hand_catch_bowl")
                    else value
                )
                print(f"  {key}: {shown}")


if __name__ == "__main__":
    main()
