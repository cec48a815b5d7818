"""A friction grasp in physics: close on a 4 cm cube, lift 10 cm, hold 2 s, slip < 2 mm."""

import numpy as np
import pytest
from pydrake.all import RigidTransform

from bicoord_drake.config import StationConfig
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station
from tests.sim.kinematics import R_TOP_DOWN, joint_ramp, solve_arm_ik


def _pose_in_gripper(tcp: np.ndarray, obj: np.ndarray) -> np.ndarray:
    from pydrake.all import Quaternion

    X_WT = RigidTransform(Quaternion(tcp[3:]), tcp[:3])
    return X_WT.inverse().multiply(obj[:3])


@pytest.mark.parametrize("side,x", [("left", -0.2), ("right", 0.15)])
def test_cube_lift_and_hold_without_slip(side, x):
    scene = Scene(name="grasp", objects=(cube("cube", x, -0.1, size=0.04, mass=0.05),))
    station = build_station(scene, StationConfig(render=False))
    sim = Simulation(station)
    home = station.embodiment.home_action()
    k = 0 if side == "left" else 7
    q_home = np.asarray(station.embodiment.home)  # IK seed: the in-plane home (no spread)
    centre = np.array([x, -0.1, 0.77])
    q_pre = solve_arm_ik(station, side, RigidTransform(R_TOP_DOWN, centre + [0, 0, 0.10]), q_home)
    q_grasp = solve_arm_ik(station, side, RigidTransform(R_TOP_DOWN, centre + [0, 0, 0.004]), q_pre)
    q_lift = solve_arm_ik(
        station, side, RigidTransform(R_TOP_DOWN, centre + [0, 0, 0.104]), q_grasp, opening=0.0
    )

    def run(q_targets, opening, steps):
        for q in joint_ramp(sim.joint_state()[k : k + 6], q_targets, steps):
            a = home.copy()
            a[k : k + 6], a[k + 6] = q, opening
            sim.step(a)

    run(q_pre, 1.0, 20)
    run(q_grasp, 1.0, 15)
    run(q_grasp, 0.0, 10)  # close: fingers stop at the cube under the force limit
    z0 = sim.object_poses()["cube"][2]
    run(q_lift, 0.0, 15)
    run(q_lift, 0.0, 5)  # settle
    start = _pose_in_gripper(sim.tcp_pose(side), sim.object_poses()["cube"])
    run(q_lift, 0.0, 30)  # hold 2 s
    end = _pose_in_gripper(sim.tcp_pose(side), sim.object_poses()["cube"])
    lifted = sim.object_poses()["cube"][2] - z0
    assert lifted == pytest.approx(0.10, abs=0.01), f"cube lifted {lifted:.3f} m"
    slip = np.linalg.norm(end - start)
    assert slip < 0.002, f"cube slipped {slip * 1000:.2f} mm in the gripper during the hold"
    # the jaws are stopped by the cube, not closed: the measured opening matches 4 cm
    opening = sim.joint_state()[k + 6]
    gap = 2 * station.embodiment.arm.gripper.finger_position(opening)
    assert gap == pytest.approx(0.04, abs=0.004)


def test_finger_contacts_report_the_grasping_side():
    scene = Scene(name="grasp", objects=(cube("cube", -0.2, -0.1), cube("free", 0.2, 0.1)))
    station = build_station(scene, StationConfig(render=False))
    sim = Simulation(station)
    home = station.embodiment.home_action()
    centre = np.array([-0.2, -0.1, 0.774])
    q_pre = solve_arm_ik(
        station,
        "left",
        RigidTransform(R_TOP_DOWN, centre + [0, 0, 0.1]),
        np.asarray(station.embodiment.home),
    )
    q_grasp = solve_arm_ik(station, "left", RigidTransform(R_TOP_DOWN, centre), q_pre)
    for q, opening, n in ((q_pre, 1.0, 20), (q_grasp, 1.0, 15), (q_grasp, 0.0, 10)):
        for qi in joint_ramp(sim.joint_state()[:6], q, n):
            a = home.copy()
            a[:6], a[6] = qi, opening
            sim.step(a)
    touching = sim.finger_contacts()
    assert touching == {"cube": {"left"}, "free": set()}
