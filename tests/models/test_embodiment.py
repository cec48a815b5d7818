"""The robot model: it loads, its kinematics match the ViperX 300s, bad descriptions are refused."""

import numpy as np
import pytest
from pydantic import ValidationError
from pydrake.all import MultibodyPlant

from bicoord_drake.models.embodiment import (
    SIDES,
    Embodiment,
    arm_sdf,
    other_side,
)
from bicoord_drake.models.geometry import pose_matrix
from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.models.viperx import aloha_viperx
from bicoord_drake.sim.station import add_robot


def _axis_rotation(axis, angle):
    axis = np.asarray(axis, float)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    return T


def reference_tcp(embodiment, side, q):
    """Forward kinematics straight from the description, independent of SDFormat and Drake."""
    base = embodiment.base_pose(side)
    T = pose_matrix(base.xyz, base.rpy)
    for joint, angle in zip(embodiment.arm.joints, q, strict=True):
        T = T @ pose_matrix(joint.origin.xyz, joint.origin.rpy) @ _axis_rotation(joint.axis, angle)
    return (T @ pose_matrix((embodiment.arm.gripper.tcp_x, 0, 0), (0, 0, 0)))[:3, 3]


@pytest.fixture(scope="module")
def robot():
    e = aloha_viperx()
    plant = MultibodyPlant(0.0)
    arms = add_robot(plant, e)
    plant.Finalize()
    return e, plant, arms


def test_two_arms_load_with_six_joints_and_two_fingers_each(robot):
    e, plant, arms = robot
    assert plant.num_positions() == 16
    for inst in arms.values():
        assert plant.num_positions(inst) == 8
        assert len(plant.GetJointActuatorIndices(inst)) == 7  # 6 joints + one coupled finger


@pytest.mark.parametrize("side", SIDES)
def test_tcp_at_home_matches_reference_kinematics(robot, side):
    e, plant, arms = robot
    context = plant.CreateDefaultContext()
    X = plant.GetFrameByName("tcp", arms[side]).CalcPoseInWorld(context)
    np.testing.assert_allclose(X.translation(), reference_tcp(e, side, e.home_of(side)), atol=1e-9)
    # home: in front of its base, above the table, on its own side of the table
    base = np.array(e.base_pose(side).xyz)
    assert X.translation()[1] > base[1] + 0.15
    assert 0.85 < X.translation()[2] < 1.0
    assert np.sign(X.translation()[0]) == (-1 if side == "left" else 1)


def test_tcp_matches_reference_at_random_configurations(robot):
    e, plant, arms = robot
    context = plant.CreateDefaultContext()
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rng.uniform(e.arm.lower, e.arm.upper)
        plant.SetPositions(context, arms["right"], np.concatenate([q, [0.02, 0.02]]))
        X = plant.GetFrameByName("tcp", arms["right"]).CalcPoseInWorld(context)
        np.testing.assert_allclose(X.translation(), reference_tcp(e, "right", q), atol=1e-9)


def test_tcp_is_midway_between_the_finger_pads(robot):
    e, plant, arms = robot
    context = plant.CreateDefaultContext()
    inst = arms["left"]
    plant.SetPositions(context, inst, np.concatenate([e.home_of("left"), [0.03, 0.03]]))
    X_WT = plant.GetFrameByName("tcp", inst).CalcPoseInWorld(context)
    pads = []
    for finger in ("left_finger", "right_finger"):
        X_WF = plant.GetFrameByName(finger, inst).CalcPoseInWorld(context)
        pads.append(X_WF.translation())
    g = e.arm.gripper
    # finger frames lie on the pads' inner surfaces at the finger root; the pad centre is
    # (finger_length - pad_length / 2) further along the approach axis
    centre = np.mean(pads, axis=0) + X_WT.rotation().col(0) * (g.finger_length - g.pad_length / 2)
    np.testing.assert_allclose(X_WT.translation(), centre, atol=1e-9)
    assert np.linalg.norm(pads[0] - pads[1]) == pytest.approx(0.06, abs=1e-9)


def test_visual_meshes_are_obj_with_normals():
    sdf = arm_sdf(aloha_viperx(), "left_arm")
    uris = [part.split("</uri>")[0] for part in sdf.split("<uri>file://")[1:]]
    assert len(uris) >= 8
    for path in uris:
        text = open(path).read()
        assert "\nvn " in text and "\nf " in text, path


