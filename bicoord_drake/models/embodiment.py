"""Arm + gripper descriptions (pydantic) and their SDFormat generator.

An :class:`Embodiment` is pure data: one :class:`ArmSpec` (links, a chain of revolute joints - six
for the ViperX, seven for the Panda - and a parallel gripper), the two base poses, the home
configuration and control limits. :func:`arm_sdf` turns it into an SDFormat model string; the
station parses one model per side (``left_arm``, ``right_arm``). A second robot is a second
``Embodiment`` value registered in :data:`~bicoord_drake.models.robots.EMBODIMENTS`; nothing
else needs to change.

This module is only the schema and the generator; each robot's numbers live in its own module:
:func:`bicoord_drake.models.viperx.aloha_viperx` (the default) is two ViperX 300s arms (the
ALOHA / AgileX layout) with the public ViperX 300s kinematics, limits and link inertias, side by
side behind the table facing +y; :func:`bicoord_drake.models.franka.franka_pair` is two 7-DoF
Franka Emika Panda arms with the Franka Hand.

Gripper frame convention (every embodiment): the gripper link's x axis points along the fingers
(the approach direction), the fingers move along its y axis, and the ``tcp`` frame - midway
between the fingertip pads - has the gripper link's orientation.

Gripper convention: each finger joint's position is the distance from the gripper's midplane to
that finger's inner pad surface, so the jaw gap is twice the finger position. A gripper opening
command g in [0, 1] maps linearly onto [finger_min, finger_max]. The two fingers are coupled by a
constraint (the right finger mirrors the left) and only the left finger is actuated, under a force
limit, so a closing gripper stops at the object.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, model_validator

from bicoord_drake.models.geometry import (
    ContactProps,
    Pose,
    Primitive,
    Rgba,
    Vec3,
    export_obj,
    mesh_cache_dir,
    sdf_collision,
    sdf_inertial,
    sdf_mesh_visual,
)

Side = Literal["left", "right"]
SIDES: tuple[Side, Side] = ("left", "right")


def other_side(side: str) -> Side:
    """The arm that is not `side` ('left' <-> 'right')."""
    if side not in SIDES:
        raise ValueError(f"side must be one of {SIDES}, got {side!r}")
    return "right" if side == "left" else "left"


class LinkSpec(BaseModel):
    """A rigid link: inertia about its centre of mass, collision primitives, visual primitives."""

    model_config = ConfigDict(frozen=True)

    name: str
    mass: float = Field(gt=0)
    com: Vec3 = (0.0, 0.0, 0.0)
    inertia_diag: Vec3
    inertia_offdiag: Vec3 | None = Field(
        None, description="products of inertia (ixy, ixz, iyz) about the COM; None = principal"
    )
    collision: tuple[Primitive, ...] = ()
    visual: tuple[Primitive, ...] = ()
    color: Rgba = (0.15, 0.15, 0.17, 1.0)


class JointSpec(BaseModel):
    """A revolute arm joint; `origin` is the child frame's pose in the parent link frame."""

    model_config = ConfigDict(frozen=True)

    name: str
    parent: str
    child: str
    origin: Pose
    axis: Vec3
    lower: float
    upper: float
    velocity_limit: float = Field(gt=0, description="rad/s, used by planning")
    acceleration_limit: float = Field(gt=0, description="rad/s^2, used by planning")
    jerk_limit: float = Field(gt=0, description="rad/s^3, used by planning")
    effort_limit: float = Field(gt=0, description="N m, enforced by the actuator")
    damping: float = Field(0.0, ge=0, description="viscous joint damping, N m s/rad")
    kp: float = Field(gt=0, description="default PD stiffness, N m/rad")
    kd: float = Field(ge=0, description="default PD damping, N m s/rad")

    @model_validator(mode="after")
    def _limits_ordered(self) -> JointSpec:
        if not self.lower < self.upper:
            raise ValueError(f"joint {self.name}: lower limit must be below upper limit")
        return self


