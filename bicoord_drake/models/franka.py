"""The ``franka_pair`` embodiment: two Franka Emika Panda arms (7-DoF) with the Franka Hand.

Every number below is a published fact about the Panda, cited where it is used:

- Kinematics: Franka's modified (Craig) Denavit-Hartenberg table, "Robot and interface
  specifications", https://frankaemika.github.io/docs/control_parameters.html (the same joint
  origins as ``franka_description/robots/common/franka_arm.xacro`` in
  https://github.com/frankaemika/franka_ros and MuJoCo Menagerie's
  ``franka_emika_panda/panda.xml``). Row i takes link i-1's frame to link i's:
  ``Rx(alpha) Tx(a) Rz(q_i) Tz(d)``; the flange is ``Tz(0.107)`` past link 7.
- Limits: the same page ("Limits for Panda") and ``franka_description/robots/panda/
  joint_limits.yaml``: positions, velocities (2.175 rad/s joints 1-4, 2.61 rad/s joints 5-7),
  accelerations, jerks and torques (87 N m joints 1-4, 12 N m joints 5-7).
- Link masses, centres of mass and inertia tensors (about the COM, in the link frames):
  ``franka_description/robots/common/inertial.yaml`` (franka_ros), which quotes the identified
  parameters of C. Gaz, M. Cognetti, A. Oliva, P. Robuffo Giordano, A. De Luca, "Dynamic
  Identification of the Franka Emika Panda Robot With Retrieval of Feasible Parameters Using
  Penalty-Based Optimization", IEEE RA-L 4(4), 2019; Menagerie's ``panda.xml`` uses the same.
- Franka Hand: mounted on the flange turned by -45 deg about its axis, fingers riding 0.0584 m
  out, TCP 0.1034 m out (``franka_description/robots/common/franka_hand.xacro``); hand 0.73 kg
  and fingers 0.015 kg with the inertias of ``inertial.yaml``; 80 mm stroke (each finger 0 to
  40 mm), 70 N continuous grasping force (Franka Emika Panda datasheet, "Franka Hand").

This project's own choices: the collision and visual primitives, the base poses, the home
configuration, the PD gains and the pads' contact properties.

Frames. The links ``link0`` (base) to ``link6`` carry Franka's DH frames, so their inertias are
used as published. Link 7 and the hand are one rigid body, ``hand`` (the gripper link; the
Franka Hand is bolted to the flange), whose frame follows this project's gripper convention: its
origin is the flange centre, x along the fingers (Franka's hand z), y the direction the left
finger opens (Franka's hand -y; the fingers are symmetric), z = x cross y (Franka's hand x).
Joint 7 turns it about its x. With y = the hand's -y, Franka's ready pose (q7 = pi / 4) holds
the gripper as the ViperX holds it at home (y = world -x, z away from the robot), with joint 7
able to turn the hand 2.1 rad one way and 3.7 rad the other: every top-down grasp yaw is a
quarter turn or less from a joint-7 angle within the limits.
"""

from __future__ import annotations

import numpy as np

from bicoord_drake.models.embodiment import (
    ArmSpec,
    Embodiment,
    GripperSpec,
    JointSpec,
    LinkSpec,
)
from bicoord_drake.models.geometry import Pose, Primitive, Vec3, pose_matrix, segment

# --------------------------------------------------------------------------------------------
# Published data
# --------------------------------------------------------------------------------------------

#: Franka's DH table (a, d, alpha) per joint, modified convention: joint i's frame is
#: ``Rx(alpha_i) Tx(a_i) Rz(q_i) Tz(d_i)`` in joint i-1's (control_parameters.html).
PANDA_DH: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -np.pi / 2),
    (0.0, 0.316, np.pi / 2),
    (0.0825, 0.0, np.pi / 2),
    (-0.0825, 0.384, -np.pi / 2),
    (0.0, 0.0, np.pi / 2),
    (0.088, 0.0, np.pi / 2),
)
#: Flange: d = 0.107 m along joint 7's axis (the DH table's "Flange" row).
FLANGE_D = 0.107
#: Joint position limits, rad (control_parameters.html "Limits for Panda"; joint_limits.yaml).
Q_MIN = (-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973)
Q_MAX = (2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973)
#: Joint velocity, acceleration and jerk limits (control_parameters.html), rad/s, /s^2, /s^3.
DQ_MAX = (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)
DDQ_MAX = (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)
DDDQ_MAX = (7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0)
#: Joint torque limits, N m (control_parameters.html; joint_limits.yaml).
TAU_MAX = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)

