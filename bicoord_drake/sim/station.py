"""``build_station(scene, config)``: the one place a simulation diagram is built.

The station is a discrete ``MultibodyPlant`` (the contact approximation and step of
:class:`~bicoord_drake.config.StationConfig`, hydroelastic contact with point-contact
fallback) holding the table, two arms and the scene's objects, plus:

- joint PD control inside the plant (mutable actuator gains, integrated implicitly by the
  contact solver) with a gravity feed-forward computed on a robot-only control plant,
- an :class:`~bicoord_drake.sim.control.ActionInterpolator` that turns the action into PD
  targets with a first-order hold over each control period,
- a :class:`~bicoord_drake.sim.control.StationObserver` for joint state, TCP and object poses,
- the cameras (optional).

Exported diagram ports, sized by the embodiment's :class:`~bicoord_drake.models.layout.ActionLayout`
(``Station.layout``; 14 numbers for the ViperX pair). Input: ``action``. Outputs: ``joint_state``,
``left_tcp_pose`` / ``right_tcp_pose`` (7, xyz + wxyz), ``object_poses`` (7 per object),
``plant_state``, and per camera ``<cam>_rgb``, ``<cam>_depth`` (if enabled), ``<cam>_label``,
``<cam>_pose``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from pydrake.all import (
    AddMultibodyPlant,
    Demultiplexer,
    Diagram,
    DiagramBuilder,
    FixedOffsetFrame,
    GeometryId,
    JointActuatorIndex,
    ModelInstanceIndex,
    MultibodyPlant,
    MultibodyPlantConfig,
    Parser,
    PdControllerGains,
    PrismaticJoint,
    ProximityProperties,
    RigidTransform,
    Role,
    RoleAssign,
    RollPitchYaw,
    SceneGraph,
)

from bicoord_drake.config import StationConfig
from bicoord_drake.models.embodiment import SIDES, Embodiment, arm_sdf
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.layout import ActionLayout, action_layout
from bicoord_drake.models.objects import object_sdf
from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.models.scene import Scene
from bicoord_drake.models.table import table_sdf
from bicoord_drake.sim.cameras import CameraMount, add_cameras
from bicoord_drake.sim.control import ActionInterpolator, GravityFeedForward, StationObserver


@dataclass
class Station:
    """The built diagram and handles into it."""

    diagram: Diagram
    plant: MultibodyPlant
    scene_graph: SceneGraph
    control_plant: MultibodyPlant
    embodiment: Embodiment
    scene: Scene
    config: StationConfig
    arms: dict[str, ModelInstanceIndex]
    object_bodies: dict[str, object]
    interpolator: ActionInterpolator
    cameras: dict[str, CameraMount] = field(default_factory=dict)
    #: The prismatic joint of each sliding scene object (a drawer), by object name.
    slides: dict[str, PrismaticJoint] = field(default_factory=dict)

    @property
    def camera_names(self) -> list[str]:
        return list(self.cameras)

    @cached_property
    def layout(self) -> ActionLayout:
        """Where each arm's joints and opening sit in the action and joint-state vectors."""
        return action_layout(self.embodiment)


def rigid_transform(pose: Pose) -> RigidTransform:
    return RigidTransform(RollPitchYaw(*pose.rpy), list(pose.xyz))


def add_robot(plant: MultibodyPlant, embodiment: Embodiment) -> dict[str, ModelInstanceIndex]:
    """Parse both arms into `plant` and weld their bases; returns {'left': ..., 'right': ...}."""
    arms = {}
    for side in SIDES:
        (inst,) = Parser(plant).AddModelsFromString(arm_sdf(embodiment, f"{side}_arm"), "sdf")
        base = plant.GetFrameByName(embodiment.arm.base.name, inst)
        plant.WeldFrames(plant.world_frame(), base, rigid_transform(embodiment.base_pose(side)))
        for joint, q in zip(embodiment.arm.joint_names, embodiment.home_of(side), strict=True):
            plant.GetJointByName(joint, inst).set_default_angle(q)
        for finger in ("left_finger_joint", "right_finger_joint"):
            plant.GetJointByName(finger, inst).set_default_translation(
                float(embodiment.arm.gripper.finger_position(embodiment.home_opening))
            )
        arms[side] = inst
    return arms


