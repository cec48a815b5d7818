"""Leaf systems of the station: action interpolation, gravity feed-forward, state readout.

The action is ``[left q (n), left opening, right q (n), right opening]`` for arms of n joints
(:class:`~bicoord_drake.models.layout.ActionLayout`; 14 numbers for the ViperX pair). Every
control period the :class:`ActionInterpolator` latches the new action and, until the next period,
moves the PD targets linearly from the previous action to it (a first-order hold). Expert and
policies drive the robot through this one path.

The targets move no faster than the servos can (each joint's ``velocity_limit``, the fingers'
``finger_velocity_limit``): a jump in the action is followed at that speed over the next periods,
as a position-controlled servo with a profile velocity does. The experts' plans keep within these
limits, so only actions that ask for more (a flailing policy: targets jumping across the range
from one period to the next, driving the joints at ten times the servos' speed into the table
and into the other links until the contact solver threw objects at 15+ m/s and diverged) are
slowed.
"""

from __future__ import annotations

import numpy as np
from pydrake.all import (
    AbstractValue,
    BasicVector,
    Context,
    LeafSystem,
    ModelInstanceIndex,
    MultibodyPlant,
    RigidTransform,
)

from bicoord_drake.models.embodiment import SIDES, Embodiment
from bicoord_drake.models.layout import action_layout


class ActionInterpolator(LeafSystem):
    """Latches the action every control period; outputs per-arm PD desired states (FOH).

    Discrete state: ``[previous action (A), current action (A), latch time (1)]`` for actions
    of A = 2 (n + 1) numbers. Output ``desired_states`` (2 A): the left arm's then the right
    arm's PD desired state, each in actuator order ``[q arm (n), finger (1), v arm (n), finger
    velocity (1)]`` (the layout of the plant's desired-state input ports). One output for both
    arms, split by a native ``Demultiplexer`` in the station: the plant reads it every step, so
    it is computed once.
    """

    def __init__(self, embodiment: Embodiment, control_period: float) -> None:
        super().__init__()
        self._gripper = embodiment.arm.gripper
        self._period = control_period
        layout = action_layout(embodiment)
        size, width = layout.action_size, layout.arm_width
        self._size, self._width = size, width
        self._action = self.DeclareVectorInputPort("action", size)
        # The largest change of each action entry per period, with a hair of slack so that
        # plans sampled exactly at a limit pass unchanged.
        self._max_step = embodiment.action_speed_limits() * control_period * (1.0 + 1e-6)
        home = embodiment.home_action()
        self._state = self.DeclareDiscreteState(np.concatenate([home, home, [0.0]]))
        self.DeclarePeriodicDiscreteUpdateEvent(control_period, 0.0, self._latch)
        # Where the action's entries go in the desired-state vector [left q, left v, right q,
        # right v] (each q and v block is one side's `width` numbers: arm joints, then finger).
        self._q_slots = np.concatenate(
            [np.arange(2 * k * width, (2 * k + 1) * width) for k in range(len(SIDES))]
        )
        self._v_slots = self._q_slots + width
        # each arm's finger position (its velocity: + width)
        self._finger_q = self._q_slots[layout.gripper_indices]
        self._desired_states = self.DeclareVectorOutputPort(
            "desired_states", 2 * size, self._desired
        )

    def action_input_port(self):
        return self._action

    def desired_states_output_port(self):
        return self._desired_states

    def desired_state_sizes(self) -> list[int]:
        """The size of each arm's desired state, in ``SIDES`` order (the output's split)."""
        return [2 * self._width] * len(SIDES)

    def set_action(self, context: Context, action: np.ndarray) -> None:
        """Hold `action` from now on without interpolation (used at reset)."""
        a = np.asarray(action, dtype=float)
        context.get_mutable_discrete_state(self._state).set_value(
            np.concatenate([a, a, [context.get_time()]])
        )

    def _latch(self, context: Context, discrete_state) -> None:
        x = context.get_discrete_state(self._state).get_value()
        current = x[self._size : 2 * self._size]
        step = np.clip(self._action.Eval(context) - current, -self._max_step, self._max_step)
        discrete_state.get_mutable_vector(self._state).set_value(
            np.concatenate([current, current + step, [context.get_time()]])
        )

    def _desired(self, context: Context, output: BasicVector) -> None:
        x = context.get_discrete_state(self._state).get_value()
        size = self._size
        prev, curr, t0 = x[0:size], x[size : 2 * size], x[2 * size]
        elapsed = context.get_time() - t0
        s = min(max(elapsed / self._period, 0.0), 1.0)
        delta = curr - prev
        # The segment's velocity holds on the closed period: the plant step that coincides with
        # the next latch still reads this segment, and a zero there would brake the arm.
        moving = elapsed <= self._period * (1.0 + 1e-9)
        # Layout per arm: [q arm (n), finger, v arm (n), finger velocity]; the action's opening
        # (the last of each arm's n + 1 numbers) becomes a finger position and a finger velocity.
        out = np.empty(2 * size)
        out[self._q_slots] = prev + s * delta
        out[self._v_slots] = delta / self._period if moving else 0.0
        g = self._gripper
        out[self._finger_q] = g.finger_position(out[self._finger_q])
        out[self._finger_q + self._width] *= g.finger_max - g.finger_min
        output.SetFromVector(out)