#: Identified inertial parameters (Gaz et al. 2019, as in franka_description's inertial.yaml):
#: link -> (mass kg, COM m, (ixx, iyy, izz), (ixy, ixz, iyz)) in the link's DH frame.
PANDA_INERTIA: dict[str, tuple[float, Vec3, Vec3, Vec3]] = {
    "link0": (0.629769, (-0.041018, -0.00014, 0.049974), (0.00315, 0.00388, 0.004285),
              (8.2904e-07, 0.00015, 8.2299e-06)),
    "link1": (4.970684, (0.003875, 0.002081, -0.04762), (0.70337, 0.70661, 0.009117),
              (-0.000139, 0.006772, 0.019169)),
    "link2": (0.646926, (-0.003141, -0.02872, 0.003495), (0.007962, 0.02811, 0.025995),
              (-0.003925, 0.010254, 0.000704)),
    "link3": (3.228604, (0.027518, 0.039252, -0.066502), (0.037242, 0.036155, 0.01083),
              (-0.004761, -0.011396, -0.012805)),
    "link4": (3.587895, (-0.05317, 0.104419, 0.027454), (0.025853, 0.019552, 0.028323),
              (0.007796, -0.001332, 0.008641)),
    "link5": (1.225946, (-0.011953, 0.041065, -0.038437), (0.035549, 0.029474, 0.008627),
              (-0.002117, -0.004037, 0.000229)),
    "link6": (1.666555, (0.060149, -0.014117, -0.010517), (0.001964, 0.004354, 0.005433),
              (0.000109, -0.001158, 0.000341)),
    "link7": (0.735522, (0.010517, -0.004252, 0.061597), (0.012516, 0.010027, 0.004815),
              (-0.000428, -0.001196, -0.000741)),
    # the Franka Hand, in Franka's hand frame (flange turned -45 deg about z)
    "hand": (0.73, (-0.01, 0.0, 0.03), (0.001, 0.0025, 0.0017), (0.0, 0.0, 0.0)),
}  # fmt: skip
#: Finger mass, kg (inertial.yaml).
FINGER_MASS = 0.015
#: Hand geometry (franka_hand.xacro): hand frame = flange turned by -pi/4 about z; fingers
#: 0.0584 m out along the hand z; TCP ("hand_tcp", between the fingertip pads) 0.1034 m out.
HAND_YAW = -np.pi / 4
FINGER_ORIGIN = 0.0584
HAND_TCP = 0.1034
#: Franka Hand (datasheet): 80 mm total stroke, each finger 0-40 mm (finger joint limits
#: 0-0.04 m in franka_hand.xacro); 70 N continuous grasping force; finger speed limit 0.2 m/s
#: (franka_hand.xacro).
FINGER_TRAVEL = 0.04
GRASP_FORCE = 70.0
FINGER_SPEED = 0.2

# --------------------------------------------------------------------------------------------
# This project's choices
# --------------------------------------------------------------------------------------------