class GripperSpec(BaseModel):
    """A parallel-jaw gripper on the last arm link (`mount` link), fingers moving along its y."""

    model_config = ConfigDict(frozen=True)

    finger_origin_x: float = Field(description="finger joint origin along the mount link x")
    finger_min: float = Field(ge=0, description="finger position when closed (half jaw gap), m")
    finger_max: float = Field(gt=0, description="finger position when open (half jaw gap), m")
    force_limit: float = Field(gt=0, description="closing force limit of the actuated finger, N")
    finger_kp: float = Field(gt=0)
    finger_kd: float = Field(ge=0)
    finger_velocity_limit: float = Field(0.2, gt=0, description="m/s, used by planning")
    finger_mass: float = Field(gt=0)
    finger_length: float = Field(gt=0, description="finger plate length along x, m")
    finger_height: float = Field(gt=0, description="finger plate height along z, m")
    finger_thickness: float = Field(gt=0)
    pad_length: float = Field(gt=0)
    pad_thickness: float = Field(gt=0)
    pad_height: float = Field(gt=0)
    pad_friction: float = Field(1.0, gt=0)
    pad_modulus: float = Field(1e6, gt=0, description="hydroelastic modulus of the pads, Pa")
    finger_color: Rgba = (0.2, 0.2, 0.22, 1.0)
    pad_color: Rgba = (0.85, 0.45, 0.1, 1.0)

    @model_validator(mode="after")
    def _travel_ordered(self) -> GripperSpec:
        if not self.finger_min < self.finger_max:
            raise ValueError("gripper: finger_min must be below finger_max")
        return self

    @property
    def tcp_x(self) -> float:
        """TCP x in the mount link: midway between the pads, at the pads' centre."""
        return self.finger_origin_x + self.finger_length - self.pad_length / 2

    def finger_position(self, opening: float | np.ndarray) -> float | np.ndarray:
        """Opening command in [0, 1] -> finger joint position (half the jaw gap)."""
        return self.finger_min + np.clip(opening, 0.0, 1.0) * (self.finger_max - self.finger_min)

    @property
    def opening_rate(self) -> float:
        """The fastest change of the opening the finger speed allows (opening units per s)."""
        return self.finger_velocity_limit / (self.finger_max - self.finger_min)

    def opening(self, finger_position: float | np.ndarray) -> float | np.ndarray:
        """Finger joint position -> opening in [0, 1] (not clipped: a blocked finger reads > 0)."""
        return (finger_position - self.finger_min) / (self.finger_max - self.finger_min)

    def opening_for_gap(self, gap: float) -> float:
        """The opening command whose jaw gap (between the pads) is `gap` m, clipped to
        [0, 1] and rounded to 1e-6 (far below what the fingers resolve): how an expert asks
        for a jaw width rather than for one gripper's fraction of its stroke."""
        return round(float(np.clip(self.opening(gap / 2), 0.0, 1.0)), 6)


class WristFlip(BaseModel):
    """A roll-pitch-roll wrist whose parts are symmetric about the pitch axis: turning both
    rolls by half a turn and negating the pitch gives the same TCP pose with the same arm
    geometry (the ViperX's forearm roll, wrist angle and wrist rotate). Indices within one
    arm's joints."""

    model_config = ConfigDict(frozen=True)

    first_roll: int = Field(ge=0)
    pitch: int = Field(ge=0)
    second_roll: int = Field(ge=0)


class ArmSpec(BaseModel):
    """A serial arm: base link, links, its revolute joints in order (any number), and a gripper
    on the last link."""

    model_config = ConfigDict(frozen=True)

    base: LinkSpec
    links: tuple[LinkSpec, ...]
    joints: tuple[JointSpec, ...]
    gripper: GripperSpec
    gripper_link: LinkSpec = Field(description="the link the fingers ride on (child of last joint)")

    @model_validator(mode="after")
    def _chain(self) -> ArmSpec:
        names = [self.base.name] + [link.name for link in self.links]
        for joint in self.joints:
            if joint.parent not in names or joint.child not in names:
                raise ValueError(f"joint {joint.name} refers to an unknown link")
        if self.joints[-1].child != self.gripper_link.name:
            raise ValueError("the last joint's child must be the gripper link")
        return self

    @property
    def joint_names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def lower(self) -> np.ndarray:
        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> np.ndarray:
        return np.array([j.upper for j in self.joints])

    def hand_boxes(self, opening: float = 1.0) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """The hand's extent in the TCP frame, derived from the data (no field to fill in):
        one axis-aligned box (lo, hi) around each collision primitive of the gripper link and
        one around both fingers at `opening`. Planners choose grasps, place yaws and staging
        poses by it (a wide hand needs room along its finger axis y)."""
        g = self.gripper
        shift = np.array([g.tcp_x, 0.0, 0.0])
        boxes = []
        for prim in self.gripper_link.collision:
            lo, hi = prim.trimesh().bounds
            boxes.append((np.asarray(lo) - shift, np.asarray(hi) - shift))
        span = float(g.finger_position(opening)) + g.pad_thickness + g.finger_thickness
        lo = np.array([g.finger_origin_x, -span, -g.finger_height / 2]) - shift
        hi = np.array([g.finger_origin_x + g.finger_length, span, g.finger_height / 2]) - shift
        boxes.append((lo, hi))
        return tuple(boxes)

    def hand_half_height(self) -> float:
        """How far the hand (its gripper link) reaches from the TCP along the gripper's z
        either way, m: what a horizontal grasp must keep above the support."""
        link = self.hand_boxes()[: len(self.gripper_link.collision)]
        return max(float(max(-lo[2], hi[2])) for lo, hi in link)