def test_unknown_embodiment_lists_valid_names():
    with pytest.raises(ValueError, match="aloha_viperx"):
        get_embodiment("panda_pair")


def test_home_outside_joint_limits_is_refused():
    fields = aloha_viperx().model_dump()
    fields["home"] = (0.0, -3.0, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValidationError, match="joint limits"):
        Embodiment(**fields)


def test_gripper_opening_maps_onto_finger_travel():
    g = aloha_viperx().arm.gripper
    assert g.finger_position(0.0) == pytest.approx(g.finger_min)
    assert g.finger_position(1.0) == pytest.approx(g.finger_max)
    assert g.opening(g.finger_position(0.37)) == pytest.approx(0.37)
    assert 2 * g.finger_max >= 0.085  # opens wider than the largest task cube side


def test_actuators_have_the_servo_datasheet_torques(robot):
    """XM540-W270 10.6 N m at 12 V (shoulder and elbow: two servos), XM430-W350 4.1 N m."""
    e, plant, arms = robot
    expected = {
        "waist": 10.6,
        "shoulder": 21.2,
        "elbow": 21.2,
        "forearm_roll": 10.6,
        "wrist_angle": 10.6,
        "wrist_rotate": 4.1,
    }
    for inst in arms.values():
        for i in plant.GetJointActuatorIndices(inst):
            actuator = plant.get_joint_actuator(i)
            if actuator.joint().name() in expected:
                assert actuator.effort_limit() == pytest.approx(expected[actuator.joint().name()])
    assert all(3.1 < j.velocity_limit <= np.pi for j in e.arm.joints)  # 30 rev/min = pi rad/s


def test_each_joint_holds_the_arm_stretched_out_horizontally(robot):
    """Gravity torque of the unloaded arm, reaching straight forward, within every limit."""
    e, plant, arms = robot
    context = plant.CreateDefaultContext()
    q = np.array([0.0, np.pi / 2 - 0.02, -np.pi / 2 + 0.02, 0.0, 0.0, 0.0])  # shoulder flat
    plant.SetPositions(context, arms["left"], np.concatenate([q, [0.02, 0.02]]))
    tau = -plant.CalcGravityGeneralizedForces(context)
    start = plant.GetJointByName("waist", arms["left"]).velocity_start()
    limits = np.array([j.effort_limit for j in e.arm.joints])
    assert np.all(np.abs(tau[start : start + 6]) < limits)
    assert abs(tau[start + 1]) > 0.25 * limits[1]  # the pose really loads the shoulder


def test_arm_sdf_is_reused_but_never_names_a_missing_mesh(tmp_path, monkeypatch):
    import re
    from pathlib import Path

    from bicoord_drake.models.embodiment import arm_sdf

    def meshes(sdf: str) -> list[Path]:
        return [Path(p) for p in re.findall(r"<uri>file://([^<]+)</uri>", sdf)]

    embodiment = get_embodiment("aloha_viperx")
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "a"))
    first = arm_sdf(embodiment, "left_arm")
    assert arm_sdf(embodiment, "left_arm") is first  # reused, not made again
    assert meshes(first) and all(p.is_relative_to(tmp_path / "a") for p in meshes(first))
    for p in meshes(first):
        p.unlink()
    again = arm_sdf(embodiment, "left_arm")
    assert again == first and all(p.exists() for p in meshes(again))
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "b"))
    moved = arm_sdf(embodiment, "left_arm")
    assert all(p.is_relative_to(tmp_path / "b") and p.exists() for p in meshes(moved))


def test_other_side_swaps_the_arms_and_rejects_other_names():
    assert other_side("left") == "right"
    assert other_side("right") == "left"
    with pytest.raises(ValueError, match="left"):
        other_side("middle")


def test_the_schema_module_builds_no_robot():
    """embodiment.py is the schema and the SDFormat generator; every robot's numbers live in
    a module of its own (models/viperx.py, models/franka.py)."""
    from bicoord_drake.models import embodiment
    from bicoord_drake.models.robots import EMBODIMENTS

    assert all(build.__module__ != embodiment.__name__ for build in EMBODIMENTS.values())
    builders = [
        name
        for name, value in vars(embodiment).items()
        if callable(value) and getattr(value, "__annotations__", {}).get("return") == "Embodiment"
    ]
    assert not builders
    assert get_embodiment("aloha_viperx") == aloha_viperx()
