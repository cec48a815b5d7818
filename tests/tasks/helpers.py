"""Synthetic world states for the task tests (no Drake): a task scene's initial state with some
poses, gripper commands, contacts and velocities overridden, a predicate's value after a number
of identical frames at 15 Hz, and the product of two quaternions."""

from dataclasses import replace

from bicoord_drake.stages import WorldState
from bicoord_drake.stages.predicates import reset_predicate
from tests.stages import helpers as stage_tests


def state_with(scene, poses=None, openings=(1.0, 1.0), contacts=None, velocities=None, step=0):
    """`scene`'s initial state with `poses`, the gripper commands `openings` (left, right),
    `contacts` and `velocities` overridden, at `step` (15 Hz): tests.stages.helpers.state, its
    arguments positional, keeping the initial positions of the scene's sliding joints (a drawer)."""
    s = stage_tests.state(
        scene, poses=poses, openings=openings, contacts=contacts, velocities=velocities, step=step
    )
    return replace(s, joint_positions=WorldState.initial(scene).joint_positions)


def after(pred, state, frames=8):
    """`pred` after `frames` identical updates at 15 Hz (stateful predicates see time pass)."""
    reset_predicate(pred)
    return [pred(replace(state, step=k, time=k / 15)) for k in range(frames)][-1]


def quat_mul(a, b):
    """The Hamilton product a * b of two quaternions wxyz (b's rotation, then a's)."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return (
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    )