def add_scene_objects(
    plant: MultibodyPlant, scene: Scene, rigid_kinds: tuple[str, ...] = ()
) -> dict[str, object]:
    """Parse every scene object (rigid-hydroelastic if its shape's kind is in `rigid_kinds`);
    weld fixtures, mount sliding objects on their prismatic joint (:func:`add_slide`), give
    free objects their initial pose."""
    bodies = {}
    for obj in scene.objects:
        sdf = object_sdf(obj, rigid=obj.shape.kind in rigid_kinds)
        (inst,) = Parser(plant).AddModelsFromString(sdf, "sdf")
        body = plant.GetBodyByName(obj.name, inst)
        X_WO = rigid_transform(obj.pose)
        if obj.fixed:
            plant.WeldFrames(plant.world_frame(), body.body_frame(), X_WO)
        elif obj.slide is not None:
            add_slide(plant, scene, obj, bodies[obj.slide.parent], body)
        else:
            plant.SetDefaultFloatingBaseBodyPose(body, X_WO)
        bodies[obj.name] = body
    return bodies


def add_slide(plant: MultibodyPlant, scene: Scene, obj, parent, body) -> PrismaticJoint:
    """The prismatic joint ``<name>_slide`` of a sliding object: its frame on the parent is
    the object's scene pose (joint position 0), the axis, limits and damping its ``Slide``'s.
    Drake filters contact between the two bodies (jointed bodies do not collide)."""
    slide = obj.slide
    X_WP = rigid_transform(scene.object(slide.parent).pose)
    X_PJ = X_WP.inverse() @ rigid_transform(obj.pose)
    frame = plant.AddFrame(FixedOffsetFrame(f"{obj.name}_slide_frame", parent.body_frame(), X_PJ))
    axis_J = X_PJ.rotation().inverse() @ np.asarray(slide.axis, dtype=float)
    joint = plant.AddJoint(
        PrismaticJoint(
            f"{obj.name}_slide",
            frame,
            body.body_frame(),
            axis_J,
            slide.lower,
            slide.upper,
            slide.damping,
        )
    )
    joint.set_default_translation(0.0)
    return joint


def slide_joints(plant: MultibodyPlant, scene: Scene) -> dict[str, PrismaticJoint]:
    """The prismatic joint of each sliding object of `scene` in a finalized `plant`."""
    return {o.name: plant.GetJointByName(f"{o.name}_slide") for o in scene.sliding_objects}


def build_control_plant(embodiment: Embodiment) -> tuple[MultibodyPlant, dict]:
    """A finalized robot-only continuous plant for gravity compensation and kinematics."""
    plant = MultibodyPlant(time_step=0.0)
    arms = add_robot(plant, embodiment)
    plant.Finalize()
    return plant, arms


def _configure_actuators(
    plant: MultibodyPlant,
    embodiment: Embodiment,
    arms: dict[str, ModelInstanceIndex],
    kp_scale: float,
) -> None:
    arm, g = embodiment.arm, embodiment.arm.gripper
    gains = {j.name: (j.kp * kp_scale, j.kd * kp_scale**0.5) for j in arm.joints}
    gains["left_finger_joint"] = (g.finger_kp, g.finger_kd)
    # GetJointActuatorIndices(instance) is empty before Finalize(): walk all actuators instead.
    for i in range(plant.num_actuators()):
        actuator = plant.get_mutable_joint_actuator(JointActuatorIndex(i))
        if actuator.model_instance() in arms.values():
            kp, kd = gains[actuator.joint().name()]
            actuator.set_controller_gains(PdControllerGains(p=kp, d=kd))
    for inst in arms.values():
        plant.AddCouplerConstraint(
            joint0=plant.GetJointByName("left_finger_joint", inst),
            joint1=plant.GetJointByName("right_finger_joint", inst),
            gear_ratio=1.0,
            offset=0.0,
        )


def _set_hydroelastic_margin(
    plant: MultibodyPlant,
    scene_graph: SceneGraph,
    margin: float,
    geometries: list[GeometryId] | None = None,
) -> None:
    """Give every hydroelastic geometry (compliant or rigid) of `geometries` (default: all)
    Drake's contact `margin` (m)."""
    inspector = scene_graph.model_inspector()
    source = plant.get_source_id()
    if geometries is None:
        geometries = inspector.GetAllGeometryIds(Role.kProximity)
    for geometry in geometries:
        props = inspector.GetProximityProperties(geometry)
        if not props.HasProperty("hydroelastic", "compliance_type"):
            continue
        props = ProximityProperties(props)
        props.UpdateProperty("hydroelastic", "margin", margin)
        scene_graph.AssignRole(source, geometry, props, RoleAssign.kReplace)