#: Base poses: both bases face +y (at q = 0 joint 1 points the arm along +y) at table-top
#: height, 0.30 m either side of the centre line, their joint-1 axes 0.20 m behind the table's
#: back edge (y = -0.35). A Panda with its gripper pointing straight down reaches 0.79 m from
#: its joint-1 axis, but close to its base only with the elbow folded to its limit and the hand
#: against its own column: at y = -0.37 (the first choice, whole-table reach) the experts'
#: grasps 0.12-0.25 m in front of a base (balance_roller's roller lies at y = -0.25) found no
#: collision-free IK, or only at joint limits from which a carry could not continue. From
#: y = -0.55 every task object (y in [-0.25, 0.16], |x| <= 0.44) is 0.3-0.75 m from the arm
#: that takes it, the arms together reach the table up to y = 0.15 over its whole width (10 cm
#: grid at 0.76 and 0.95 m) and both reach its centre; the back strip y > 0.15, which no task
#: uses, is out of reach.
BASE_X = 0.30
BASE_Y = -0.55
BASE_Z = 0.75
#: Home: each arm in its own vertical plane (q1 = q3 = q5 = 0: the two homes are mirror images,
#: the TCPs 0.600 m apart, within 6 mm of the reference robot's start distance of 0.606 m - see
#: docs/metrics.md - so no home_spread), the gripper pointing straight down (q6 = q2 - q4)
#: 0.40 m in front of its base (y = 0.03) at z = 1.05 m (0.30 m above the table; the hand's top
#: at 1.25 m), open; the
#: elbow folded as in Franka's ready pose. q7 = pi / 4 (also as in the ready pose) undoes the
#: -45 deg hand mount so that the fingers open along world x and the gripper frame is oriented
#: as the ViperX's at home (y = world -x, z = away from the robot).
HOME = (0.0, -0.42, 0.0, -2.58, 0.0, 2.16, np.pi / 4)
#: PD gains of the joint actuators (MuJoCo Menagerie's panda.xml position actuators: kp 4500,
#: 4500, 3500, 3500, 2000, 2000, 2000 N m/rad with kd = kp / 10) and viscous joint damping
#: (Menagerie's 1 N m s/rad).
KP = (4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0)
#: Snapshot pose (``scripts/render.py --pose reach``): the TCPs where the ViperX's reach pose
#: puts them, (-+0.12, -0.06, 0.865), pointing down (IK, rounded to 1 mrad).
REACH = (
    (-0.163, 0.287, -0.181, -2.321, 0.104, 2.591, 1.037),
    (0.204, 0.283, 0.14, -2.325, -0.059, 2.6, 0.829),
)
KD = tuple(k / 10 for k in KP)
JOINT_DAMPING = 1.0

WHITE = (0.9, 0.91, 0.92, 1.0)
BLACK = (0.22, 0.22, 0.24, 1.0)


def _dh_origin(a: float, d: float, alpha: float) -> Pose:
    """Joint i's frame in joint i-1's at q_i = 0: Rx(alpha) Tx(a) Tz(d)."""
    xyz = (a, -d * np.sin(alpha), d * np.cos(alpha))
    return Pose(xyz=tuple(_clean(v) for v in xyz), rpy=(float(alpha), 0.0, 0.0))


def _clean(v: float) -> float:
    return float(np.round(v, 12)) + 0.0


def _rpy(R: np.ndarray) -> Vec3:
    """Extrinsic roll-pitch-yaw of R = Rz(y) Ry(p) Rx(r) (away from pitch = +-pi/2)."""
    pitch = float(np.arcsin(np.clip(-R[2, 0], -1.0, 1.0)))
    if abs(np.cos(pitch)) < 1e-9:
        raise ValueError("gimbal lock")
    return (
        _clean(np.arctan2(R[2, 1], R[2, 2])),
        _clean(pitch),
        _clean(np.arctan2(R[1, 0], R[0, 0])),
    )


#: The gripper link frame G in Franka's hand frame H: x_G = z_H, y_G = -y_H, z_G = x_H.
R_HAND_G = pose_matrix((0, 0, 0), (np.pi, -np.pi / 2, 0))[:3, :3]
#: ... and in link 7's frame: the flange offset, the -45 deg hand mount, then R_HAND_G.
X_LINK7_G = pose_matrix((0, 0, FLANGE_D), (0, 0, HAND_YAW))
X_LINK7_G[:3, :3] = X_LINK7_G[:3, :3] @ R_HAND_G


