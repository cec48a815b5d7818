"""A task stage (sub-goal, what each arm does, score, predicate) and the world state it reads.

A :class:`WorldState` is an immutable snapshot of the simulated world at one control step. Stage
predicates are small functions of one snapshot (see :mod:`bicoord_drake.stages.predicates`); the
:class:`~bicoord_drake.stages.monitor.StageMonitor` evaluates them every control step.

Velocities: ``WorldState.capture`` stores each object's spatial velocity read from the plant (exact,
instantaneous), so ``at_rest`` needs no history. Synthetic states may pass ``object_velocities``
directly or derive them from the previous snapshot with :meth:`WorldState.with_velocities_from`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.layout import ActionLayout, default_embodiment, layout_of
from bicoord_drake.models.objects import Shape
from bicoord_drake.models.scene import Scene

if TYPE_CHECKING:  # no Drake import at run time: predicates and tests stay Drake-free
    from bicoord_drake.sim.simulation import Simulation

StageKind = Literal["transient", "persistent"]


@functools.cache
def _default_layout() -> ActionLayout:
    """The layout of the default embodiment (synthetic states that give none)."""
    return layout_of(default_embodiment())


# --------------------------------------------------------------------------- rotations
def quat_to_matrix(wxyz: Sequence[float]) -> np.ndarray:
    """3x3 rotation of a (not necessarily unit) quaternion w, x, y, z."""
    w, x, y, z = np.asarray(wxyz, dtype=float) / np.linalg.norm(wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion w, x, y, z (w >= 0) of a rotation matrix."""
    R = np.asarray(R, dtype=float)
    trace = np.trace(R)
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + R[i, i] - R[j, j] - R[k, k], 1e-12))
        q = [0.0, 0.0, 0.0, 0.0]
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    q = np.asarray(q)
    return q if q[0] >= 0 else -q


def pose_vector(pose: Pose) -> np.ndarray:
    """A scene ``Pose`` (xyz + rpy) as a (7,) xyz + quaternion wxyz vector."""
    return np.concatenate([pose.xyz, matrix_to_quat(pose.matrix()[:3, :3])])