class GravityFeedForward(LeafSystem):
    """Actuation that cancels gravity on each arm, computed on a robot-only control plant.

    Output ``actuation``: the left arm's actuators then the right arm's (split by a native
    ``Demultiplexer`` in the station, so the gravity forces are computed once per plant step).
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        arms: dict[str, ModelInstanceIndex],
        control_plant: MultibodyPlant,
        control_arms: dict[str, ModelInstanceIndex],
    ) -> None:
        super().__init__()
        self._cplant = control_plant
        self._ccontext = control_plant.CreateDefaultContext()
        self._state = self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self._act_dofs = {
            side: [
                control_plant.get_joint_actuator(i).joint().velocity_start()
                for i in control_plant.GetJointActuatorIndices(inst)
            ]
            for side, inst in control_arms.items()
        }
        self._all_act_dofs = [i for side in SIDES for i in self._act_dofs[side]]
        # Index into the station plant's state of each control-plant position, in its order.
        index = np.arange(plant.num_positions(), dtype=float)
        arm_positions = np.zeros(control_plant.num_positions())
        for side, inst in arms.items():
            control_plant.SetPositionsInArray(
                control_arms[side], plant.GetPositionsFromArray(inst, index), arm_positions
            )
        self._arm_positions = arm_positions.astype(int)
        self._actuation = self.DeclareVectorOutputPort(
            "actuation", len(self._all_act_dofs), self._calc
        )

    def actuation_sizes(self) -> list[int]:
        """The number of actuators of each arm, in ``SIDES`` order (the output's split)."""
        return [len(self._act_dofs[side]) for side in SIDES]

    def _calc(self, context: Context, output: BasicVector) -> None:
        x = self._state.Eval(context)
        self._cplant.SetPositions(self._ccontext, x[self._arm_positions])
        tau_g = self._cplant.CalcGravityGeneralizedForces(self._ccontext)
        output.SetFromVector(-tau_g[self._all_act_dofs])


class StationObserver(LeafSystem):
    """Joint state, TCP poses and object poses, read from the plant.

    Outputs: ``joint_state`` = [left q (n), left opening, right q (n), right opening] (the
    action's layout);
    ``left_tcp_pose`` / ``right_tcp_pose`` = xyz + quaternion wxyz in world, its sign the one
    nearer the arm's TCP orientation at home (:func:`same_hemisphere`: Drake's w >= 0 would
    flip it wherever w crosses 0, as it does for a TCP pointing down, so a policy's end-pose
    input would jump between q and -q for an unchanged orientation);
    ``object_poses`` = 7 numbers per scene object, in scene order.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        embodiment: Embodiment,
        arms: dict[str, ModelInstanceIndex],
        object_bodies: list,
    ) -> None:
        super().__init__()
        self._plant, self._gripper = plant, embodiment.arm.gripper
        self._arms = arms
        self._state = self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        gripper_name = embodiment.arm.gripper_link.name
        self._gripper_body = {
            s: plant.GetBodyByName(gripper_name, i).index() for s, i in arms.items()
        }
        self._X_GT = RigidTransform([embodiment.arm.gripper.tcp_x, 0.0, 0.0])
        self._home_quaternion = self._home_tcp_quaternions(embodiment)
        self._object_bodies = [b.index() for b in object_bodies]
        layout = action_layout(embodiment)
        self._n = layout.arm_joints
        self.DeclareVectorOutputPort("joint_state", layout.state_size, self._joint_state)
        for side in SIDES:
            self.DeclareVectorOutputPort(
                f"{side}_tcp_pose",
                7,
                lambda context, output, side=side: self._tcp(context, output, side),
            )
        self.DeclareVectorOutputPort("object_poses", 7 * max(len(object_bodies), 0), self._objects)

    def _joint_state(self, context: Context, output: BasicVector) -> None:
        x = self._state.Eval(context)
        q_all = x[: self._plant.num_positions()]
        out = []
        for side in SIDES:
            q = self._plant.GetPositionsFromArray(self._arms[side], q_all)
            out.extend(q[: self._n])
            out.append(float(self._gripper.opening(q[self._n])))
        output.SetFromVector(np.asarray(out))

    def _home_tcp_quaternions(self, embodiment: Embodiment) -> dict[str, np.ndarray]:
        """Each arm's TCP orientation (wxyz) with its joints at home."""
        plant = self._plant
        context = plant.CreateDefaultContext()
        n = len(embodiment.home)
        out = {}
        for side, instance in self._arms.items():
            q = plant.GetPositions(context, instance)
            q[:n] = embodiment.home_of(side)
            plant.SetPositions(context, instance, q)
            X_WG = plant.EvalBodyPoseInWorld(context, plant.get_body(self._gripper_body[side]))
            out[side] = (X_WG @ self._X_GT).rotation().ToQuaternion().wxyz()
        return out

    def _tcp(self, context: Context, output: BasicVector, side: str) -> None:
        X_WG = self._poses.Eval(context)[self._gripper_body[side]]
        pose = pose_to_vector(X_WG @ self._X_GT)
        pose[3:] = same_hemisphere(pose[3:], self._home_quaternion[side])
        output.SetFromVector(pose)

    def _objects(self, context: Context, output: BasicVector) -> None:
        poses = self._poses.Eval(context)
        if self._object_bodies:
            output.SetFromVector(
                np.concatenate([pose_to_vector(poses[b]) for b in self._object_bodies])
            )


def same_hemisphere(quaternion: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """`quaternion` or its negative (the same rotation), whichever is nearer `reference`: a
    continuous choice for every orientation less than 180 degrees from the reference."""
    q = np.asarray(quaternion, dtype=float)
    return -q if float(q @ np.asarray(reference, dtype=float)) < 0.0 else q


def pose_to_vector(X: RigidTransform) -> np.ndarray:
    """RigidTransform -> [x, y, z, qw, qx, qy, qz]."""
    return np.concatenate([X.translation(), X.rotation().ToQuaternion().wxyz()])
