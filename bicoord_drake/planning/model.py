"""The planning model of a scene: table, both arms and the scene's objects as obstacles.

:class:`PlanningModel` is built once per scene (one ``RobotDiagram`` and one
``SceneGraphCollisionChecker``) and then kept in step with the world:

- ``set_object_pose(name, X_WO)`` moves an obstacle. Every object - fixed or free - is welded to
  the world through an anchor ``FixedOffsetFrame`` whose pose is a context *parameter*, so moving
  it changes no model and no configuration vector.
- ``attach(name, side, q)`` makes an object part of the robot: its collision primitives ride on
  that arm's gripper link (checked against the other arm with the inter-arm clearance, and
  against the world with the environment clearance) and its own body is parked out of reach.
  ``detach(side, q)`` puts it back into the world where the gripper left it.
- A two-handed hold (``attach_both(name, q)``, or ``attach(..., together=True)`` while the
  other gripper holds it): one object held by both grippers. Its primitives ride on the left
  gripper (the *carrier*); collisions between it and both hands, and between the two hands
  themselves, are filtered while the hold lasts (the hold fixes the grippers' relative pose,
  which was checked when the grasps were chosen); everything else of each arm is still checked
  against it. ``detach`` of one side leaves the other holding it alone.
- ``set_gripper(side, opening)`` sets the finger opening held fixed while planning.
- ``ignoring(names)`` is a context manager under which the named objects collide with nothing
  (the object being grasped, or the held object a second gripper takes over).
- ``holding(held)`` is a context manager under which the grippers hold the given objects at the
  given grasps instead of what they hold (a merged motion's check carries each object from its
  pick to its release this way); ``arms_only()`` one under which the checker sees only the pairs
  between the two arms (each with what it holds).

Configurations: planning uses ``q = [left n arm joints, right n arm joints]`` (n from the
embodiment: 6 for the ViperX, 7 for the Panda; ``side_slice(side)`` gives one arm's entries);
``full_q(q)`` adds the fixed finger positions to give the plant's position vector.

Checking: ``set_padding(clearance, env_clearance)`` (or the ``padded`` context manager) sets the
checker's margins - ``clearance`` between the two arms and what they hold, ``env_clearance`` for
each arm's self pairs and against the table and objects; ``collision_free(q)``,
``colliding_pairs(q)`` and ``edge_free(a, b, resolution)`` query it. ``path_distance(a, b)``
bounds how far any robot point moves along a joint-space segment (the resolution metric).

Distances for the optimisers (:mod:`.ik`, :mod:`.motion`) come from two diagram contexts whose
collision filters split the geometry pairs in two classes: ``"arms"`` (left arm with what it
holds vs right arm with what it holds) and ``"env"`` (each arm's self pairs and arm vs table and
objects). Each class gets its own minimum-distance bound per call.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from pydrake.all import (
    Box,
    Capsule,
    CollisionFilterDeclaration,
    Context,
    Cylinder,
    FixedOffsetFrame,
    GeometryInstance,
    GeometrySet,
    Parallelism,
    ProximityProperties,
    RigidTransform,
    RobotDiagramBuilder,
    SceneGraphCollisionChecker,
    Shape,
    Sphere,
)

from bicoord_drake.models.embodiment import SIDES, Embodiment
from bicoord_drake.models.geometry import Primitive
from bicoord_drake.models.layout import default_embodiment
from bicoord_drake.models.objects import SceneObject, object_sdf
from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.models.scene import Scene
from bicoord_drake.models.table import table_sdf
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.timing import CONTROL_DT
from bicoord_drake.sim.station import add_robot, rigid_transform

#: Where the body of a held object is parked (far below the floor, out of every query's reach).
PARK = RigidTransform([0.0, 0.0, -50.0])
_HELD_GROUP = "held_{side}"


@dataclass(frozen=True)
class HeldObject:
    """An object rigidly held by one gripper: `X_GO` is its pose in the gripper-link frame."""

    name: str
    side: str
    X_GO: RigidTransform


def drake_shape(prim: Primitive) -> Shape:
    """Drake shape of a collision primitive (in the primitive's own frame)."""
    if prim.kind == "box":
        return Box(*prim.size)
    if prim.kind == "cylinder":
        return Cylinder(prim.size[0], prim.size[1])
    if prim.kind == "capsule":
        return Capsule(prim.size[0], prim.size[1])
    return Sphere(prim.size[0])


def _bounding_radius(shape) -> float:
    """Radius of a sphere about the shape's origin that contains it."""
    if isinstance(shape, Box):
        return 0.5 * float(np.linalg.norm([shape.width(), shape.depth(), shape.height()]))
    if isinstance(shape, Cylinder):
        return float(np.hypot(shape.radius(), shape.length() / 2))
    if isinstance(shape, Capsule):
        return shape.radius() + shape.length() / 2
    if isinstance(shape, Sphere):
        return shape.radius()
    raise TypeError(f"unsupported collision shape {type(shape).__name__}")


@lru_cache(maxsize=4096)
def bisection_order(n: int) -> np.ndarray:
    """0..n ordered coarse to fine: both ends, the midpoint, the quarter points, ..."""
    seen = np.zeros(n + 1, bool)
    order = []
    level = 0
    while len(order) < n + 1:
        grid = np.unique(np.round(np.linspace(0, n, 2**level + 1)).astype(int))
        new = grid[~seen[grid]]
        seen[new] = True
        order.extend(new.tolist())
        level += 1
    return np.array(order, dtype=float)


class PlanningModel:
    """Kinematic + collision model of the two arms in one scene (see the module docstring)."""

    def __init__(
        self,
        scene: Scene | None = None,
        embodiment: Embodiment | str | None = None,
        control_period: float = CONTROL_DT,
    ) -> None:
        """The model of `scene` (default: an empty table) with `embodiment`'s two arms (a
        registered name or an :class:`Embodiment`; default: the default robot), its plans
        sampled every `control_period` seconds: the station's control period, or for an expert
        below 15 Hz a k-th of it (:meth:`~bicoord_drake.tasks.base.WorldView.planning_model`,
        :func:`~bicoord_drake.planning.timing.planning_substeps`)."""
        if not control_period > 0:
            raise ValueError(f"control_period must be > 0 s, got {control_period!r}")
        self.scene = scene or Scene()
        #: Seconds between two samples of every plan made on this model (the planning period;
        #: the name is the control period's, which it is at 15 Hz and faster).
        self.control_period = float(control_period)
        if embodiment is None:
            embodiment = default_embodiment()
        self.embodiment = get_embodiment(embodiment) if isinstance(embodiment, str) else embodiment
        builder = RobotDiagramBuilder(time_step=0.0)
        plant = builder.plant()
        builder.parser().AddModelsFromString(table_sdf(), "sdf")
        self.arms = add_robot(plant, self.embodiment)
        self._anchors: dict[str, FixedOffsetFrame] = {}
        for obj in self.scene.objects:
            (inst,) = builder.parser().AddModelsFromString(object_sdf(obj), "sdf")
            body = plant.GetBodyByName(obj.name, inst)
            anchor = plant.AddFrame(
                FixedOffsetFrame(f"{obj.name}_anchor", plant.world_frame(), RigidTransform())
            )
            plant.WeldFrames(anchor, body.body_frame(), RigidTransform())
            self._anchors[obj.name] = anchor
        plant.Finalize()
        self.diagram = builder.Build()
        self.plant = plant
        self.scene_graph = self.diagram.scene_graph()

        arm = self.embodiment.arm
        self.arm_indices = {
            side: np.array(
                [plant.GetJointByName(j, self.arms[side]).position_start() for j in arm.joint_names]
            )
            for side in SIDES
        }
        self.finger_indices = {
            side: np.array(
                [
                    plant.GetJointByName(f, self.arms[side]).position_start()
                    for f in ("left_finger_joint", "right_finger_joint")
                ]
            )
            for side in SIDES
        }
        self.q_indices = np.concatenate([self.arm_indices["left"], self.arm_indices["right"]])
        #: Joints per arm, and each arm's entries in a planning configuration.
        self.arm_joints = n = len(arm.joints)
        self.arm_slices = {"left": slice(0, n), "right": slice(n, 2 * n)}
        self.lower = np.tile(arm.lower, 2)
        self.upper = np.tile(arm.upper, 2)
        self.home = np.concatenate([self.embodiment.home_of(side) for side in SIDES])
        self.tcp_frames = {side: plant.GetFrameByName("tcp", self.arms[side]) for side in SIDES}
        #: The hand's extent in the TCP frame (``ArmSpec.hand_boxes``, fingers open).
        self.hand_boxes = arm.hand_boxes()
        self.gripper_bodies = {
            side: plant.GetBodyByName(arm.gripper_link.name, self.arms[side]) for side in SIDES
        }
        self.robot_bodies = {
            side: [plant.get_body(i) for i in plant.GetBodyIndices(self.arms[side])]
            for side in SIDES
        }

        arm_spec = self.embodiment.arm
        cluster = {arm_spec.gripper_link.name, arm_spec.joints[-2].child, "left_finger"}
        cluster.add("right_finger")
        self.gripper_cluster = {
            side: [b for b in self.robot_bodies[side] if b.name() in cluster] for side in SIDES
        }
        self._q_full = np.zeros(plant.num_positions())
        self._object_poses: dict[str, RigidTransform] = {}
        self._held: dict[str, HeldObject] = {}
        self._ignored: frozenset[str] = frozenset()
        self._contexts: dict[str, tuple[Context, Context]] = {}
        self._fk_context = plant.CreateDefaultContext()

        self.joint_radius = self._joint_radius_bounds()
        self.checker = SceneGraphCollisionChecker(
            model=self.diagram,
            robot_model_instances=list(self.arms.values()),
            edge_step_size=0.01,
            env_collision_padding=0.0,
            self_collision_padding=0.0,
            # Measured: OpenMP threads only slow the checks down on the 2-core target machine.
            implicit_context_parallelism=Parallelism(1),
        )
        self._cluster_pairs = [
            (a.index(), b.index())
            for a in self.gripper_cluster["left"]
            for b in self.gripper_cluster["right"]
        ]
        self._nominal_filtered = {
            pair: self.checker.IsCollisionFilteredBetween(*pair) for pair in self._cluster_pairs
        }
        # What the checker carries now (see _sync_checker_held): per gripper the held
        # object's name and grasp (None: nothing), and whether the hands' filters are open.
        self._checker_held: dict[str, tuple[str, bytes] | None] = dict.fromkeys(SIDES)
        self._checker_together = False
        for side in SIDES:
            self.set_gripper(side, self.embodiment.home_opening)
        for obj in self.scene.objects:
            self.set_object_pose(obj.name, rigid_transform(obj.pose))

    # ------------------------------------------------------------------ configurations
    @property
    def num_positions(self) -> int:
        return self.plant.num_positions()

    @property
    def num_joints(self) -> int:
        """Length of a planning configuration: both arms' joints (2 n)."""
        return 2 * self.arm_joints

    @property
    def redundant(self) -> bool:
        """Whether an arm has more joints than a TCP pose has degrees of freedom (six): its
        IK solutions then form a continuum, and the IK cost picks one."""
        return self.arm_joints > 6

    def full_q(self, q: np.ndarray) -> np.ndarray:
        """Plant positions for planning joints `q` (fingers at the current openings)."""
        q_full = self._q_full.copy()
        q_full[self.q_indices] = q
        return q_full

    def planning_q(self, q_full: np.ndarray) -> np.ndarray:
        """The planning joints of a plant position vector."""
        return np.asarray(q_full)[self.q_indices]

    def side_slice(self, side: str) -> slice:
        """The entries of one arm in a planning configuration: ``0:n`` left, ``n:2n`` right."""
        return self.arm_slices[side]

    def set_gripper(self, side: str, opening: float) -> None:
        """Finger opening in [0, 1] held fixed while planning for `side`."""
        finger = float(self.embodiment.arm.gripper.finger_position(opening))
        self._q_full[self.finger_indices[side]] = finger

    def within_limits(self, q: np.ndarray, tol: float = 1e-6) -> bool:
        """Whether `q` is within the joint limits (to `tol`)."""
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))

    # ------------------------------------------------------------------ kinematics
    def tcp_pose(self, q: np.ndarray, side: str) -> RigidTransform:
        """X_WT: the TCP of `side` in the world at `q`."""
        self.plant.SetPositions(self._fk_context, self.full_q(q))
        return self.tcp_frames[side].CalcPoseInWorld(self._fk_context)

    def gripper_pose(self, q: np.ndarray, side: str) -> RigidTransform:
        """X_WG: the gripper link of `side` in the world at `q`."""
        self.plant.SetPositions(self._fk_context, self.full_q(q))
        return self.gripper_bodies[side].EvalPoseInWorld(self._fk_context)

    # ------------------------------------------------------------------ world state
    def object(self, name: str) -> SceneObject:
        return self.scene.object(name)

    def object_pose(self, name: str) -> RigidTransform:
        """Current X_WO of an object in the planning world (for a held object: where it was
        last put down or taken from; use `held_pose` while it is held)."""
        return self._object_poses[name]

    def set_object_pose(self, name: str, X_WO: RigidTransform) -> None:
        """Move an obstacle (not allowed while it is held)."""
        if name not in self._anchors:
            raise KeyError(f"no object {name!r} in the planning scene")
        if self.holders(name):
            raise PlanningError("object_held", f"{name} is held; detach it before moving it")
        self._object_poses[name] = X_WO
        self._refresh_anchor(name)

    def set_slide(self, name: str, position: float) -> None:
        """Put a sliding object (a drawer) at joint `position` (m from its scene pose, clipped
        to its limits): its obstacle moves along the slide axis, so checks see it there."""
        slide = self.object(name).slide
        if slide is None:
            raise ValueError(f"object {name!r} is not on a slide joint")
        d = float(np.clip(position, slide.lower, slide.upper))
        X_0 = rigid_transform(self.object(name).pose)
        shift = self.scene.slide_axis(name) * d
        self.set_object_pose(name, RigidTransform(X_0.rotation(), X_0.translation() + shift))

    def slide_position(self, name: str) -> float:
        """The joint position of a sliding object where the model has it now (m)."""
        X_0 = rigid_transform(self.object(name).pose)
        offset = self.object_pose(name).translation() - X_0.translation()
        return float(offset @ self.scene.slide_axis(name))

    def holders(self, name: str) -> list[str]:
        """The sides whose grippers hold `name` (both for a two-handed hold), left first."""
        return [side for side in SIDES if side in self._held and self._held[side].name == name]

    def _holder(self, name: str) -> str | None:
        """The carrier of `name` (the first holder; its shapes ride on that gripper)."""
        sides = self.holders(name)
        return sides[0] if sides else None

    @property
    def held_together(self) -> str | None:
        """The object both grippers hold (a two-handed hold), or None."""
        left, right = self._held.get("left"), self._held.get("right")
        return left.name if left and right and left.name == right.name else None

    def _anchor_pose(self, name: str) -> RigidTransform:
        """Where the object's own body is: parked while held or ignored."""
        if name in self._ignored or self._holder(name) is not None:
            return PARK
        return self._object_poses[name]

    def _refresh_anchor(self, name: str) -> None:
        anchor, X = self._anchors[name], self._anchor_pose(name)
        self.checker.PerformOperationAgainstAllModelContexts(
            lambda _model, ctx: anchor.SetPoseInParentFrame(ctx.plant_context(), X)
        )
        for _, plant_ctx in self._contexts.values():
            anchor.SetPoseInParentFrame(plant_ctx, X)

    @property
    def held(self) -> dict[str, HeldObject]:
        """What each gripper holds, by side."""
        return dict(self._held)

    def held_pose(self, side: str, q: np.ndarray) -> RigidTransform:
        """X_WO of the object held by `side` at `q`."""
        return self.gripper_pose(q, side) @ self._held[side].X_GO

    def attach(
        self,
        name: str,
        side: str,
        q: np.ndarray,
        X_WO: RigidTransform | None = None,
        *,
        together: bool = False,
    ) -> None:
        """`side` grasps `name` at configuration `q` (object at `X_WO`, default: its current
        pose); from now on it moves with that gripper and is checked as part of the robot.

        With `together`, the object may already be held by the other gripper: both then hold
        it (a two-handed hold; see the module docstring); `X_WO` defaults to where the other
        gripper holds it at `q`."""
        if side in self._held:
            raise PlanningError("gripper_busy", f"{side} gripper already holds {self._held[side]}")
        other = self._holder(name)
        if other is not None and not together:
            raise PlanningError(
                "object_held", f"{name} is already held (by {other}; together=True holds it both)"
            )
        if X_WO is None:
            X_WO = self._object_poses[name] if other is None else self.held_pose(other, q)
        X_GO = self.gripper_pose(q, side).inverse() @ X_WO
        self._held[side] = HeldObject(name, side, X_GO)
        if other is None:
            self._object_poses[name] = X_WO
            self._refresh_anchor(name)
        self._sync_checker_held()

    def attach_both(self, name: str, q: np.ndarray, X_WO: RigidTransform | None = None) -> None:
        """Both grippers grasp `name` at `q` (a two-handed hold; object at `X_WO`, default:
        its current pose)."""
        for side in SIDES:
            if side in self._held:
                raise PlanningError(
                    "gripper_busy", f"{side} gripper already holds {self._held[side]}"
                )
        self.attach(name, "left", q, X_WO)
        self.attach(name, "right", q, X_WO, together=True)

    def detach(
        self, side: str, q: np.ndarray | None = None, X_WO: RigidTransform | None = None
    ) -> None:
        """Release what `side` holds; it stays where the gripper is at `q` (or at `X_WO`).
        If the other gripper holds it too, it stays held by that one (`q`/`X_WO` unused)."""
        held = self._held.pop(side, None)
        if held is None:
            raise PlanningError("gripper_empty", f"{side} gripper holds nothing")
        if self.holders(held.name):
            self._sync_checker_held()
            return
        if X_WO is None:
            if q is None:
                self._held[side] = held
                raise ValueError("detach needs the configuration q or the release pose X_WO")
            X_WO = self.gripper_pose(q, side) @ held.X_GO
        self._sync_checker_held()
        self.set_object_pose(held.name, X_WO)

    def detach_both(self, q: np.ndarray | None = None, X_WO: RigidTransform | None = None) -> None:
        """End a two-handed hold: the object stays where the grippers leave it at `q` (or at
        `X_WO`)."""
        name = self.held_together
        if name is None:
            raise PlanningError("not_held_together", "the grippers do not hold one object together")
        if X_WO is None:
            if q is None:
                raise ValueError("detach_both needs the configuration q or the release pose X_WO")
            X_WO = self.held_pose("left", q)
        self.detach("right")
        self.detach("left", X_WO=X_WO)

    def _held_shapes(self, held: HeldObject) -> list[tuple[object, RigidTransform]]:
        obj = self.scene.object(held.name)
        if not obj.collide:
            return []
        return [
            (drake_shape(p), held.X_GO @ rigid_transform(p.pose)) for p in obj.shape.primitives()
        ]

    def _sync_checker_held(self) -> None:
        """Put each held object's shapes on its carrier's gripper and set the hand-to-hand
        filters of a two-handed hold. A gripper whose shapes are already those of its hold
        (the same object at the same grasp) keeps them: adding a shape to the checker costs
        milliseconds (it rebuilds the checker's contexts), and merged motions switch the holds
        back and forth many times per plan."""
        for side in SIDES:
            held = self._held.get(side)
            carried = not (
                held is None or held.name in self._ignored or self._holder(held.name) != side
            )
            key = (held.name, held.X_GO.GetAsMatrix34().tobytes()) if carried else None
            if self._checker_held.get(side) == key:
                continue
            group = _HELD_GROUP.format(side=side)
            self.checker.RemoveAllAddedCollisionShapes(group)
            self._checker_held[side] = key
            if not carried:
                continue
            for shape, X_GP in self._held_shapes(held):
                self.checker.AddCollisionShapeToBody(group, self.gripper_bodies[side], shape, X_GP)
        together = self.held_together is not None
        if self._checker_together != together:
            for pair in self._cluster_pairs:
                self.checker.SetCollisionFilteredBetween(
                    *pair, together or self._nominal_filtered[pair]
                )
            self._checker_together = together
        self._update_radius()
        self._contexts.clear()

    @contextmanager
    def holding(self, held: Mapping[str, HeldObject]) -> Iterator[None]:
        """Within the block the grippers hold exactly `held` (side -> :class:`HeldObject`, each
        at its grasp ``X_GO``) instead of what they hold now; afterwards the holds are put back
        as they were. An object held in neither is untouched (its pose stays where the model
        has it); one held in only one of them is parked or put back at that pose. A merged
        motion's check carries each object this way from its pick to its release."""
        for side, h in held.items():
            if h.side != side:
                raise ValueError(f"{h.name} is held by {h.side}, not {side}")
        previous = dict(self._held)
        self._set_held(dict(held))
        try:
            yield
        finally:
            self._set_held(previous)

    def _set_held(self, held: dict[str, HeldObject]) -> None:
        before = {h.name for h in self._held.values()}
        self._held = held
        for name in sorted(before ^ {h.name for h in held.values()}):
            self._refresh_anchor(name)
        self._sync_checker_held()

    # ------------------------------------------------------------------ ignoring objects
    @contextmanager
    def ignoring(self, names: Iterable[str]) -> Iterator[None]:
        """Within the block the named objects (free, fixed or held) collide with nothing."""
        names = frozenset(names)
        unknown = names - set(self._anchors)
        if unknown:
            raise KeyError(f"unknown objects {sorted(unknown)}")
        previous = self._ignored
        if names <= previous:
            yield
            return
        self._set_ignored(previous | names)
        try:
            yield
        finally:
            self._set_ignored(previous)

    def _set_ignored(self, names: frozenset[str]) -> None:
        # An ignored object is parked out of reach (a held one loses its attached shapes):
        # cheaper than rewriting collision filters in every checker context.
        changed = names ^ self._ignored
        self._ignored = names
        for name in changed:
            if self._holder(name) is None:
                self._refresh_anchor(name)
            else:
                self._sync_checker_held()

    # ------------------------------------------------------------------ distance contexts
    def distance_context(self, kind: str) -> Context:
        """Plant context (inside its own diagram context) whose collision filters leave only
        the pairs of class `kind`: ``"arms"`` or ``"env"`` (see the module docstring)."""
        if kind not in self._contexts:
            self._contexts[kind] = self._make_context(kind)
        return self._contexts[kind][1]

    def _make_context(self, kind: str) -> tuple[Context, Context]:
        root = self.diagram.CreateDefaultContext()
        plant_ctx = self.plant.GetMyMutableContextFromRoot(root)
        sg_ctx = self.scene_graph.GetMyMutableContextFromRoot(root)
        for name, anchor in self._anchors.items():
            anchor.SetPoseInParentFrame(plant_ctx, self._anchor_pose(name))
        geoms = {side: self._geometries(self.robot_bodies[side]) for side in SIDES}
        held_geoms: dict[str, list] = {side: [] for side in SIDES}
        source = self.plant.get_source_id()
        for side, held in self._held.items():
            if held.name in self._ignored or self._holder(held.name) != side:
                continue
            frame = self.plant.GetBodyFrameIdOrThrow(self.gripper_bodies[side].index())
            for i, (shape, X_GP) in enumerate(self._held_shapes(held)):
                gid = self.scene_graph.RegisterGeometry(
                    sg_ctx, source, frame, GeometryInstance(X_GP, shape, f"held_{side}_{i}")
                )
                self.scene_graph.AssignRole(sg_ctx, source, gid, ProximityProperties())
                held_geoms[side].append(gid)
        inspector = self.scene_graph.model_inspector()
        robot_all = set(geoms["left"] + geoms["right"])
        env = [g for g in inspector.GetAllGeometryIds() if g not in robot_all]
        left = GeometrySet(geoms["left"] + held_geoms["left"])
        right = GeometrySet(geoms["right"] + held_geoms["right"])
        decl = CollisionFilterDeclaration()
        if kind == "arms":
            decl.ExcludeWithin(left).ExcludeWithin(right)
            decl.ExcludeBetween(GeometrySet(env), GeometrySet(env + list(robot_all)))
            for side in SIDES:
                decl.ExcludeBetween(GeometrySet(held_geoms[side]), GeometrySet(env))
            if self.held_together is not None:  # the hold fixes the hands' relative pose
                hands = {s: self._geometries(self.gripper_cluster[s]) for s in SIDES}
                decl.ExcludeBetween(
                    GeometrySet(hands["left"] + held_geoms["left"]),
                    GeometrySet(hands["right"] + held_geoms["right"]),
                )
        elif kind == "env":
            decl.ExcludeBetween(left, right).ExcludeWithin(GeometrySet(env))
            for side in SIDES:
                # The held object touches its own gripper and fingers.
                grip = self._geometries(self.gripper_cluster[side])
                decl.ExcludeBetween(GeometrySet(held_geoms[side]), GeometrySet(grip))
                decl.ExcludeWithin(GeometrySet(held_geoms[side]))
        else:
            raise ValueError(f"unknown distance context {kind!r}; use 'arms' or 'env'")
        self.scene_graph.collision_filter_manager(sg_ctx).Apply(decl)
        return root, plant_ctx

    def _geometries(self, bodies: Iterable) -> list:
        return [g for b in bodies for g in self.plant.GetCollisionGeometriesForBody(b)]

    # ------------------------------------------------------------------ collision checking
    def set_padding(self, clearance: float, env_clearance: float) -> None:
        """Checker padding: `clearance` between the two arms (and what they hold),
        `env_clearance` for each arm's self pairs and against the environment."""
        n = self.plant.num_bodies()
        side_of = np.full(n, -1)
        for k, side in enumerate(SIDES):
            for b in self.robot_bodies[side]:
                side_of[int(b.index())] = k
        robot = side_of >= 0
        pad = np.zeros((n, n))
        pad[np.ix_(robot, np.ones(n, bool))] = env_clearance
        pad[np.ix_(np.ones(n, bool), robot)] = env_clearance
        cross = (side_of[:, None] >= 0) & (side_of[None, :] >= 0) & (side_of[:, None] != side_of)
        pad[cross] = clearance
        np.fill_diagonal(pad, 0.0)
        self.checker.SetPaddingMatrix(pad)

    @contextmanager
    def arms_only(self) -> Iterator[None]:
        """Within the block the checker sees only the pairs between the two arms (each with
        what it holds): each arm's self pairs and its pairs with the table and the objects are
        filtered, and put back afterwards. Filters set inside the block (a two-handed hold's)
        are undone with it."""
        previous = np.array(self.checker.GetFilteredCollisionMatrix(), copy=True)
        side_of = np.full(self.plant.num_bodies(), -1)
        for k, side in enumerate(SIDES):
            for b in self.robot_bodies[side]:
                side_of[int(b.index())] = k
        robot = side_of >= 0
        cross = robot[:, None] & robot[None, :] & (side_of[:, None] != side_of[None, :])
        only = previous.copy()
        only[(only == 0) & ~cross] = 1
        together = self._checker_together
        self.checker.SetCollisionFilterMatrix(only)
        try:
            yield
        finally:
            self.checker.SetCollisionFilterMatrix(previous)
            self._checker_together = together

    @contextmanager
    def keeping_padding(self) -> Iterator[None]:
        """The checker's padding as it is now is put back after the block, however it ends."""
        # A copy: the checker returns a live view of its padding, which set_padding overwrites.
        previous = np.array(self.checker.GetPaddingMatrix(), copy=True)
        try:
            yield
        finally:
            self.checker.SetPaddingMatrix(previous)

    @contextmanager
    def padded(self, clearance: float, env_clearance: float) -> Iterator[None]:
        """`set_padding` within the block; the previous padding is restored after it."""
        with self.keeping_padding():
            self.set_padding(clearance, env_clearance)
            yield

    def collision_free(self, q: np.ndarray, openings: Mapping[str, float] | None = None) -> bool:
        """Whether `q` is collision-free under the current padding (held objects included), the
        fingers as set (:meth:`set_gripper`) or, given `openings` (side -> opening), at those."""
        q_full = self.full_q(q)
        for side, opening in (openings or {}).items():
            finger = float(self.embodiment.arm.gripper.finger_position(opening))
            q_full[self.finger_indices[side]] = finger
        return bool(self.checker.CheckConfigCollisionFree(q_full))

    def colliding_pairs(self, q: np.ndarray, margin: float = 0.0) -> list[tuple[str, str, float]]:
        """Body pairs closer than their padding + `margin` at `q`: (body, other, distance)."""
        clearance = self.checker.CalcRobotClearance(self.full_q(q), 0.1 + margin)
        out = []
        for r, o, d in zip(
            clearance.robot_indices(), clearance.other_indices(), clearance.distances(), strict=True
        ):
            if d < margin:
                out.append((self._body_label(r), self._body_label(o), float(d)))
        return sorted(set(out), key=lambda x: x[2])

    def edge_free(
        self, q_a: np.ndarray, q_b: np.ndarray, resolution: float, endpoints: bool = True
    ) -> bool:
        """Whether the straight segment a-b is collision-free (current padding), checked so that
        no robot point moves more than `resolution` (m) between checks. Checks run coarse to
        fine (bisection order), so a colliding segment is usually rejected after a few."""
        a, b = np.asarray(q_a, float), np.asarray(q_b, float)
        n = max(1, int(np.ceil(self.path_distance(a, b) / resolution)))
        order = bisection_order(n) if endpoints else bisection_order(n)[2:]
        start = 0
        size = 4
        while start < len(order):
            t = order[start : start + size] / n
            Q = np.tile(self._q_full, (len(t), 1))
            Q[:, self.q_indices] = a + t[:, None] * (b - a)
            if not all(self.checker.CheckConfigsCollisionFree(list(Q))):
                return False
            start += size
            size *= 2
        return True

    def _body_label(self, index) -> str:
        body = self.plant.get_body(index)
        inst = self.plant.GetModelInstanceName(body.model_instance())
        return f"{inst}/{body.name()}" if inst.endswith("_arm") else body.name()

    # ------------------------------------------------------------------ path resolution
    def path_distance(self, q_a: np.ndarray, q_b: np.ndarray) -> float:
        """An upper bound (m) on how far any single robot point (held objects included) moves
        along the straight joint-space segment from `q_a` to `q_b`: per arm, the sum over
        its joints of |dq| times the joint's lever-arm bound; the larger of the two arms."""
        d = np.abs(np.asarray(q_b, float) - np.asarray(q_a, float)) * self.joint_radius
        n = self.arm_joints
        return float(max(d[:n].sum(), d[n:].sum()))

    def _joint_radius_bounds(self) -> np.ndarray:
        """Per joint, a bound on the distance from its axis of any collision geometry it moves.

        Triangle inequality along the chain: joint-origin offsets of the joints after it, plus
        the farthest bounding sphere of the geometry of the link it moves and its descendants.
        """
        arm = self.embodiment.arm
        inspector = self.scene_graph.model_inspector()
        reach = {}
        for body in self.robot_bodies["left"]:
            reach[body.name()] = max(
                (
                    np.linalg.norm(inspector.GetPoseInFrame(g).translation())
                    + _bounding_radius(inspector.GetShape(g))
                    for g in self.plant.GetCollisionGeometriesForBody(body)
                ),
                default=0.0,
            )
        child_links = [j.child for j in arm.joints]
        # Geometry of the gripper link includes the fingers (they ride on it).
        g_link = arm.gripper_link.name
        finger_origin = arm.gripper.finger_origin_x + arm.gripper.finger_max
        reach[g_link] = max(
            reach[g_link],
            finger_origin + max(reach["left_finger"], reach["right_finger"]),
        )
        offsets = [float(np.linalg.norm(j.origin.xyz)) for j in arm.joints]
        radius = np.zeros(len(arm.joints))
        for i in range(len(arm.joints)):
            best, chain = 0.0, 0.0
            for k in range(i, len(arm.joints)):
                if k > i:
                    chain += offsets[k]
                best = max(best, chain + reach[child_links[k]])
            radius[i] = best
        self._base_radius = radius.copy()
        self._offsets = offsets
        return np.tile(radius, 2)

    def _update_radius(self) -> None:
        """Grow the joint radii of an arm that holds an object by that object's extent."""
        radius = np.tile(self._base_radius, 2)
        arm = self.embodiment.arm
        n = len(arm.joints)
        for side, held in self._held.items():
            ext = max(
                (
                    np.linalg.norm(X_GP.translation()) + _bounding_radius(shape)
                    for shape, X_GP in self._held_shapes(held)
                ),
                default=0.0,
            )
            for i in range(n):
                chain = sum(self._offsets[i + 1 :])
                k = i + (0 if side == "left" else n)
                radius[k] = max(radius[k], chain + ext)
        self.joint_radius = radius
