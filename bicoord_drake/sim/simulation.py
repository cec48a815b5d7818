"""Stepping a station one control period at a time, and reading what it observes.

>>> from bicoord_drake.models.scene import demo_scene
>>> sim = Simulation(build_station(demo_scene("cubes")))     # doctest: +SKIP
>>> sim.reset()
>>> sim.step(sim.station.embodiment.home_action())
>>> sim.joint_state(), sim.tcp_pose("left"), sim.images()["head_camera"].shape
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from pydrake.all import RigidTransform, Simulator

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.sim.cameras import extrinsic_matrix, intrinsic_matrix, intrinsics
from bicoord_drake.sim.station import Station, build_station  # noqa: F401  (re-export)


class PhysicsDivergedError(RuntimeError):
    """The simulated state became non-finite: the physics diverged (a numerical failure of the
    simulation, not an invalid action). The rollout cannot go on."""


class Simulation:
    """A Drake simulator over a :class:`Station`, advanced one control step per action."""

    def __init__(self, station: Station) -> None:
        self.station = station
        self.simulator = Simulator(station.diagram)
        self.context = self.simulator.get_mutable_context()
        self._action_port = station.diagram.GetInputPort("action")
        self._steps = 0
        self.reset()

    # ---------------------------------------------------------------- stepping
    def reset(self, action: np.ndarray | None = None) -> None:
        """Back to t = 0: default (scene) object poses, arms at `action` (default: home)."""
        st = self.station
        self.context.SetTime(0.0)
        st.diagram.SetDefaultContext(self.context)
        action = st.embodiment.home_action() if action is None else self._check(action)
        plant_context = self.plant_context
        g, layout = st.embodiment.arm.gripper, st.layout
        for side in SIDES:
            finger = g.finger_position(action[layout.gripper(side)])
            q = np.concatenate([action[layout.arm(side)], [finger] * 2])
            st.plant.SetPositions(plant_context, st.arms[side], q)
            st.plant.SetVelocities(
                plant_context, st.arms[side], np.zeros(st.plant.num_velocities(st.arms[side]))
            )
        st.interpolator.set_action(
            st.interpolator.GetMyMutableContextFromRoot(self.context), action
        )
        self._action_port.FixValue(self.context, action)
        self.simulator.Initialize()
        self._steps = 0

    def restore(
        self,
        plant_state: np.ndarray,
        action: np.ndarray,
        previous_action: np.ndarray,
        frame: int,
    ) -> None:
        """Set the simulation to recorded control step `frame` (>= 1): plant ``[q; v]``, the
        action in effect (latched at the previous control step, interpolated from
        `previous_action`), time and step count.

        Replaying the recorded actions from `frame` then reproduces the recording exactly (the
        stage resets of :mod:`bicoord_drake.env`). Frame 0 is :meth:`reset`."""
        st = self.station
        x = np.asarray(plant_state, dtype=float)
        n = st.plant.num_multibody_states()
        if x.shape != (n,):
            raise ValueError(f"plant state must have shape ({n},), got {x.shape}: another scene?")
        if frame < 1:
            raise ValueError("restore a frame >= 1 (frame 0 is reset())")
        action, previous_action = self._check(action), self._check(previous_action)
        period = st.config.control_period
        self.context.SetTime(frame * period)
        st.plant.SetPositionsAndVelocities(self.plant_context, x)
        # The interpolator's discrete state [previous, current, latch time] as it was at `frame`.
        interp = st.interpolator.GetMyMutableContextFromRoot(self.context)
        interp.get_mutable_discrete_state(0).set_value(
            np.concatenate([previous_action, action, [(frame - 1) * period]])
        )
        self._action_port.FixValue(self.context, action)
        self.simulator.Initialize()
        self._steps = int(frame)

    def step(self, action: np.ndarray) -> None:
        """Apply `action` for one control period (first-order hold from the previous one).

        Raises :class:`PhysicsDivergedError` if the state becomes non-finite, naming the
        fastest free body before the step."""
        self._action_port.FixValue(self.context, self._check(action))
        plant = self.station.plant
        before = plant.GetPositionsAndVelocities(self.plant_context).copy()
        self._steps += 1
        try:
            self.simulator.AdvanceTo(self._steps * self.station.config.control_period)
        except RuntimeError as exc:
            if "non-finite" not in str(exc):
                raise
            raise PhysicsDivergedError(self._divergence(before)) from exc
        if not np.all(np.isfinite(plant.GetPositionsAndVelocities(self.plant_context))):
            raise PhysicsDivergedError(self._divergence(before))

    def _divergence(self, before: np.ndarray) -> str:
        """Why control step `self._steps` diverged: the fastest free body at its start."""
        plant = self.station.plant
        context = plant.CreateDefaultContext()
        plant.SetPositionsAndVelocities(context, before)
        speeds = []
        for index in plant.GetFloatingBaseBodies():
            body = plant.get_body(index)
            V = body.EvalSpatialVelocityInWorld(context)
            spin, speed = np.linalg.norm(V.rotational()), np.linalg.norm(V.translational())
            speeds.append((spin, speed, body.name()))
        message = f"the physics diverged during control step {self._steps}"
        if speeds:
            spin, speed, name = max(speeds)
            message += (
                f"; at its start {name!r} spun at {spin:.0f} rad/s and moved at {speed:.2f} m/s "
                f"(plant step {plant.time_step():.4f} s)"
            )
        return message

    def _check(self, action: np.ndarray) -> np.ndarray:
        a = self.station.layout.check(action)
        if not np.all(np.isfinite(a)):
            raise ValueError("action contains NaN or infinite values")
        return a

    # ---------------------------------------------------------------- reading
    @property
    def time(self) -> float:
        return self.context.get_time()

    @property
    def steps(self) -> int:
        return self._steps

    @property
    def plant_context(self):
        return self.station.plant.GetMyMutableContextFromRoot(self.context)

    def _eval(self, name: str):
        return self.station.diagram.GetOutputPort(name).Eval(self.context)

    def joint_state(self) -> np.ndarray:
        """[left q (n), left opening, right q (n), right opening] (``station.layout``)."""
        return np.array(self._eval("joint_state"))

    def tcp_pose(self, side: str) -> np.ndarray:
        """TCP pose of one arm: xyz + quaternion wxyz, world frame."""
        return np.array(self._eval(f"{side}_tcp_pose"))

    def object_poses(self) -> dict[str, np.ndarray]:
        flat = np.array(self._eval("object_poses"))
        return {name: flat[7 * i : 7 * i + 7] for i, name in enumerate(self.station.object_bodies)}

    def joint_positions(self) -> dict[str, float]:
        """Each sliding object's joint position (m from its scene pose; a drawer's opening)."""
        ctx = self.plant_context
        return {name: float(j.get_translation(ctx)) for name, j in self.station.slides.items()}

    def contact_pairs(self) -> set[tuple[int, int]]:
        """Body-index pairs (sorted) in contact now, from point and hydroelastic contact."""
        st = self.station
        results = st.plant.get_contact_results_output_port().Eval(self.plant_context)
        pairs = set()
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            pairs.add(tuple(sorted((int(info.bodyA_index()), int(info.bodyB_index())))))
        if results.num_hydroelastic_contacts():
            inspector = st.scene_graph.model_inspector()
            for i in range(results.num_hydroelastic_contacts()):
                surface = results.hydroelastic_contact_info(i).contact_surface()
                a, b = (
                    int(st.plant.GetBodyFromFrameId(inspector.GetFrameId(g)).index())
                    for g in (surface.id_M(), surface.id_N())
                )
                pairs.add(tuple(sorted((a, b))))
        return pairs

    def finger_contacts(self) -> dict[str, set[str]]:
        """For each scene object, the sides ('left', 'right') whose fingers touch it now."""
        return self.contacts()[1]

    def robot_contacts(self) -> dict[str, set[str]]:
        """For each scene object, the sides ('left', 'right') any of whose bodies (fingers, palm,
        wrist, links, base) touch it now."""
        return self.contacts()[0]

    def contacts(self) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
        """(robot contacts, finger contacts) of every scene object, from one pass over the
        contact pairs (see :meth:`robot_contacts`, :meth:`finger_contacts`)."""
        objects = self.station.object_bodies
        robot: dict[str, set[str]] = {name: set() for name in objects}
        fingers: dict[str, set[str]] = {name: set() for name in objects}
        by_body, sides, finger_bodies = self._contact_bodies
        for a, b in self.contact_pairs():
            for body, other in ((a, b), (b, a)):
                if body in sides and other in by_body:
                    robot[by_body[other]].add(sides[body])
                    if body in finger_bodies:
                        fingers[by_body[other]].add(sides[body])
        return robot, fingers

    @cached_property
    def _contact_bodies(self) -> tuple[dict[int, str], dict[int, str], frozenset[int]]:
        """Body index -> object name, arm body index -> side, and the finger body indices."""
        st = self.station
        by_body = {int(body.index()): name for name, body in st.object_bodies.items()}
        sides = {
            int(index): side
            for side, inst in st.arms.items()
            for index in st.plant.GetBodyIndices(inst)
        }
        fingers = frozenset(
            int(st.plant.GetBodyByName(name, inst).index())
            for inst in st.arms.values()
            for name in ("left_finger", "right_finger")
        )
        return by_body, sides, fingers

    def images(self, depth: bool = False) -> dict[str, np.ndarray]:
        """RGB (H, W, 3) uint8 per camera; with `depth`, also '<cam>_depth' (H, W) uint16 mm."""
        out = {}
        for name in self.station.cameras:
            out[name] = np.array(self._eval(f"{name}_rgb").data, copy=True)[:, :, :3]
            if depth:
                if not self.station.config.cameras.depth:
                    raise ValueError("depth was not enabled in the station's CameraConfig")
                out[f"{name}_depth"] = np.array(self._eval(f"{name}_depth").data, copy=True)[
                    :, :, 0
                ]
        return out

    def label_image(self, camera: str) -> np.ndarray:
        """Per-pixel render labels (H, W) int: the plant body index of what is seen."""
        return np.array(self._eval(f"{camera}_label").data, copy=True)[:, :, 0]

    def camera_pose(self, camera: str) -> RigidTransform:
        """X_WC of a camera (Drake/OpenCV axes); the sensor body is the camera frame itself."""
        return self._eval(f"{camera}_pose")

    def intrinsic_cv(self, camera: str) -> np.ndarray:
        mount = self.station.cameras[camera]
        return intrinsic_matrix(intrinsics(self.station.config.cameras, mount.fov_y_deg))

    def extrinsic_cv(self, camera: str) -> np.ndarray:
        return extrinsic_matrix(self.camera_pose(camera))
