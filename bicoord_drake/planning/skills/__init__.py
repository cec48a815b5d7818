"""Skills: the vocabulary task experts are written in.

A skill plans one arm's part of a stage as an :class:`ArmPlan` - joint samples on the control
grid, a gripper-opening schedule and attach/detach events - from IK keyframes, collision-checked
joint paths and ruckig timing. Every skill is a function whose first argument is the shared
:class:`SkillContext` (the planning model, the arms' joint angles and openings, limits and
clearances), which it advances. :func:`merge` runs two arm plans at the same time and checks the
combined two-arm motion against collisions sample by sample; if the arms would meet it delays
one of them until they do not, so both arms act together whenever that is safe. The result, a
:class:`Motion`, turns into the actions the station takes (its layout: 2 (n + 1) numbers for
two n-joint arms, 14 for the ViperX pair).

========================  ===================================================================
module                    skills
========================  ===================================================================
:mod:`.core`              :class:`ArmPlan`, :class:`Motion`, :class:`SkillContext` (``sync``,
                          ``refresh_grasps``: a held object out of its hand is ``grasp_lost``,
                          ``transaction``, ``rehearsal``), :func:`merge`,
                          :func:`combine` (two plans as they are, unchecked), :func:`hold`,
                          :func:`hold_still` (both arms), :func:`periods` (seconds -> samples),
                          :func:`plan_both` (two arms' parts, either planned first)
:mod:`.arm`               :func:`move`, :func:`move_tcp`, :func:`solve_tcp`, :func:`grip`,
                          :func:`lift`, :func:`retreat`, :func:`wait_beside`,
                          :func:`tcp_deviation`
:mod:`.pick_place`        :func:`pick`, :func:`place`, :func:`drop_into`, :func:`carry_above`,
                          :func:`stabilize`, :func:`release`
:mod:`.tracking`          :func:`track` (a TCP path at every sample), :func:`push`
:mod:`.pour`              :func:`pour` (tilt a held container about its rim and back)
:mod:`.sliding`           :func:`pull` (drag a held object along a straight line, e.g. a
                          block out from under a stack)
:mod:`.handover`          :func:`handover` (mid-air, both arms arrive at once; options for the
                          orientations at the meeting and the receiver's grasps),
                          :func:`crossing_grasps`, :func:`meet_motion`
:mod:`.toss`              :func:`toss` (a throw released on the control grid into a container
                          the other arm holds under the predicted landing point)
:mod:`.bimanual`          two hands on one object: :func:`two_hand_grasps` (chosen together;
                          a pot by its two handles: :func:`handle_pairs`),
                          :func:`pick_together`, :func:`grip_together` (same control steps),
                          :func:`track_together` / :func:`carry_together` (the object's path,
                          both arms by one timing), :func:`release_together`,
                          :func:`on_wrist_branch` (the same TCP pose on the other wrist branch)
:mod:`.drawer`            :func:`grasp_handle`, :func:`slide_drawer` (the TCP along a
                          drawer's slide axis; the model's drawer follows),
                          :func:`let_go_handle`
:mod:`.overlap`           :func:`leave_as_arrives` (the leaving arm's way back timed to end
                          with the arriving arm's work), :func:`slowed_after`, :func:`split_at`
:mod:`.turns`             :func:`arrive_as_leaves` (turn-taking at a shared spot: one arm
                          arrives as the other leaves), :func:`take_turn` (the same with
                          fallbacks when the arms conflict), :func:`arrival_delay`,
                          :func:`first_step_in_zone`
========================  ===================================================================

Every planning failure raises :class:`~bicoord_drake.planning.errors.PlanningError` with a
reason; the two-arm skills (handover, toss, the ``*_together`` skills) leave the context
unchanged when they fail.

>>> ctx = SkillContext(view.planning_model())                      # doctest: +SKIP
>>> left = pick(ctx, "left", "cube_a")
>>> right = pick(ctx, "right", "cube_b")
>>> motion = merge(ctx, left, right)     # both arms pick at once
>>> for action in motion.actions(): sim.step(action)
"""

from bicoord_drake.planning.skills.arm import (
    RELEASE_FORCE_RATE,
    env_gap,
    gentle_release_time,
    grip,
    lift,
    move,
    move_tcp,
    retreat,
    solve_tcp,
    tcp_deviation,
    wait_beside,
)
from bicoord_drake.planning.skills.bimanual import (
    GraspPair,
    carry_together,
    grip_together,
    handle_pairs,
    on_wrist_branch,
    pick_together,
    release_together,
    track_together,
    two_hand_grasps,
)
from bicoord_drake.planning.skills.core import (
    GRASP_LOST_DISTANCE,
    ArmPlan,
    Motion,
    SkillContext,
    combine,
    hold,
    hold_still,
    merge,
    periods,
    plan_both,
)
from bicoord_drake.planning.skills.handover import (
    ReceiverGrasps,
    crossing_grasps,
    fingers_cross,
    handover,
    meet_motion,
)
from bicoord_drake.planning.skills.overlap import leave_as_arrives, slowed_after, split_at
from bicoord_drake.planning.skills.pick_place import (
    carry_above,
    drop_into,
    pick,
    pick_sliding,
    place,
    release,
    stabilize,
)
from bicoord_drake.planning.skills.pour import pour
from bicoord_drake.planning.skills.shapes import half_extent
from bicoord_drake.planning.skills.sliding import pull
from bicoord_drake.planning.skills.toss import least_spin_velocity, toss
from bicoord_drake.planning.skills.tracking import push, track
from bicoord_drake.planning.skills.turns import (
    arrival_delay,
    arrive_as_leaves,
    first_step_in_zone,
    take_turn,
)

__all__ = [
    "GRASP_LOST_DISTANCE",
    "ArmPlan",
    "GraspPair",
    "Motion",
    "ReceiverGrasps",
    "SkillContext",
    "arrival_delay",
    "arrive_as_leaves",
    "carry_above",
    "carry_together",
    "combine",
    "crossing_grasps",
    "drop_into",
    "fingers_cross",
    "first_step_in_zone",
    "RELEASE_FORCE_RATE",
    "gentle_release_time",
    "grip",
    "grip_together",
    "handle_pairs",
    "half_extent",
    "handover",
    "hold",
    "hold_still",
    "periods",
    "least_spin_velocity",
    "leave_as_arrives",
    "lift",
    "meet_motion",
    "merge",
    "plan_both",
    "on_wrist_branch",
    "move",
    "move_tcp",
    "pick",
    "pick_sliding",
    "pick_together",
    "place",
    "pour",
    "pull",
    "push",
    "release",
    "release_together",
    "retreat",
    "wait_beside",
    "env_gap",
    "solve_tcp",
    "slowed_after",
    "split_at",
    "stabilize",
    "take_turn",
    "tcp_deviation",
    "toss",
    "track",
    "track_together",
    "two_hand_grasps",
]