def _tensor(diag: Vec3, offdiag: Vec3) -> np.ndarray:
    (ixx, iyy, izz), (ixy, ixz, iyz) = diag, offdiag
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def _hand_inertia() -> tuple[float, Vec3, Vec3, Vec3]:
    """Link 7 and the hand as one body in the gripper frame G: mass, COM, diag, products."""
    parts = []
    R_G7 = X_LINK7_G[:3, :3].T
    m, c, diag, off = PANDA_INERTIA["link7"]
    c_G = R_G7 @ (np.asarray(c) - X_LINK7_G[:3, 3])
    parts.append((m, c_G, R_G7 @ _tensor(diag, off) @ R_G7.T))
    m, c, diag, off = PANDA_INERTIA["hand"]
    R_GH = R_HAND_G.T
    parts.append((m, R_GH @ np.asarray(c), R_GH @ _tensor(diag, off) @ R_GH.T))
    mass = sum(p[0] for p in parts)
    com = sum(p[0] * p[1] for p in parts) / mass
    inertia = np.zeros((3, 3))
    for mi, ci, Ii in parts:
        d = ci - com
        inertia += Ii + mi * (d @ d * np.eye(3) - np.outer(d, d))
    return (
        mass,
        tuple(_clean(v) for v in com),
        (_clean(inertia[0, 0]), _clean(inertia[1, 1]), _clean(inertia[2, 2])),
        (_clean(inertia[0, 1]), _clean(inertia[0, 2]), _clean(inertia[1, 2])),
    )


def _link(name: str, shapes: tuple[Primitive, ...], color=WHITE) -> LinkSpec:
    mass, com, diag, off = PANDA_INERTIA[name] if name != "hand" else _hand_inertia()
    return LinkSpec(
        name=name,
        mass=mass,
        com=com,
        inertia_diag=diag,
        inertia_offdiag=off,
        collision=shapes,
        visual=shapes,
        color=color,
    )


def _cyl_z(radius: float, z0: float, z1: float, xy=(0.0, 0.0)) -> Primitive:
    return segment("cylinder", (*xy, z0), (*xy, z1), radius)