class Embodiment(BaseModel):
    """A two-arm robot: the same arm twice, at two base poses, with a home configuration."""

    model_config = ConfigDict(frozen=True)

    name: str
    arm: ArmSpec
    left_base: Pose
    right_base: Pose
    home: tuple[float, ...] = Field(
        description="home joint angles of one arm in its own vertical plane; both arms start "
        "from these angles (their bases face the same way), turned by `home_spread`"
    )
    home_spread: float = Field(
        0.0,
        ge=0.0,
        le=0.5,
        description="rad: each arm's first joint (the vertical one at the base) turned outward "
        "from `home` by this angle, the left arm's up and the right arm's down, so the two homes "
        "stay mirror images and the TCPs start as far apart as the reference robot's "
        "(docs/metrics.md, 'start distance'); 0: both arms at `home`",
    )
    home_opening: float = Field(1.0, ge=0, le=1)
    closed_form_ik: Literal["spherical_wrist_6r"] | None = Field(
        None,
        description="a closed-form IK the planner may use as a fast path: 'spherical_wrist_6r' "
        "(six joints - z, y, y, x, y, x - with a spherical wrist, as the ViperX); None: "
        "numerical IK only",
    )
    reach_pose: tuple[tuple[float, ...], tuple[float, ...]] | None = Field(
        None,
        description="(left arm angles, right arm angles) of a pose leaning over the table, for "
        "snapshots (scripts/render.py --pose reach); None: snapshots use home",
    )
    wrist_flip: WristFlip | None = Field(
        None, description="a symmetric roll-pitch-roll wrist (a second branch of every pose)"
    )

    @model_validator(mode="after")
    def _home_valid(self) -> Embodiment:
        if len(self.home) != len(self.arm.joints):
            raise ValueError(f"home must have {len(self.arm.joints)} joint angles")
        for side in SIDES:
            q = self.home_of(side)
            if np.any(q < self.arm.lower) or np.any(q > self.arm.upper):
                raise ValueError(
                    f"the {side} arm's home (home turned by home_spread) is outside the joint "
                    "limits"
                )
        return self

    @model_validator(mode="after")
    def _wrist_flip_valid(self) -> Embodiment:
        n = len(self.arm.joints)
        if self.reach_pose is not None and any(len(q) != n for q in self.reach_pose):
            raise ValueError(f"reach_pose must give {n} joint angles per arm")
        if self.wrist_flip is not None and max(self.wrist_flip.model_dump().values()) >= n:
            raise ValueError(f"wrist_flip joint indices must be below {n}")
        return self

    @property
    def num_arm_joints(self) -> int:
        return len(self.arm.joints)

    def base_pose(self, side: Side) -> Pose:
        return self.left_base if side == "left" else self.right_base

    def home_of(self, side: Side) -> np.ndarray:
        """One arm's home joint angles: `home` with the first joint turned outward by
        `home_spread` (up for the left arm, down for the right)."""
        q = np.array(self.home, dtype=float)
        q[0] += self.home_spread if side == "left" else -self.home_spread
        return q

    def home_action(self) -> np.ndarray:
        """The action ``[left q, left opening, right q, right opening]`` (2 (n + 1) numbers for
        n arm joints: 14 for the ViperX pair) holding both arms at home."""
        return np.concatenate([np.append(self.home_of(side), self.home_opening) for side in SIDES])

    def with_pad_modulus(self, modulus: float | None) -> Embodiment:
        """This robot with its finger pads' hydroelastic modulus (Pa) set to `modulus` (a
        physics setting, ``StationConfig.pad_modulus``); None: unchanged."""
        if modulus is None:
            return self
        gripper = self.arm.gripper.model_copy(update={"pad_modulus": float(modulus)})
        return self.model_copy(update={"arm": self.arm.model_copy(update={"gripper": gripper})})

    def action_speed_limits(self) -> np.ndarray:
        """The fastest each action entry may change (per s), in the action's layout: each
        joint's velocity limit (rad/s) and the gripper's opening rate."""
        side = [j.velocity_limit for j in self.arm.joints] + [self.arm.gripper.opening_rate]
        return np.array(side + side, dtype=float)


