"""The ``aloha_viperx`` embodiment (the default robot): two ViperX 300 s arms side by side
behind the table facing +y, the ALOHA / AgileX layout.

Joint offsets, axes, limits, masses and principal inertias follow the public ViperX 300 s model;
the actuator limits are the DYNAMIXEL servos' datasheet values (cited below); the collision and
visual primitives, the base poses, the home and the PD gains are this project's own choices.
The schema these numbers fill in is :mod:`bicoord_drake.models.embodiment`.
"""

from __future__ import annotations

import numpy as np

from bicoord_drake.models.embodiment import (
    ArmSpec,
    Embodiment,
    GripperSpec,
    JointSpec,
    LinkSpec,
    WristFlip,
)
from bicoord_drake.models.geometry import Pose, Primitive, segment

#: Actuator limits of the ViperX 300 s (Interbotix "ViperX-300 6DOF" specifications,
#: https://docs.trossenrobotics.com/interbotix_xsarms_docs/specifications/vx300s.html): waist,
#: forearm roll and wrist angle are one DYNAMIXEL XM540-W270 each, shoulder and elbow two each
#: (a servo and its shadow on one axis: twice the torque), wrist rotate an XM430-W350. The arms
#: run at 12 V (the ALOHA / AgileX supply). Stall torque at 12 V, the most a servo can give:
#: XM540-W270 10.6 N m (ROBOTIS e-Manual, https://emanual.robotis.com/docs/en/dxl/x/xm540-w270/),
#: XM430-W350 4.1 N m (https://emanual.robotis.com/docs/en/dxl/x/xm430-w350/). The effort
#: limit clips everything the actuator outputs: PD plus gravity feed-forward.
XM540_STALL = 10.6
XM430_STALL = 4.1
#: Joint speed limit, rad/s, used by the planner: just under the XM540-W270's no-load speed at
#: 12 V, 30 rev/min = pi rad/s (the XM430-W350 turns at up to 46 rev/min = 4.8 rad/s;
#: Interbotix's vx300s description caps every joint at pi rad/s). 3.14 is the value the experts'
#: plans were made with.
ARM_SPEED = 3.14
#: Home: each arm in its own vertical plane, its waist then turned this far outward (rad), so
#: the TCPs start 0.606 m apart - the reference robot's start distance (aloha-agilex in RoboTwin
#: 2.0 / BiCoord-Bench; the evidence is in docs/metrics.md) - instead of the bases' 0.50 m.
#: Solved from the forward kinematics (tests/models/test_home_start_distance.py checks it).
HOME_SPREAD = 0.2188


