"""Leaf systems of the station: action interpolation, gravity feed-forward, state readout.

The 14-dim action is ``[left 6 joints, left opening, right 6 joints, right opening]``. Every
control period the :class:`ActionInterpolator` latches the new action and, until the next period,
moves the PD targets linearly from the previous action to it (a first-order hold). Expert and
policies drive the robot through this one path.
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

ACTION_SIZE = 14


def split_action(action: np.ndarray) -> dict[str, tuple[np.ndarray, float]]:
    """14-vector -> {'left': (q6, opening), 'right': (q6, opening)}."""
    a = np.asarray(action, dtype=float)
    return {"left": (a[0:6], float(a[6])), "right": (a[7:13], float(a[13]))}


class ActionInterpolator(LeafSystem):
    """Latches the action every control period; outputs per-arm PD desired states (FOH).

    Discrete state: ``[previous action (14), current action (14), latch time (1)]``. Outputs
    ``left_desired_state`` / ``right_desired_state`` in actuator order ``[q arm (6), finger (1),
    v arm (6), finger velocity (1)]``, the layout of the plant's desired-state input ports.
    """

    def __init__(self, embodiment: Embodiment, control_period: float) -> None:
        super().__init__()
        self._gripper = embodiment.arm.gripper
        self._period = control_period
        self._action = self.DeclareVectorInputPort("action", ACTION_SIZE)
        home = embodiment.home_action()
        self._state = self.DeclareDiscreteState(np.concatenate([home, home, [0.0]]))
        self.DeclarePeriodicDiscreteUpdateEvent(control_period, 0.0, self._latch)
        for k, side in enumerate(SIDES):
            self.DeclareVectorOutputPort(
                f"{side}_desired_state",
                14,
                lambda context, output, k=k: self._desired(context, output, k),
            )

    def action_input_port(self):
        return self._action

    def set_action(self, context: Context, action: np.ndarray) -> None:
        """Hold `action` from now on without interpolation (used at reset)."""
        a = np.asarray(action, dtype=float)
        context.get_mutable_discrete_state(self._state).set_value(
            np.concatenate([a, a, [context.get_time()]])
        )

    def _latch(self, context: Context, discrete_state) -> None:
        x = context.get_discrete_state(self._state).get_value()
        new = self._action.Eval(context)
        discrete_state.get_mutable_vector(self._state).set_value(
            np.concatenate([x[14:28], new, [context.get_time()]])
        )

    def _desired(self, context: Context, output: BasicVector, k: int) -> None:
        x = context.get_discrete_state(self._state).get_value()
        prev, curr, t0 = x[0:14], x[14:28], x[28]
        elapsed = context.get_time() - t0
        s = np.clip(elapsed / self._period, 0.0, 1.0)
        target = prev + s * (curr - prev)
        # The segment's velocity holds on the closed period: the plant step that coincides with
        # the next latch still reads this segment, and a zero there would brake the arm.
        moving = elapsed <= self._period * (1.0 + 1e-9)
        velocity = (curr - prev) / self._period if moving else np.zeros(14)
        sl = slice(7 * k, 7 * k + 7)
        q, v = target[sl].copy(), velocity[sl].copy()
        q[6] = self._gripper.finger_position(q[6])
        v[6] = v[6] * (self._gripper.finger_max - self._gripper.finger_min)
        output.SetFromVector(np.concatenate([q, v]))


class GravityFeedForward(LeafSystem):
    """Actuation that cancels gravity on each arm, computed on a robot-only control plant."""

    def __init__(
        self,
        plant: MultibodyPlant,
        arms: dict[str, ModelInstanceIndex],
        control_plant: MultibodyPlant,
        control_arms: dict[str, ModelInstanceIndex],
    ) -> None:
        super().__init__()
        self._plant, self._arms = plant, arms
        self._cplant, self._carms = control_plant, control_arms
        self._ccontext = control_plant.CreateDefaultContext()
        self._state = self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self._act_dofs = {
            side: [
                control_plant.get_joint_actuator(i).joint().velocity_start()
                for i in control_plant.GetJointActuatorIndices(inst)
            ]
            for side, inst in control_arms.items()
        }
        for side in SIDES:
            self.DeclareVectorOutputPort(
                f"{side}_actuation",
                len(self._act_dofs[side]),
                lambda context, output, side=side: self._calc(context, output, side),
            )

    def _calc(self, context: Context, output: BasicVector, side: str) -> None:
        x = self._state.Eval(context)
        nq = self._plant.num_positions()
        for s, inst in self._arms.items():
            q = self._plant.GetPositionsFromArray(inst, x[:nq])
            self._cplant.SetPositions(self._ccontext, self._carms[s], q)
        tau_g = self._cplant.CalcGravityGeneralizedForces(self._ccontext)
        output.SetFromVector(-tau_g[self._act_dofs[side]])


class StationObserver(LeafSystem):
    """Joint state (14), TCP poses and object poses, read from the plant.

    Outputs: ``joint_state`` = [left q (6), left opening, right q (6), right opening];
    ``left_tcp_pose`` / ``right_tcp_pose`` = xyz + quaternion wxyz in world;
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
        self._object_bodies = [b.index() for b in object_bodies]
        self.DeclareVectorOutputPort("joint_state", ACTION_SIZE, self._joint_state)
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
            out.extend(q[:6])
            out.append(float(self._gripper.opening(q[6])))
        output.SetFromVector(np.asarray(out))

    def _tcp(self, context: Context, output: BasicVector, side: str) -> None:
        X_WG = self._poses.Eval(context)[self._gripper_body[side]]
        output.SetFromVector(pose_to_vector(X_WG @ self._X_GT))

    def _objects(self, context: Context, output: BasicVector) -> None:
        poses = self._poses.Eval(context)
        if self._object_bodies:
            output.SetFromVector(
                np.concatenate([pose_to_vector(poses[b]) for b in self._object_bodies])
            )


def pose_to_vector(X: RigidTransform) -> np.ndarray:
    """RigidTransform -> [x, y, z, qw, qx, qy, qz]."""
    return np.concatenate([X.translation(), X.rotation().ToQuaternion().wxyz()])