def build_station(scene: Scene, config: StationConfig | None = None) -> Station:
    """Build the simulation diagram for `scene` (see the module docstring for its ports)."""
    config = config or StationConfig()
    embodiment = get_embodiment(config.embodiment).with_pad_modulus(config.pad_modulus)
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(
        MultibodyPlantConfig(
            time_step=config.time_step,
            discrete_contact_approximation=config.contact_approximation,
            contact_model=config.contact_model,
            sap_near_rigid_threshold=config.sap_near_rigid_threshold,
        ),
        builder,
    )
    Parser(plant).AddModelsFromString(table_sdf(scene.appearance), "sdf")
    arms = add_robot(plant, embodiment)
    _configure_actuators(plant, embodiment, arms, config.kp_scale)
    object_bodies = add_scene_objects(plant, scene, config.rigid_object_kinds)
    if config.hydroelastic_margin > 0:
        _set_hydroelastic_margin(plant, scene_graph, config.hydroelastic_margin)
    for obj in scene.objects:
        if obj.contact_margin is not None:
            geometries = plant.GetCollisionGeometriesForBody(object_bodies[obj.name])
            _set_hydroelastic_margin(plant, scene_graph, obj.contact_margin, geometries)
    plant.Finalize()

    interpolator = builder.AddNamedSystem(
        "action_interpolator", ActionInterpolator(embodiment, config.control_period)
    )
    builder.ExportInput(interpolator.action_input_port(), "action")
    desired = builder.AddNamedSystem(
        "desired_state_split", Demultiplexer(interpolator.desired_state_sizes())
    )
    builder.Connect(interpolator.desired_states_output_port(), desired.get_input_port())
    for k, side in enumerate(SIDES):
        builder.Connect(desired.get_output_port(k), plant.get_desired_state_input_port(arms[side]))

    control_plant, control_arms = build_control_plant(embodiment)
    if config.gravity_compensation:
        gravity = builder.AddNamedSystem(
            "gravity_feed_forward", GravityFeedForward(plant, arms, control_plant, control_arms)
        )
        builder.Connect(plant.get_state_output_port(), gravity.GetInputPort("state"))
        split = builder.AddNamedSystem("actuation_split", Demultiplexer(gravity.actuation_sizes()))
        builder.Connect(gravity.GetOutputPort("actuation"), split.get_input_port())
        for k, side in enumerate(SIDES):
            builder.Connect(split.get_output_port(k), plant.get_actuation_input_port(arms[side]))

    observer = builder.AddNamedSystem(
        "observer", StationObserver(plant, embodiment, arms, list(object_bodies.values()))
    )
    builder.Connect(plant.get_state_output_port(), observer.GetInputPort("state"))
    builder.Connect(plant.get_body_poses_output_port(), observer.GetInputPort("body_poses"))
    for name in ("joint_state", "left_tcp_pose", "right_tcp_pose", "object_poses"):
        builder.ExportOutput(observer.GetOutputPort(name), name)
    builder.ExportOutput(plant.get_state_output_port(), "plant_state")

    mounts = {}
    if config.render and config.cameras.names:
        sensors = add_cameras(
            builder, plant, scene_graph, embodiment, arms, config.cameras, scene.appearance
        )
        for name, (sensor, mount) in sensors.items():
            builder.ExportOutput(sensor.color_image_output_port(), f"{name}_rgb")
            builder.ExportOutput(sensor.label_image_output_port(), f"{name}_label")
            builder.ExportOutput(sensor.body_pose_in_world_output_port(), f"{name}_pose")
            if config.cameras.depth:
                builder.ExportOutput(sensor.depth_image_16U_output_port(), f"{name}_depth")
            mounts[name] = mount

    diagram = builder.Build()
    diagram.set_name("bicoord_station")
    return Station(
        diagram=diagram,
        plant=plant,
        scene_graph=scene_graph,
        control_plant=control_plant,
        embodiment=embodiment,
        scene=scene,
        config=config,
        arms=arms,
        object_bodies=object_bodies,
        interpolator=interpolator,
        cameras=mounts,
        slides=slide_joints(plant, scene),
    )
