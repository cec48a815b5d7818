"""Grasp and place candidates: geometry of every candidate, ranking, place transforms."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from bicoord_drake.models.geometry import Pose, Primitive
from bicoord_drake.models.objects import (
    BowlShape,
    BoxShape,
    CompoundShape,
    CylinderShape,
    SceneObject,
    SphereShape,
)
from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    GraspParams,
    arm_base,
    bowl_rim_grasps,
    box_grasps,
    cylinder_grasps,
    grasp_candidates,
    handle_grasps,
    naturalness,
    place_candidates,
    place_pose,
    pose_to_transform,
    sphere_grasps,
    stack_target,
    table_target,
    turned_onto,
)

DOWN = np.array([0.0, 0.0, -1.0])


@pytest.fixture(scope="module")
def embodiment():
    return get_embodiment("aloha_viperx")


@pytest.fixture(scope="module")
def gripper(embodiment):
    return embodiment.arm.gripper


def resting(shape, x=0.0, y=0.0, yaw=0.0) -> RigidTransform:
    half = {"box": lambda s: s.size[2] / 2, "cylinder": lambda s: s.length / 2}
    z = TABLE_TOP + half.get(shape.kind, lambda s: 0.0)(shape)
    return RigidTransform(RotationMatrix.MakeZRotation(yaw), [x, y, z])


def assert_common(grasps, gripper, params: GraspParams | None = None):
    params = params or GraspParams()
    assert grasps, "expected candidates"
    scores = [g.score for g in grasps]
    assert scores == sorted(scores, reverse=True)
    for g in grasps:
        R = g.X_WG.rotation().matrix()
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-9) and np.linalg.det(R) == pytest.approx(1)
        # Jaw gap fits: open with margin, and not thinner than the closed jaw.
        assert g.width + 2 * params.margin <= 2 * gripper.finger_max + 1e-12
        assert g.width >= 2 * gripper.finger_min
        # Pregrasp: same orientation, retreated along -approach.
        offset = g.X_WG.translation() - g.X_WPre.translation()
        assert np.allclose(offset, params.pregrasp_distance * g.approach)
        assert np.allclose(g.X_WPre.rotation().matrix(), R)
        assert g.approach[2] <= 0.25  # never from below


# --------------------------------------------------------------------------------------------
# Boxes
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("yaw", [0.0, 0.5, -1.2])
def test_box_top_grasps_across_the_narrow_side(yaw, gripper):
    shape = BoxShape(size=(0.03, 0.2, 0.06))  # only the 3 cm side fits the 9 cm jaw
    X_WO = resting(shape, 0.1, 0.05, yaw)
    grasps = box_grasps(X_WO, shape, gripper, kinds=("top",))
    assert_common(grasps, gripper)
    narrow = X_WO.rotation().col(0)
    top = TABLE_TOP + 0.06
    assert len(grasps) == 2  # both finger orientations of the one fitting axis
    for g in grasps:
        assert g.kind == "top"
        assert np.allclose(g.approach, DOWN)
        assert abs(g.finger_axis @ narrow) == pytest.approx(1.0)
        assert g.width == pytest.approx(0.03)
        # Pads flush with the top face: TCP half a pad below it, above the fingertip clearance.
        assert g.X_WG.translation()[2] == pytest.approx(top - gripper.pad_length / 2)
        assert np.allclose(g.X_WG.translation()[:2], X_WO.translation()[:2])
        # X_OG is the grasp in the object frame.
        assert (X_WO @ g.X_OG).IsNearlyEqualTo(g.X_WG, 1e-12)


def test_small_cube_tcp_keeps_fingertips_off_the_table(gripper):
    shape = BoxShape(size=(0.03, 0.03, 0.03))
    grasps = box_grasps(resting(shape), shape, gripper, kinds=("top",))
    assert len(grasps) == 4
    for g in grasps:
        tip = g.X_WG.translation() + g.approach * gripper.pad_length / 2
        assert tip[2] >= TABLE_TOP + GraspParams().tip_clearance - 1e-12


def test_box_side_grasps_are_horizontal_and_clear_the_table(gripper):
    shape = BoxShape(size=(0.05, 0.04, 0.12))
    X_WO = resting(shape, -0.1, 0.0, 0.3)
    grasps = box_grasps(X_WO, shape, gripper, kinds=("side",))
    assert_common(grasps, gripper)
    params = GraspParams()
    assert len(grasps) == 8
    for g in grasps:
        assert abs(g.approach[2]) < 1e-12
        assert abs(g.finger_axis[2]) < 1e-12
        assert g.X_WG.translation()[2] >= TABLE_TOP + params.side_clearance - 1e-12
        # Fingers across the other horizontal side than the approached face.
        across = np.abs(X_WO.rotation().matrix().T @ g.finger_axis)
        along = np.abs(X_WO.rotation().matrix().T @ g.approach)
        i, j = int(np.argmax(along)), int(np.argmax(across))
        assert {i, j} == {0, 1}
        assert g.width == pytest.approx(shape.size[j])


def test_flat_low_box_has_no_side_grasp_and_big_box_none(gripper):
    flat = BoxShape(size=(0.06, 0.06, 0.03))
    assert box_grasps(resting(flat), flat, gripper, kinds=("side",)) == []
    big = SceneObject(name="crate", shape=BoxShape(size=(0.12, 0.12, 0.12)))
    with pytest.raises(PlanningError) as err:
        grasp_candidates(big, gripper)
    assert err.value.reason == "no_grasp"


def test_tilted_box_uses_its_most_upward_face(gripper):
    shape = BoxShape(size=(0.04, 0.06, 0.03))
    R = RotationMatrix(RollPitchYaw(np.pi / 2, 0.0, 0.0))  # object y now points up
    X_WO = RigidTransform(R, [0.0, 0.0, TABLE_TOP + 0.03])
    grasps = box_grasps(X_WO, shape, gripper, kinds=("top",))
    assert_common(grasps, gripper)
    for g in grasps:
        assert np.allclose(g.approach, DOWN, atol=1e-12)
        assert g.X_WG.translation()[2] == pytest.approx(TABLE_TOP + 0.06 - gripper.pad_length / 2)


# --------------------------------------------------------------------------------------------
# Round shapes
# --------------------------------------------------------------------------------------------


def test_upright_cylinder_top_and_side(gripper):
    shape = CylinderShape(radius=0.025, length=0.1)
    X_WO = resting(shape, 0.05, 0.1)
    grasps = cylinder_grasps(X_WO, shape, gripper)
    assert_common(grasps, gripper)
    axis_xy = X_WO.translation()[:2]
    kinds = {g.kind for g in grasps}
    assert kinds == {"top", "side"}
    for g in grasps:
        assert g.width == pytest.approx(0.05)
        assert abs(g.finger_axis[2]) < 1e-12  # across the diameter, never along the axis
        p = g.X_WG.translation()
        assert np.allclose(p[:2], axis_xy)  # TCP on the axis: the pads meet the widest chord
        if g.kind == "top":
            assert np.allclose(g.approach, DOWN)
            assert p[2] == pytest.approx(TABLE_TOP + 0.1 - gripper.pad_length / 2)
        else:
            assert abs(g.approach[2]) < 1e-12
            assert abs(g.X_WG.rotation().col(2)[2]) == pytest.approx(1.0)


def test_lying_cylinder_top_grasp_across_the_diameter(gripper):
    shape = CylinderShape(radius=0.02, length=0.15)
    R = RotationMatrix(RollPitchYaw(0.0, np.pi / 2, 0.4))
    X_WO = RigidTransform(R, [0.0, 0.0, TABLE_TOP + 0.02])
    grasps = cylinder_grasps(X_WO, shape, gripper)
    assert_common(grasps, gripper)
    axis = R.col(2)
    for g in grasps:
        assert g.kind == "top"
        assert np.allclose(g.approach, DOWN, atol=1e-12)
        assert abs(g.finger_axis @ axis) < 1e-12


def test_sphere_top_grasps(gripper):
    shape = SphereShape(radius=0.03)
    X_WO = RigidTransform([0.0, 0.1, TABLE_TOP + 0.03])
    grasps = sphere_grasps(X_WO, shape, gripper)
    assert_common(grasps, gripper)
    assert len(grasps) == GraspParams().n_yaw
    for g in grasps:
        assert np.allclose(g.approach, DOWN)
        assert g.width == pytest.approx(0.06)


def test_compound_grasps_hold_the_object_by_a_part(gripper):
    stick = Primitive(kind="cylinder", size=(0.012, 0.11), pose=Pose(xyz=(0.0, 0.0, 0.055)))
    ball = Primitive(kind="sphere", size=(0.025,), pose=Pose(xyz=(0.0, 0.0, 0.125)))
    mic = SceneObject(name="mic", shape=CompoundShape(parts=(stick, ball)))
    X_WO = RigidTransform(RollPitchYaw(0.0, 0.0, 0.4), [0.1, 0.0, TABLE_TOP])
    every = grasp_candidates(mic, gripper, X_WO=X_WO)
    head = grasp_candidates(mic, gripper, X_WO=X_WO, parts=[1])
    alone = sphere_grasps(
        X_WO @ RigidTransform([0.0, 0.0, 0.125]), SphereShape(radius=0.025), gripper
    )
    assert len(head) == len(alone) and len(every) > len(head)
    assert [g.score for g in every] == sorted((g.score for g in every), reverse=True)
    for g, h in zip(head, alone, strict=True):
        assert g.X_WG.IsExactlyEqualTo(h.X_WG) and g.width == h.width
        # X_OG is in the object's frame: holding the part holds the object
        assert (X_WO @ g.X_OG).IsNearlyEqualTo(g.X_WG, 1e-12)
    with pytest.raises(ValueError, match="out of range"):
        grasp_candidates(mic, gripper, parts=[2])
    with pytest.raises(ValueError, match="compound"):
        grasp_candidates(
            SceneObject(name="b", shape=BoxShape(size=(0.04,) * 3)), gripper, parts=[0]
        )


def test_bowl_rim_fingers_straddle_the_wall(gripper):
    shape = BowlShape(radius=0.07, base_radius=0.045, height=0.05, wall=0.006)
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(0.2), [0.15, -0.05, TABLE_TOP])
    grasps = bowl_rim_grasps(X_WO, shape, gripper)
    assert_common(grasps, gripper)
    params = GraspParams()
    tilt = np.arctan2(shape.radius - shape.base_radius, shape.height)
    centre = X_WO.translation()
    for g in grasps:
        assert g.kind == "rim"
        assert np.allclose(g.approach, DOWN)
        p = g.X_WG.translation()
        radial = p - centre
        radial[2] = 0.0
        # Fingers close radially, across the wall.
        assert abs(g.finger_axis @ radial / np.linalg.norm(radial)) == pytest.approx(1.0)
        # The pads sit just below the rim, fingertips above the table.
        below_rim = TABLE_TOP + shape.height - p[2]
        assert below_rim == pytest.approx(params.rim_depth + gripper.pad_length / 2)
        assert p[2] - gripper.pad_length / 2 > TABLE_TOP
        # The TCP lies between the wall's inner and outer surfaces at its height.
        outer = shape.radius - below_rim * np.tan(tilt)
        inner = outer - shape.wall / np.cos(tilt)
        assert inner < np.linalg.norm(radial) < outer
        # The open jaw clears the wall over the whole pad length.
        assert g.width >= shape.wall / np.cos(tilt) + gripper.pad_length * np.tan(tilt) - 1e-12


def test_leaning_rim_grasp_lies_flat_on_a_flared_wall(gripper):
    shape = BowlShape(radius=0.058, base_radius=0.045, height=0.05, wall=0.009)
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(0.4), [0.1, 0.0, TABLE_TOP])
    tilt = np.arctan2(shape.radius - shape.base_radius, shape.height)
    upright = bowl_rim_grasps(X_WO, shape, gripper)
    grasps = bowl_rim_grasps(X_WO, shape, gripper, params=GraspParams(rim_lean=True))
    assert len(grasps) == len(upright) > 0
    centre = X_WO.translation()
    for g in grasps:
        radial = g.X_WG.translation() - centre
        radial[2] = 0.0
        radial /= np.linalg.norm(radial)
        # down the wall's slant: tipped outward at the top by the wall's lean
        assert g.approach @ DOWN == pytest.approx(np.cos(tilt))
        assert g.approach @ radial == pytest.approx(-np.sin(tilt))
        # the fingers close across the wall, perpendicular to it; the jaw holds its thickness
        wall_dir = np.cos(tilt) * np.array([0, 0, 1.0]) + np.sin(tilt) * radial
        assert abs(g.finger_axis @ wall_dir) == pytest.approx(0.0, abs=1e-9)
        assert g.width == pytest.approx(shape.wall)
    # the default grasps are unchanged: vertical approach
    assert all(np.allclose(g.approach, DOWN) for g in upright)
    # a wall thinner than the closed jaw cannot be gripped flat
    thin = BowlShape(radius=0.058, base_radius=0.045, height=0.05, wall=0.006)
    assert bowl_rim_grasps(X_WO, thin, gripper, params=GraspParams(rim_lean=True)) == []


def test_rim_grasp_of_a_shallow_dish_keeps_the_fingertips_off_its_floor(gripper):
    # a dish shallower than the pads: by default the pads' top sits 3 mm below the rim and the
    # inside fingertip reaches down into the base; with rim_floor it stays above the floor
    shape = BowlShape(radius=0.075, base_radius=0.075, height=0.03, wall=0.012, segments=12)
    X_WO = RigidTransform([0.0, 0.0, TABLE_TOP])
    half_pad = gripper.pad_length / 2
    tips = [g.X_WG.translation()[2] - half_pad for g in bowl_rim_grasps(X_WO, shape, gripper)]
    assert min(tips) < TABLE_TOP + shape.wall
    params = GraspParams(rim_floor=0.005)
    grasps = bowl_rim_grasps(X_WO, shape, gripper, params=params)
    assert_common(grasps, gripper, params)
    for g in grasps:
        tcp = g.X_WG.translation()
        assert tcp[2] - half_pad == pytest.approx(TABLE_TOP + shape.wall + 0.005)
        assert tcp[2] > TABLE_TOP + shape.height  # the pads stand above the rim
    # a deep bowl keeps its pads rim_depth below the rim
    deep = BowlShape(radius=0.07, base_radius=0.07, height=0.08, wall=0.006)
    for g in bowl_rim_grasps(X_WO, deep, gripper, params=params):
        below_rim = TABLE_TOP + deep.height - g.X_WG.translation()[2]
        assert below_rim == pytest.approx(params.rim_depth + half_pad)
    # too little wall above the floor for the pads: no grasp
    flat = BowlShape(radius=0.075, base_radius=0.075, height=0.02, wall=0.012)
    assert bowl_rim_grasps(X_WO, flat, gripper, params=params) == []


# --------------------------------------------------------------------------------------------
# Handles
# --------------------------------------------------------------------------------------------


def test_cylinder_handle(gripper):
    shape = CylinderShape(radius=0.008, length=0.1)
    R = RotationMatrix(RollPitchYaw(np.pi / 2, 0.0, 0.0))  # bar axis horizontal (world -y)
    X_WH = RigidTransform(R, [0.0, 0.2, TABLE_TOP + 0.12])
    grasps = handle_grasps(X_WH, shape, gripper)
    assert_common(grasps, gripper)
    axis = R.col(2)
    for g in grasps:
        assert g.kind == "handle"
        assert abs(g.approach @ axis) < 1e-12 and abs(g.finger_axis @ axis) < 1e-12
        assert np.allclose(g.X_WG.translation(), X_WH.translation())
        assert g.width == pytest.approx(0.016)


def test_box_handle_fingers_across_the_thickness(gripper):
    shape = BoxShape(size=(0.12, 0.02, 0.03))  # long along x
    X_WH = RigidTransform(RotationMatrix.MakeZRotation(0.7), [0.1, 0.2, TABLE_TOP + 0.1])
    grasps = handle_grasps(X_WH, shape, gripper)
    assert_common(grasps, gripper)
    long_axis = X_WH.rotation().col(0)
    for g in grasps:
        assert abs(g.approach @ long_axis) < 1e-12 and abs(g.finger_axis @ long_axis) < 1e-12
        assert (X_WH @ g.X_OG).IsNearlyEqualTo(g.X_WG, 1e-12)


# --------------------------------------------------------------------------------------------
# Ranking
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("side", ["left", "right"])
def test_best_top_grasp_needs_least_wrist_roll(side, embodiment, gripper):
    base = arm_base(embodiment, side)
    obj = SceneObject(
        name="cube",
        shape=BoxShape(size=(0.04, 0.04, 0.04)),
        pose=Pose(xyz=(0.2 if side == "right" else -0.2, 0.0, TABLE_TOP + 0.02)),
    )
    best = grasp_candidates(obj, gripper, base=base)[0]
    reach = best.X_WG.translation() - base
    reach[2] = 0.0
    reach /= np.linalg.norm(reach)
    z = best.X_WG.rotation().col(2)
    # Top-down natural pose: gripper z points away from the arm base, fingers across the reach.
    assert z @ reach > 0.9
    assert naturalness(best.X_WG, base) > 0.9


# --------------------------------------------------------------------------------------------
# Place
# --------------------------------------------------------------------------------------------


def test_place_pose_puts_the_object_at_the_target(gripper):
    obj = SceneObject(
        name="cube",
        shape=BoxShape(size=(0.04, 0.05, 0.06)),
        pose=Pose(xyz=(-0.1, 0.0, TABLE_TOP + 0.03), rpy=(0, 0, 0.3)),
    )
    grasp = grasp_candidates(obj, gripper)[0]
    target = table_target((0.12, 0.08), obj.shape, yaw=-0.4)
    assert target.translation()[2] == pytest.approx(TABLE_TOP + 0.03 + 0.002)
    X_WG = place_pose(grasp.X_GO, target)
    assert (X_WG @ grasp.X_GO).IsNearlyEqualTo(target, 1e-12)
    cands = place_candidates(grasp.X_GO, target, obj.shape, lift=0.1)
    assert len(cands) == 2  # a non-square box looks the same turned by pi only
    assert [c.score for c in cands] == sorted((c.score for c in cands), reverse=True)
    for c in cands:
        assert (c.X_WG @ grasp.X_GO).IsNearlyEqualTo(c.X_WO, 1e-12)
        assert np.allclose(c.X_WO.translation(), target.translation())
        assert np.allclose(c.X_WPre.translation() - c.X_WG.translation(), [0, 0, 0.1])


def test_stack_target_rests_on_the_support():
    support = BoxShape(size=(0.05, 0.05, 0.05))
    X_WS = RigidTransform(RotationMatrix.MakeZRotation(0.5), [0.0, 0.1, TABLE_TOP + 0.025])
    held = BoxShape(size=(0.04, 0.04, 0.04))
    X_WO = stack_target(X_WS, support, held, clearance=0.0)
    assert X_WO.translation()[2] - 0.02 == pytest.approx(TABLE_TOP + 0.05)
    assert np.allclose(X_WO.rotation().matrix(), X_WS.rotation().matrix(), atol=1e-12)
    bowl = BowlShape(radius=0.07, base_radius=0.045, height=0.05, wall=0.006)
    in_bowl = stack_target(RigidTransform([0.2, 0.0, TABLE_TOP]), bowl, held, clearance=0.0)
    assert in_bowl.translation()[2] == pytest.approx(TABLE_TOP + 0.006 + 0.02)


def test_pose_to_transform_matches_pose_matrix():
    pose = Pose(xyz=(0.1, 0.2, 0.8), rpy=(0.1, -0.2, 0.7))
    obj = SceneObject(name="o", shape=SphereShape(radius=0.02), pose=pose)
    assert np.allclose(pose_to_transform(obj).GetAsMatrix4(), pose.matrix())


def test_pot_handles_are_grasped_from_outside_horizontally():
    from bicoord_drake.models.objects import PotShape, SceneObject
    from bicoord_drake.planning.grasps import grasp_candidates, pot_handle_grasps

    gripper = get_embodiment("aloha_viperx").arm.gripper
    pot = PotShape(radius=0.07, height=0.08)
    yaw = 0.3
    X_WO = RigidTransform(RollPitchYaw(0, 0, yaw), [0.1, -0.1, TABLE_TOP])
    for sign in (-1.0, 1.0):
        grasps = pot_handle_grasps(X_WO, pot, gripper, handles=(sign,))
        assert grasps
        outward = sign * X_WO.rotation().col(0)
        handle = X_WO @ RigidTransform(pot.handle_pose(sign).matrix())
        for g in grasps:
            assert g.kind == "handle"
            assert g.approach @ outward < -0.99  # toward the pot's axis, horizontal
            assert abs(g.finger_axis[2]) > 0.99  # pads on the plate's top and bottom
            assert g.width == pytest.approx(pot.handle_thickness)
            # the TCP on the handle, not inside the pot
            p = g.X_WG.translation()
            assert abs(p[2] - handle.translation()[2]) < 1e-9
            assert np.linalg.norm(p[:2] - X_WO.translation()[:2]) > pot.radius
            assert (X_WO @ g.X_OG).IsNearlyEqualTo(g.X_WG, 1e-9)
    obj = SceneObject(name="pot", shape=pot, pose=Pose(xyz=(0.1, -0.1, TABLE_TOP)))
    assert {g.kind for g in grasp_candidates(obj, gripper)} == {"handle"}
    with pytest.raises(ValueError):
        pot_handle_grasps(X_WO, pot, gripper, handles=(0.0,))


def test_pot_handles_grasped_across_their_width_keep_the_pads_on_its_sides():
    from bicoord_drake.models.objects import PotShape
    from bicoord_drake.planning.grasps import ACROSS_PITCH, pot_handle_grasps_across

    gripper = get_embodiment("franka_pair").arm.gripper
    pot = PotShape(radius=0.06, height=0.09)
    X_WO = RigidTransform(RollPitchYaw(0, 0, 0.3), [0.1, -0.1, TABLE_TOP])
    for sign in (-1.0, 1.0):
        grasps = pot_handle_grasps_across(X_WO, pot, gripper, handles=(sign,))
        assert len(grasps) == 2
        outward = sign * X_WO.rotation().col(0)
        for g in grasps:
            # the jaw across the plate's width, horizontal; the approach toward the axis,
            # tilted ACROSS_PITCH down
            assert abs(g.finger_axis @ X_WO.rotation().col(1)) > 0.999
            assert g.width == pytest.approx(pot.handle_width)
            assert g.approach @ outward == pytest.approx(-np.cos(ACROSS_PITCH))
            assert g.approach[2] == pytest.approx(-np.sin(ACROSS_PITCH))
            assert (X_WO @ g.X_OG).IsNearlyEqualTo(g.X_WG, 1e-9)


def test_turned_onto_takes_u_onto_v_by_the_smallest_turn():
    R = RotationMatrix(RollPitchYaw(0.3, -0.2, 1.1))
    u = np.array([0.0, 0.0, 1.0])
    v = np.array([0.6, 0.0, 0.8])
    turned = turned_onto(R, u, v)
    turn = turned @ R.inverse()  # the rotation applied
    np.testing.assert_allclose(turn.multiply(u), v, atol=1e-12)
    # the smallest turn is about u x v, by the angle between them; it leaves u x v fixed
    axis = np.cross(u, v) / np.linalg.norm(np.cross(u, v))
    np.testing.assert_allclose(turn.multiply(axis), axis, atol=1e-12)
    angle = AngleAxis(turn.ToQuaternion()).angle()
    assert angle == pytest.approx(np.arccos(0.8), abs=1e-12)


def test_turned_onto_leaves_parallel_vectors_unturned():
    R = RotationMatrix(RollPitchYaw(0.1, 0.2, 0.3))
    z = np.array([0.0, 0.0, 1.0])
    assert np.array_equal(turned_onto(R, z, z).matrix(), R.matrix())