# --------------------------------------------------------------------------- world state
def _frozen_array(value: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    arr = np.array(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{what} must have shape {shape}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class WorldState:
    """What the stage predicates may read at one control step (immutable).

    ``object_poses`` / ``tcp_poses``: name or side -> (7,) xyz + quaternion wxyz, world frame.
    ``joint_state`` and ``action``: vectors of ``layout`` (the robot's; default: the default
    embodiment's, 14 numbers [left q (6), left opening, right q (6), right opening]), zeros and
    open grippers when not given; ``action`` is the command in effect (opening 1 = open).
    ``contacts``: object -> sides any of whose robot bodies (fingers, palm, wrist, links) touch
    it; ``finger_contacts``: object -> sides whose fingers touch it (a subset of ``contacts``;
    when not given, taken to be ``contacts``). ``object_velocities``: object -> (6,) [v_xyz,
    w_xyz] in world (may be empty for synthetic states). ``joint_positions``: sliding object (a
    drawer) -> its prismatic joint's position, m from its scene pose. ``scene`` gives initial
    poses and shapes (sizes) of the objects.
    """

    scene: Scene
    object_poses: Mapping[str, np.ndarray]
    step: int = 0
    time: float = 0.0
    tcp_poses: Mapping[str, np.ndarray] = field(default_factory=dict)
    joint_state: np.ndarray | None = None
    action: np.ndarray | None = None
    contacts: Mapping[str, frozenset[str]] = field(default_factory=dict)
    finger_contacts: Mapping[str, frozenset[str]] | None = None
    object_velocities: Mapping[str, np.ndarray] = field(default_factory=dict)
    joint_positions: Mapping[str, float] = field(default_factory=dict)
    layout: ActionLayout | None = None

    def __post_init__(self) -> None:
        poses = {n: _frozen_array(p, (7,), f"pose of {n!r}") for n, p in self.object_poses.items()}
        tcps = {s: _frozen_array(p, (7,), f"{s} TCP pose") for s, p in self.tcp_poses.items()}
        vels = {
            n: _frozen_array(v, (6,), f"velocity of {n!r}")
            for n, v in self.object_velocities.items()
        }
        contacts = {n: frozenset(sides) for n, sides in self.contacts.items()}
        fingers = None
        if self.finger_contacts is not None:
            fingers = {n: frozenset(sides) for n, sides in self.finger_contacts.items()}
            for name, sides in fingers.items():
                if not sides <= contacts.get(name, frozenset()):
                    raise ValueError(
                        f"finger contacts of {name!r} ({sorted(sides)}) must also be robot "
                        f"contacts ({sorted(contacts.get(name, ()))})"
                    )
        set_ = object.__setattr__
        set_(self, "object_poses", MappingProxyType(poses))
        set_(self, "tcp_poses", MappingProxyType(tcps))
        set_(self, "object_velocities", MappingProxyType(vels))
        set_(self, "contacts", MappingProxyType(contacts))
        if fingers is not None:
            set_(self, "finger_contacts", MappingProxyType(fingers))
        joints = {n: float(d) for n, d in self.joint_positions.items()}
        set_(self, "joint_positions", MappingProxyType(joints))
        layout = self.layout or _default_layout()
        set_(self, "layout", layout)
        size = (layout.action_size,)
        joint_state = np.zeros(size) if self.joint_state is None else self.joint_state
        action = _open_action(layout) if self.action is None else self.action
        set_(self, "joint_state", _frozen_array(joint_state, size, "joint_state"))
        set_(self, "action", _frozen_array(action, size, "action"))

    # ---------------------------------------------------------------- construction
    @classmethod
    def initial(cls, scene: Scene, **overrides: Any) -> WorldState:
        """The scene as sampled: objects at their initial poses, at rest, grippers open."""
        fields: dict[str, Any] = {
            "object_poses": {o.name: pose_vector(o.pose) for o in scene.objects},
            "object_velocities": {o.name: np.zeros(6) for o in scene.objects},
            "joint_positions": {o.name: 0.0 for o in scene.sliding_objects},
        }
        fields.update(overrides)
        return cls(scene=scene, **fields)

    @classmethod
    def capture(cls, sim: Simulation, action: np.ndarray, scene: Scene | None = None) -> WorldState:
        """Snapshot a running :class:`~bicoord_drake.sim.simulation.Simulation`.

        Call it after ``sim.step(action)``; `action` is the command in effect. `scene` defaults to
        the station's scene.
        """
        station = sim.station
        plant, plant_context = station.plant, sim.plant_context
        robot, fingers = sim.contacts()
        velocities = {}
        for name, body in station.object_bodies.items():
            V = plant.EvalBodySpatialVelocityInWorld(plant_context, body)
            velocities[name] = np.concatenate([V.translational(), V.rotational()])
        return cls(
            scene=station.scene if scene is None else scene,
            step=sim.steps,
            time=sim.time,
            object_poses=sim.object_poses(),
            tcp_poses={side: sim.tcp_pose(side) for side in SIDES},
            joint_state=sim.joint_state(),
            action=np.asarray(action, dtype=float),
            contacts=robot,
            finger_contacts=fingers,
            object_velocities=velocities,
            joint_positions=sim.joint_positions(),
            layout=station.layout,
        )

    def with_velocities_from(self, previous: WorldState) -> WorldState:
        """A copy whose object velocities are finite differences against `previous`."""
        dt = self.time - previous.time
        if dt <= 0:
            raise ValueError(f"previous state must be earlier (dt = {dt})")
        vels = {}
        for name, pose in self.object_poses.items():
            if name not in previous.object_poses:
                continue
            prev = previous.object_poses[name]
            linear = (pose[:3] - prev[:3]) / dt
            R_rel = quat_to_matrix(pose[3:]) @ quat_to_matrix(prev[3:]).T
            q = matrix_to_quat(R_rel)
            angle = 2.0 * math.atan2(np.linalg.norm(q[1:]), q[0])
            axis = q[1:] / max(np.linalg.norm(q[1:]), 1e-12)
            vels[name] = np.concatenate([linear, axis * angle / dt])
        return replace(self, object_velocities=vels)

    # ---------------------------------------------------------------- accessors
    def pose(self, name: str) -> np.ndarray:
        try:
            return self.object_poses[name]
        except KeyError:
            raise KeyError(
                f"no object {name!r} in world state; objects: {sorted(self.object_poses)}"
            ) from None

    def position(self, name: str) -> np.ndarray:
        return self.pose(name)[:3]

    def rotation(self, name: str) -> np.ndarray:
        """R_WO: the object's orientation as a 3x3 matrix."""
        return quat_to_matrix(self.pose(name)[3:])

    def velocity(self, name: str) -> np.ndarray:
        """(6,) [v_xyz, w_xyz]; a clear error when the snapshot carries no velocities."""
        try:
            return self.object_velocities[name]
        except KeyError:
            raise ValueError(
                f"world state has no velocity for {name!r}: capture it with WorldState.capture "
                "or derive it with with_velocities_from(previous)"
            ) from None

    def initial_pose(self, name: str) -> np.ndarray:
        """The object's pose in the scene as sampled (7,)."""
        return pose_vector(self.scene.object(name).pose)

    def shape(self, name: str) -> Shape:
        return self.scene.object(name).shape

    def joint_position(self, name: str) -> float:
        """The slide joint position of a sliding object (m; a drawer's opening)."""
        try:
            return self.joint_positions[name]
        except KeyError:
            raise KeyError(
                f"no joint position for {name!r} in world state; sliding objects: "
                f"{sorted(self.joint_positions)}"
            ) from None

    def opening(self, side: str) -> float:
        """Commanded gripper opening of one arm (1 = open)."""
        return float(self.action[self.layout.gripper(side)])

    def touching(self, name: str) -> frozenset[str]:
        """Sides any of whose robot bodies (fingers, palm, wrist, links) touch the object now."""
        return self.contacts.get(name, frozenset())

    def fingers_touching(self, name: str) -> frozenset[str]:
        """Sides whose fingers touch the object now (what a grasp needs); the robot contacts
        when the state was made without separate finger contacts."""
        fingers = self.contacts if self.finger_contacts is None else self.finger_contacts
        return fingers.get(name, frozenset())


def _open_action(layout: ActionLayout) -> np.ndarray:
    action = np.zeros(layout.action_size)
    action[layout.gripper_indices] = 1.0
    return action


# --------------------------------------------------------------------------- stage
@dataclass(frozen=True)
class Stage:
    """One sub-goal of a task.

    `left` / `right` say what each arm does (for annotations). `score` is the stage's share of
    the task (scores of a task sum to 1). `predicate` returns True when the sub-goal holds; it may
    return a fraction in [0, 1] for partial credit (the stage counts only at 1). *Transient*
    stages are latched the first time they hold, *persistent* ones must hold at the end.
    `depends_on`: indices of earlier stages that must count for this one to count; None means
    the previous stage, () means independent.
    """

    subgoal: str
    left: str
    right: str
    score: float
    predicate: Callable[[WorldState], bool | float]
    kind: StageKind
    depends_on: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("transient", "persistent"):
            raise ValueError(f"stage {self.subgoal!r}: kind must be 'transient' or 'persistent'")
        if not 0.0 <= self.score <= 1.0:
            raise ValueError(f"stage {self.subgoal!r}: score {self.score} not in [0, 1]")
        if not callable(self.predicate):
            raise TypeError(f"stage {self.subgoal!r}: predicate must be callable")
        if self.depends_on is not None:
            object.__setattr__(self, "depends_on", tuple(int(d) for d in self.depends_on))


def resolve_dependencies(stages: Sequence[Stage]) -> tuple[tuple[int, ...], ...]:
    """Validate a stage list and return each stage's explicit dependency indices.

    Raises ValueError for an empty list, scores that do not sum to 1, or a dependency that does
    not point to an earlier stage.
    """
    if not stages:
        raise ValueError("a task needs at least one stage")
    total = sum(s.score for s in stages)
    if not math.isclose(total, 1.0, abs_tol=1e-6):
        scores = ", ".join(f"{s.subgoal!r}: {s.score}" for s in stages)
        raise ValueError(f"stage scores must sum to 1, got {total:.6g} ({scores})")
    deps = []
    for j, stage in enumerate(stages):
        d = (j - 1,) if stage.depends_on is None and j > 0 else (stage.depends_on or ())
        bad = [i for i in d if not 0 <= i < j]
        if bad:
            raise ValueError(
                f"stage {j} ({stage.subgoal!r}) depends on {bad}: dependencies must point to "
                f"earlier stages (0..{j - 1})"
            )
        deps.append(tuple(sorted(set(d))))
    return tuple(deps)