# --------------------------------------------------------------------------------------------
# SDFormat generation
# --------------------------------------------------------------------------------------------

FINGER_NAMES = ("left_finger", "right_finger")


def arm_sdf(embodiment: Embodiment, model_name: str) -> str:
    """SDFormat (1.9) for one arm; its base link is welded to the world by the station.

    Cached per process: every station, control plant and planning model builds the same arms
    (meshing their visuals costs ~0.25 s per arm). A cached text is made again if the mesh
    files it names are gone or the mesh cache moved."""
    key = (embodiment, model_name, mesh_cache_dir())
    sdf = _ARM_SDF.get(key)
    if sdf is None or not all(Path(uri).exists() for uri in _MESH_URI.findall(sdf)):
        sdf = _ARM_SDF[key] = _make_arm_sdf(embodiment, model_name)
    return sdf


_ARM_SDF: dict[tuple, str] = {}
_MESH_URI = re.compile(r"<uri>file://([^<]+)</uri>")


def _make_arm_sdf(embodiment: Embodiment, model_name: str) -> str:
    arm = embodiment.arm
    g = arm.gripper
    origin_of = {joint.child: joint for joint in arm.joints}
    body: list[str] = []
    for link in (arm.base, *arm.links):
        joint = origin_of.get(link.name)
        pose = (
            f'<pose relative_to="{joint.parent}">{_pose_body(joint.origin)}</pose>' if joint else ""
        )
        body.append(_link_sdf(link, f"{embodiment.name}_{link.name}", pose))
    for joint in arm.joints:
        body.append(
            f'<joint name="{joint.name}" type="revolute"><parent>{joint.parent}</parent>'
            f"<child>{joint.child}</child>"
            f"<axis><xyz>{_vec(joint.axis)}</xyz><limit><lower>{joint.lower}</lower>"
            f"<upper>{joint.upper}</upper><effort>{joint.effort_limit}</effort>"
            f"<velocity>{joint.velocity_limit}</velocity></limit>"
            f"<dynamics><damping>{joint.damping}</damping></dynamics></axis></joint>"
        )
    body.extend(_finger_sdf(embodiment.name, arm.gripper_link.name, g, sign) for sign in (1, -1))
    body.append(
        f'<frame name="tcp" attached_to="{arm.gripper_link.name}">'
        f'<pose relative_to="{arm.gripper_link.name}">{g.tcp_x} 0 0 0 0 0</pose></frame>'
    )
    # Neighbouring links of the wrist and of the shoulder overlap by construction.
    wrist_cluster = [arm.joints[-2].child, arm.gripper_link.name, *FINGER_NAMES]
    shoulder_cluster = [arm.base.name, arm.joints[0].child, arm.joints[1].child]
    body.append(_filter_group("gripper_cluster", wrist_cluster))
    body.append(_filter_group("shoulder_cluster", shoulder_cluster))
    return (
        '<?xml version="1.0"?><sdf version="1.9" xmlns:drake="http://drake.mit.edu">'
        f'<model name="{model_name}">{"".join(body)}</model></sdf>'
    )


#: The arm links and finger plates are rigid-hydroelastic: against the compliant task objects
#: and pads they make hydroelastic contact (a pressure field over the overlap), which stays
#: quiet under the "lagged" approximation; with point contact only, an object resting on or
#: struck by a link was thrown off within a control step. Link against table or rigid object
#: is point contact (Drake's fallback for rigid-rigid pairs).
LINK_CONTACT = ContactProps(friction=0.8, hydroelastic="rigid", resolution_hint=0.01)


def _link_sdf(link: LinkSpec, mesh_prefix: str, pose: str) -> str:
    parts = [f'<link name="{link.name}">', pose, _link_inertial(link)]
    for i, prim in enumerate(link.collision):
        parts.append(sdf_collision(f"{link.name}_collision_{i}", prim, LINK_CONTACT))
    if link.visual:
        mesh = trimesh.util.concatenate([p.trimesh(smooth=0.008) for p in link.visual])
        parts.append(
            sdf_mesh_visual(f"{link.name}_visual", export_obj(mesh, mesh_prefix), link.color)
        )
    parts.append("</link>")
    return "".join(parts)