def aloha_viperx() -> Embodiment:
    """Two ViperX 300s arms behind the table, bases 0.5 m apart, facing +y.

    Joint offsets, axes, limits, masses and principal inertias follow the public ViperX 300s
    model; collision and visual geometry are this project's own primitives.
    """
    dark, grey = (0.12, 0.12, 0.14, 1.0), (0.55, 0.56, 0.6, 1.0)

    def j(name, parent, child, xyz, axis, lo, hi, effort, kp, kd, damping, vel=ARM_SPEED):
        return JointSpec(
            name=name,
            parent=parent,
            child=child,
            origin=Pose(xyz=xyz),
            axis=axis,
            lower=lo,
            upper=hi,
            velocity_limit=vel,
            acceleration_limit=8.0,
            jerk_limit=80.0,
            effort_limit=effort,
            kp=kp,
            kd=kd,
            damping=damping,
        )

    base = LinkSpec(
        name="base_link",
        mass=0.969,
        com=(-0.0534, 0.0, 0.0206),
        inertia_diag=(0.00602, 0.00717, 0.0017),
        collision=(Primitive(kind="cylinder", size=(0.055, 0.07), pose=Pose(xyz=(0, 0, 0.035))),),
        visual=(
            Primitive(kind="cylinder", size=(0.055, 0.07), pose=Pose(xyz=(0, 0, 0.035))),
            Primitive(kind="box", size=(0.14, 0.12, 0.012), pose=Pose(xyz=(-0.02, 0, 0.006))),
        ),
        color=dark,
    )
    shoulder = LinkSpec(
        name="shoulder_link",
        mass=0.798614,
        com=(0.0, 0.0, 0.0116),
        inertia_diag=(0.00120156, 0.00113744, 0.0009388),
        collision=(Primitive(kind="cylinder", size=(0.045, 0.05), pose=Pose(xyz=(0, 0, 0.02))),),
        visual=(Primitive(kind="cylinder", size=(0.045, 0.05), pose=Pose(xyz=(0, 0, 0.02))),),
        color=dark,
    )
    upper_arm = LinkSpec(
        name="upper_arm_link",
        mass=0.792592,
        com=(0.0171605, 0.0, 0.191323),
        inertia_diag=(0.00911338, 0.008925, 0.000759317),
        collision=(
            segment("capsule", (0, 0, 0.0), (0, 0, 0.3), 0.032),
            segment("capsule", (0, 0, 0.3), (0.05955, 0, 0.3), 0.03),
        ),
        visual=(
            segment("capsule", (0, 0, 0.0), (0, 0, 0.3), 0.032),
            segment("capsule", (0, 0, 0.3), (0.05955, 0, 0.3), 0.03),
            segment("cylinder", (0, -0.04, 0), (0, 0.04, 0), 0.036),
        ),
        color=dark,
    )
    upper_forearm = LinkSpec(
        name="upper_forearm_link",
        mass=0.322228,
        com=(0.107963, 0.0, 0.0),
        inertia_diag=(0.00144107, 0.00134228, 0.000152047),
        collision=(segment("capsule", (0.03, 0, 0), (0.2, 0, 0), 0.028),),
        visual=(
            segment("capsule", (0.0, 0, 0), (0.2, 0, 0), 0.028),
            segment("cylinder", (0, -0.035, 0), (0, 0.035, 0), 0.032),
        ),
        color=grey,
    )
    lower_forearm = LinkSpec(
        name="lower_forearm_link",
        mass=0.414823,
        com=(0.0374395, 0.0, 0.0),
        inertia_diag=(0.0005911, 0.000546493, 0.000155707),
        collision=(segment("capsule", (0.02, 0, 0), (0.085, 0, 0), 0.026),),
        visual=(segment("capsule", (0.0, 0, 0), (0.085, 0, 0), 0.026),),
        color=dark,
    )
    wrist = LinkSpec(
        name="wrist_link",
        mass=0.115395,
        com=(0.04236, 0.0, 0.010577),
        inertia_diag=(4.63051e-05, 4.32576e-05, 2.10295e-05),
        collision=(segment("capsule", (0.0, 0, 0), (0.045, 0, 0), 0.024),),
        visual=(
            segment("capsule", (0.0, 0, 0), (0.05, 0, 0), 0.024),
            segment("cylinder", (0, -0.03, 0), (0, 0.03, 0), 0.026),
        ),
        color=grey,
    )
    gripper_link = LinkSpec(
        name="gripper_link",
        mass=0.251652,
        com=(0.0395662, 0.0, 0.00400649),
        inertia_diag=(0.000689546, 0.000650316, 0.000468142),
        collision=(
            Primitive(kind="box", size=(0.045, 0.06, 0.05), pose=Pose(xyz=(0.03, 0, 0))),
            Primitive(kind="box", size=(0.016, 0.13, 0.03), pose=Pose(xyz=(0.06, 0, 0))),
        ),
        visual=(
            Primitive(kind="box", size=(0.045, 0.06, 0.05), pose=Pose(xyz=(0.03, 0, 0))),
            Primitive(kind="box", size=(0.016, 0.13, 0.03), pose=Pose(xyz=(0.06, 0, 0))),
        ),
        color=dark,
    )
    gripper = GripperSpec(
        finger_origin_x=0.0687,
        finger_min=0.004,
        finger_max=0.045,
        force_limit=30.0,
        finger_kp=3000.0,
        finger_kd=20.0,
        finger_mass=0.034,
        finger_length=0.075,
        finger_height=0.022,
        finger_thickness=0.008,
        pad_length=0.035,
        pad_thickness=0.004,
        pad_height=0.022,
        pad_friction=1.0,
        pad_modulus=2e6,
    )
    pi = 3.14158
    joints = (
        j(
            "waist",
            "base_link",
            "shoulder_link",
            (0, 0, 0.079),
            (0, 0, 1),
            -pi,
            pi,
            XM540_STALL,
            1000,
            40,
            0.5,
        ),
        j(
            "shoulder",
            "shoulder_link",
            "upper_arm_link",
            (0, 0, 0.04805),
            (0, 1, 0),
            -1.85005,
            1.25664,
            2 * XM540_STALL,
            2000,
            60,
            0.5,
        ),
        j(
            "elbow",
            "upper_arm_link",
            "upper_forearm_link",
            (0.05955, 0, 0.3),
            (0, 1, 0),
            -1.76278,
            1.6057,
            2 * XM540_STALL,
            1500,
            30,
            0.5,
        ),
        j(
            "forearm_roll",
            "upper_forearm_link",
            "lower_forearm_link",
            (0.2, 0, 0),
            (1, 0, 0),
            -pi,
            pi,
            XM540_STALL,
            300,
            3,
            0.1,
        ),
        j(
            "wrist_angle",
            "lower_forearm_link",
            "wrist_link",
            (0.1, 0, 0),
            (0, 1, 0),
            -1.8675,
            2.23402,
            XM540_STALL,
            300,
            3,
            0.1,
        ),
        j(
            "wrist_rotate",
            "wrist_link",
            "gripper_link",
            (0.069744, 0, 0),
            (1, 0, 0),
            -pi,
            pi,
            XM430_STALL,
            150,
            1,
            0.05,
        ),
    )
    arm = ArmSpec(
        base=base,
        links=(shoulder, upper_arm, upper_forearm, lower_forearm, wrist, gripper_link),
        joints=joints,
        gripper=gripper,
        gripper_link=gripper_link,
    )
    half_pi = float(np.pi / 2)
    return Embodiment(
        name="aloha_viperx",
        arm=arm,
        left_base=Pose(xyz=(-0.25, -0.42, 0.75), rpy=(0, 0, half_pi)),
        right_base=Pose(xyz=(0.25, -0.42, 0.75), rpy=(0, 0, half_pi)),
        home=(0.0, -0.96, 1.16, 0.0, 0.4, 0.0),
        home_spread=HOME_SPREAD,
        closed_form_ik="spherical_wrist_6r",
        # the right arm mirrors the waist, the forearm roll and the wrist rotation
        reach_pose=((-0.35, 0.05, 0.35, 0.0, 1.0, 0.0), (0.35, 0.05, 0.35, 0.0, 1.0, 0.0)),
        wrist_flip=WristFlip(first_roll=3, pitch=4, second_roll=5),
    )