def panda_arm() -> ArmSpec:
    """One Panda with the Franka Hand (frames and data: see the module docstring).

    Collision primitives (link frames; at q = 0 the arm stands straight up, joint 2's axis
    along the base y, joints 4 and 6 along -y, the flange pointing down 0.088 m in front):
    the base plate and the joint-1 column, shoulder / elbow / wrist housings as cylinders on
    their joint axes, the upper arm and the forearm as capsules, the hand as a box with the
    fingers' standard plates and compliant pads."""
    r_big, r_mid, r_wrist = 0.062, 0.056, 0.048
    link0 = _link(
        "link0",
        (
            Primitive(kind="box", size=(0.23, 0.17, 0.1), pose=Pose(xyz=(-0.055, 0.0, 0.05))),
            _cyl_z(0.075, 0.0, 0.14),
        ),
    )
    # link1: the column on joint 1 up to the shoulder housing (joint 2's axis is link1's y)
    link1 = _link(
        "link1",
        (
            _cyl_z(r_big, -0.195, -0.05),
            segment("capsule", (0, -0.04, 0), (0, 0.04, 0), r_big),
        ),
    )
    # link2: the shoulder housing (on its z, joint 2) and the root of the upper arm (its -y)
    link2 = _link(
        "link2",
        (
            _cyl_z(r_big, -0.06, 0.06),
            segment("capsule", (0, -0.02, 0), (0, -0.14, 0), r_mid),
        ),
    )
    # link3: the upper arm along its z (joint 3) up to the elbow; the elbow housing on joint
    # 4's axis (link3's y) at x = 0.0825
    link3 = _link(
        "link3",
        (
            segment("capsule", (0, 0, -0.17), (0, 0, -0.03), r_mid),
            segment("capsule", (0.0825, -0.045, 0), (0.0825, 0.045, 0), r_mid),
        ),
    )
    # link4: the elbow housing (its z) and the forearm's root, going up (its +y) and back
    # to joint 5's axis at x = -0.0825
    link4 = _link(
        "link4",
        (
            _cyl_z(r_mid, -0.05, 0.05),
            segment("capsule", (0, 0.02, 0), (-0.0825, 0.13, 0), r_mid),
        ),
    )
    # link5: the forearm along its z (joint 5) below the wrist, and the slim strut beside
    # joint 6's housing
    link5 = _link(
        "link5",
        (
            segment("capsule", (0, 0, -0.27), (0, 0, -0.14), r_mid),
            segment("capsule", (0, 0.075, -0.2), (0, 0.075, -0.05), 0.025),
        ),
    )
    # link6: the wrist housing on joint 6 (its z) and the arm to joint 7 at x = 0.088
    link6 = _link(
        "link6",
        (
            _cyl_z(r_wrist, -0.07, 0.03),
            segment("capsule", (0.0, 0, 0.0), (0.088, 0, 0.0), 0.04),
        ),
        color=BLACK,
    )
    # hand = link 7 (a cylinder on the joint-7 axis behind the flange, i.e. along -x) + the
    # Franka Hand (a box 0.2 m long along the finger direction y)
    hand = _link(
        "hand",
        (
            segment("cylinder", (-0.155, 0, 0), (0.0, 0, 0), 0.044),
            Primitive(kind="box", size=(0.052, 0.2, 0.06), pose=Pose(xyz=(0.031, 0.0, 0.0))),
        ),
    )
    gripper = GripperSpec(
        finger_origin_x=FINGER_ORIGIN,
        finger_min=0.0,
        finger_max=FINGER_TRAVEL,
        force_limit=GRASP_FORCE,
        finger_kp=3000.0,  # as the ViperX's fingers (a project choice)
        finger_kd=20.0,
        finger_velocity_limit=FINGER_SPEED,
        finger_mass=FINGER_MASS,
        # fingertip 0.0545 m past the finger joint, pad 19 mm long: the pad centre is the
        # Franka TCP, 0.0584 + 0.0545 - 0.0095 = 0.1034 m out (franka_hand.xacro's rubber tip)
        finger_length=0.0545,
        finger_height=0.02,
        finger_thickness=0.01,
        pad_length=0.019,
        pad_thickness=0.003,
        pad_height=0.0175,
        pad_friction=1.0,
        pad_modulus=2e6,
        finger_color=WHITE,
        pad_color=BLACK,
    )
    assert abs(gripper.tcp_x - HAND_TCP) < 1e-12  # the TCP where Franka puts hand_tcp
    links = (link1, link2, link3, link4, link5, link6, hand)
    parents = ("link0", "link1", "link2", "link3", "link4", "link5", "link6")
    joints = []
    for i, (a, d, alpha) in enumerate(PANDA_DH):
        origin = _dh_origin(a, d, alpha)
        axis = (0.0, 0.0, 1.0)
        if i == 6:  # joint 7's child is the hand: its frame G sits at the flange
            X = pose_matrix(origin.xyz, origin.rpy) @ X_LINK7_G
            origin = Pose(xyz=tuple(_clean(v) for v in X[:3, 3]), rpy=_rpy(X[:3, :3]))
            axis = (1.0, 0.0, 0.0)
        joints.append(
            JointSpec(
                name=f"joint{i + 1}",
                parent=parents[i],
                child=links[i].name,
                origin=origin,
                axis=axis,
                lower=Q_MIN[i],
                upper=Q_MAX[i],
                velocity_limit=DQ_MAX[i],
                acceleration_limit=DDQ_MAX[i],
                jerk_limit=DDDQ_MAX[i],
                effort_limit=TAU_MAX[i],
                damping=JOINT_DAMPING,
                kp=KP[i],
                kd=KD[i],
            )
        )
    return ArmSpec(
        base=link0, links=links, joints=tuple(joints), gripper=gripper, gripper_link=hand
    )


def franka_pair() -> Embodiment:
    """Two Pandas with Franka Hands at the table's back edge, 0.6 m apart, facing +y."""
    yaw = float(np.pi / 2)
    return Embodiment(
        name="franka_pair",
        arm=panda_arm(),
        left_base=Pose(xyz=(-BASE_X, BASE_Y, BASE_Z), rpy=(0, 0, yaw)),
        right_base=Pose(xyz=(BASE_X, BASE_Y, BASE_Z), rpy=(0, 0, yaw)),
        home=tuple(float(q) for q in HOME),
        reach_pose=REACH,
    )