def _link_inertial(link: LinkSpec) -> str:
    if link.inertia_offdiag is None:
        return sdf_inertial(link.mass, link.com, link.inertia_diag)
    (ixx, iyy, izz), (ixy, ixz, iyz) = link.inertia_diag, link.inertia_offdiag
    return (
        f"<inertial>{Pose(xyz=link.com).sdf()}<mass>{link.mass:.6g}</mass><inertia>"
        f"<ixx>{ixx:.6g}</ixx><iyy>{iyy:.6g}</iyy><izz>{izz:.6g}</izz>"
        f"<ixy>{ixy:.6g}</ixy><ixz>{ixz:.6g}</ixz><iyz>{iyz:.6g}</iyz></inertia></inertial>"
    )


def _finger_sdf(prefix: str, mount: str, g: GripperSpec, sign: int) -> str:
    """One finger: a plate and a compliant pad; its frame lies on the pad's inner surface."""
    name = FINGER_NAMES[0] if sign > 0 else FINGER_NAMES[1]
    s = float(sign)
    length = g.finger_length
    plate_y = s * (g.pad_thickness + g.finger_thickness / 2)
    plate = Primitive(
        kind="box",
        size=(length, g.finger_thickness, g.finger_height),
        pose=Pose(xyz=(length / 2, plate_y, 0.0)),
    )
    pad = Primitive(
        kind="box",
        size=(g.pad_length, g.pad_thickness, g.pad_height),
        pose=Pose(xyz=(length - g.pad_length / 2, s * g.pad_thickness / 2, 0.0)),
    )
    plate_props = ContactProps(friction=g.pad_friction, hydroelastic="rigid", resolution_hint=0.005)
    pad_props = ContactProps(
        friction=g.pad_friction,
        hydroelastic="compliant",
        hydroelastic_modulus=g.pad_modulus,
        resolution_hint=0.005,
        dissipation=5.0,
    )
    m = g.finger_mass
    inertia = (
        m * (g.finger_thickness**2 + g.finger_height**2) / 12,
        m * (length**2 + g.finger_height**2) / 12,
        m * (length**2 + g.finger_thickness**2) / 12,
    )
    plate_mesh = export_obj(plate.trimesh(smooth=0.003), f"{prefix}_{name}_plate")
    pad_mesh = export_obj(pad.trimesh(smooth=0.001), f"{prefix}_{name}_pad")
    link = (
        f'<link name="{name}">'
        f'<pose relative_to="{mount}">{g.finger_origin_x} 0 0 0 0 0</pose>'
        f"{sdf_inertial(m, (length / 2, plate_y, 0.0), inertia)}"
        f"{sdf_collision(f'{name}_plate', plate, plate_props)}"
        f"{sdf_collision(f'{name}_pad', pad, pad_props)}"
        f"{sdf_mesh_visual(f'{name}_plate_visual', plate_mesh, g.finger_color)}"
        f"{sdf_mesh_visual(f'{name}_pad_visual', pad_mesh, g.pad_color)}"
        "</link>"
    )
    # Only the left finger is actuated; the right one follows through a coupler constraint
    # (an SDFormat effort limit of 0 tells Drake not to add an actuator).
    effort = g.force_limit if sign > 0 else 0.0
    joint = (
        f'<joint name="{name}_joint" type="prismatic"><parent>{mount}</parent><child>{name}</child>'
        f"<axis><xyz>0 {s:g} 0</xyz><limit><lower>{g.finger_min}</lower>"
        f"<upper>{g.finger_max}</upper><effort>{effort}</effort>"
        f"<velocity>{g.finger_velocity_limit}</velocity></limit>"
        "<dynamics><damping>1.0</damping></dynamics></axis></joint>"
    )
    return link + joint


def _filter_group(name: str, members: list[str]) -> str:
    m = "".join(f"<drake:member>{x}</drake:member>" for x in dict.fromkeys(members))
    return (
        f'<drake:collision_filter_group name="{name}">{m}'
        f"<drake:ignored_collision_filter_group>{name}</drake:ignored_collision_filter_group>"
        "</drake:collision_filter_group>"
    )


def _pose_body(p: Pose) -> str:
    return " ".join(f"{v:.6g}" for v in (*p.xyz, *p.rpy))


def _vec(v: Vec3) -> str:
    return " ".join(f"{x:.6g}" for x in v)
