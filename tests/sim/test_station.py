"""The station: PD tracking, gravity feed-forward, the action path and its validation."""

import numpy as np
import pytest
from pydantic import ValidationError
from pydrake.all import Role

from bicoord_drake.config import CameraConfig, StationConfig, parse_resolution
from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.models.scene import demo_scene
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station


@pytest.fixture(scope="module")
def sim():
    return Simulation(build_station(demo_scene("cubes"), StationConfig(render=False)))


def _target(station):
    a = station.embodiment.home_action().copy()
    a[0:6] = [0.3, -0.5, 0.8, 0.2, 0.6, -0.3]
    a[7:13] = [-0.3, -0.4, 0.9, -0.2, 0.5, 0.3]
    return a


def test_pd_tracking_error_below_a_hundredth_radian_after_settling(sim):
    sim.reset()
    a = _target(sim.station)
    for _ in range(30):  # 2 s
        sim.step(a)
    err = np.abs(sim.joint_state() - a)
    assert err[[0, 1, 2, 3, 4, 5, 7, 8, 9, 10, 11, 12]].max() < 0.01


def _near(station):
    """An action within one control period's reach of home (no joint faster than its limit)."""
    a = station.embodiment.home_action().copy()
    a[0:6] += [0.1, -0.15, 0.12, 0.05, -0.1, 0.2]
    a[7:13] += [-0.1, 0.1, -0.05, 0.15, 0.08, -0.2]
    return a


def test_first_order_hold_moves_targets_linearly_between_actions(sim):
    sim.reset()
    st = sim.station
    home = st.embodiment.home_action()
    a = _near(st)
    interp = st.interpolator
    ctx = interp.GetMyContextFromRoot(sim.context)
    sim.step(a)  # latched at t = 0: the target reaches `a` at t = 1/15
    desired = interp.desired_states_output_port().Eval(ctx)[:14]
    np.testing.assert_allclose(desired[:6], a[:6], atol=1e-9)
    # half-way through the next period the target is half-way from a to b
    b = home.copy()
    sim._action_port.FixValue(sim.context, b)
    sim.simulator.AdvanceTo(1.5 / 15)
    desired = interp.desired_states_output_port().Eval(ctx)[:14]
    np.testing.assert_allclose(desired[:6], (a[:6] + b[:6]) / 2, atol=1e-9)


def test_gravity_feed_forward_holds_a_stretched_arm(sim):
    sim.reset()
    a = sim.station.embodiment.home_action().copy()
    a[1], a[2], a[4] = 0.6, -0.6, 0.0  # arm stretched forward: the largest gravity torque
    for _ in range(30):
        sim.step(a)
    assert np.abs(sim.joint_state()[:6] - a[:6]).max() < 0.005


def test_objects_rest_on_the_table(sim):
    sim.reset()
    for _ in range(15):
        sim.step(sim.station.embodiment.home_action())
    for name, pose in sim.object_poses().items():
        assert pose[2] == pytest.approx(0.77, abs=0.002), name


def test_same_actions_give_identical_states():
    def run():
        s = Simulation(build_station(demo_scene("cubes"), StationConfig(render=False)))
        a = _target(s.station)
        for _ in range(10):
            s.step(a)
        return s.joint_state(), s.object_poses()

    (q1, o1), (q2, o2) = run(), run()
    np.testing.assert_array_equal(q1, q2)
    for name in o1:
        np.testing.assert_array_equal(o1[name], o2[name])


def test_restore_continues_a_run_exactly(sim):
    """Restoring the plant state and actions of step k, then stepping, matches the run that
    went through step k (what stage resets rely on)."""
    home = sim.station.embodiment.home_action()
    actions = [home + 0.05 * k * np.r_[np.ones(6), 0.0, -np.ones(6), 0.0] for k in range(6)]
    sim.reset(home)
    states = []
    for a in actions:
        sim.step(a)
        states.append(sim.station.plant.GetPositionsAndVelocities(sim.plant_context).copy())
    k = 3
    sim.reset(home)
    sim.restore(states[k - 1], actions[k - 1], actions[k - 2], k)
    assert sim.steps == k and sim.time == pytest.approx(k * sim.station.config.control_period)
    for a in actions[k:]:
        sim.step(a)
    final = sim.station.plant.GetPositionsAndVelocities(sim.plant_context)
    np.testing.assert_array_equal(final, states[-1])
    with pytest.raises(ValueError, match="shape"):
        sim.restore(states[0][:-1], home, home, 1)
    with pytest.raises(ValueError, match="frame"):
        sim.restore(states[0], home, home, 0)


@pytest.mark.parametrize("bad", [np.zeros(13), np.full(14, np.nan)])
def test_bad_actions_are_refused_and_not_executed(sim, bad):
    sim.reset()
    before = sim.time
    with pytest.raises(ValueError, match="action"):
        sim.step(bad)
    assert sim.time == before


def test_config_errors_name_the_field():
    with pytest.raises(ValidationError, match="time_step"):
        StationConfig(time_step=-1)
    with pytest.raises(ValidationError, match="names"):
        CameraConfig(names=("top_camera",))
    with pytest.raises(ValidationError, match="contact_model"):
        StationConfig(contact_model="magic")
    with pytest.raises(ValueError, match="WIDTHxHEIGHT"):
        parse_resolution("320by240")
    assert parse_resolution("640x480") == (640, 480)


def test_target_velocity_holds_up_to_the_period_boundary(sim):
    """At the instant of the next latch the plant still reads the finishing segment's velocity
    (a zero there brakes a fast arm through the PD damping)."""
    sim.reset()
    st = sim.station
    a = _near(st)
    sim.step(a)  # now exactly at the end of the first segment, before the next latch
    ctx = st.interpolator.GetMyContextFromRoot(sim.context)
    desired = st.interpolator.desired_states_output_port().Eval(ctx)[:14]
    home = st.embodiment.home_action()
    np.testing.assert_allclose(desired[7:13], (a[:6] - home[:6]) * 15.0, rtol=1e-9)


def test_targets_follow_a_jump_no_faster_than_the_servos(sim):
    """An action far from the current targets is followed at each joint's velocity limit (and
    the fingers' speed), as a servo does, and reached once the time allows."""
    sim.reset()
    st = sim.station
    emb = st.embodiment
    home = emb.home_action()
    far = _target(st)
    far[6], far[13] = 0.0, 1.0 - home[13]  # grippers jump too
    g = emb.arm.gripper
    rate = np.tile(
        [j.velocity_limit for j in emb.arm.joints]
        + [g.finger_velocity_limit / (g.finger_max - g.finger_min)],
        2,
    )
    period = st.config.control_period
    ctx = st.interpolator.GetMyContextFromRoot(sim.context)
    latched = home.copy()
    for k in range(1, 20):
        sim.step(far)
        state = ctx.get_discrete_state(0).get_value()
        now = state[14:28].copy()  # the target the segment ends at
        assert np.all(np.abs(now - latched) <= rate * period * (1 + 1e-5))
        expected = latched + np.clip(far - latched, -rate * period, rate * period)
        np.testing.assert_allclose(now, expected, atol=1e-6, err_msg=f"period {k}")
        latched = now
    np.testing.assert_allclose(latched, far, atol=1e-12)  # reached within 19 periods
    # the joints moved no faster than the servos (within the PD's small overshoot)
    v = sim.station.plant.GetVelocities(sim.plant_context)
    assert np.abs(v[: 2 * len(emb.arm.joints)]).max() < 1.5 * max(rate[:6])


def test_contact_approximation_is_the_plants():
    station = build_station(
        demo_scene("cubes"), StationConfig(render=False, contact_approximation="lagged")
    )
    assert station.plant.get_discrete_contact_approximation().name == "kLagged"
    sap = build_station(
        demo_scene("cubes"), StationConfig(render=False, contact_approximation="sap")
    )
    assert sap.plant.get_discrete_contact_approximation().name == "kSap"
    assert sap.plant.get_sap_near_rigid_threshold() == StationConfig().sap_near_rigid_threshold
    with pytest.raises(ValidationError, match="contact_approximation"):
        StationConfig(contact_approximation="tamsi")


def test_hydroelastic_margin_reaches_every_hydroelastic_geometry():
    station = build_station(
        demo_scene("cubes"), StationConfig(render=False, hydroelastic_margin=1e-4)
    )
    inspector = station.scene_graph.model_inspector()
    margins = [
        inspector.GetProximityProperties(g).GetPropertyOrDefault("hydroelastic", "margin", 0.0)
        for g in inspector.GetAllGeometryIds()
        if inspector.GetProximityProperties(g) is not None
        and inspector.GetProximityProperties(g).HasProperty("hydroelastic", "compliance_type")
    ]
    assert len(margins) > 10 and all(m == pytest.approx(1e-4) for m in margins)
    with pytest.raises(ValidationError, match="hydroelastic_margin"):
        StationConfig(hydroelastic_margin=-1e-4)


def _has_modulus(station, name: str) -> set[bool]:
    """Whether each collision geometry of object `name` has a hydroelastic modulus (compliant
    geometry has one, rigid has none; Drake's compliance type is not readable from Python)."""
    inspector = station.scene_graph.model_inspector()
    frame = station.plant.GetBodyFrameIdOrThrow(station.object_bodies[name].index())
    ids = inspector.GetGeometries(frame, Role.kProximity)
    props = [inspector.GetProximityProperties(g) for g in ids]
    assert all(p.HasProperty("hydroelastic", "compliance_type") for p in props)
    return {p.HasProperty("hydroelastic", "hydroelastic_modulus") for p in props}


def test_rigid_object_kinds_make_those_objects_rigid_hydroelastic():
    scene = demo_scene("demo")
    default = build_station(scene, StationConfig(render=False))
    rigid = build_station(scene, StationConfig(render=False, rigid_object_kinds=("bowl",)))
    assert _has_modulus(default, "bowl") == {True}
    assert _has_modulus(rigid, "bowl") == {False}  # its walls reach the table: all rigid
    assert _has_modulus(rigid, "red_cube") == {True}
    with pytest.raises(ValidationError, match="rigid_object_kinds"):
        StationConfig(rigid_object_kinds=("box",))


def _pad_moduli(station) -> list[float]:
    """The hydroelastic modulus of every finger pad geometry (both arms, both fingers)."""
    inspector = station.scene_graph.model_inspector()
    return [
        inspector.GetProximityProperties(g).GetProperty("hydroelastic", "hydroelastic_modulus")
        for g in inspector.GetAllGeometryIds(Role.kProximity)
        if "pad" in inspector.GetName(g)
    ]


def test_pad_modulus_overrides_the_robots_pads_only():
    scene = demo_scene("cubes")
    own = _pad_moduli(build_station(scene, StationConfig(render=False)))
    stiff = build_station(scene, StationConfig(render=False, pad_modulus=2e7))
    assert len(own) == 4 and set(own) == {2e6}  # the ViperX's GripperSpec.pad_modulus
    assert _pad_moduli(stiff) == [2e7] * 4
    assert stiff.embodiment.arm.gripper.pad_modulus == 2e7  # the station says what it built
    assert get_embodiment("aloha_viperx").arm.gripper.pad_modulus == 2e6  # the registry's robot
    with pytest.raises(ValidationError, match="pad_modulus"):
        StationConfig(pad_modulus=0.0)


def test_same_hemisphere_keeps_the_rotation_and_picks_the_sign_nearer_the_reference():
    from bicoord_drake.sim.control import same_hemisphere

    reference = np.array([0.6, -0.23, 0.19, 0.75])
    q = np.array([0.001, -0.709, 0.0, 0.706])  # w ~ 0: Drake's sign flips around here
    assert np.array_equal(same_hemisphere(q, reference), q)
    assert np.array_equal(same_hemisphere(-q, reference), q)


def test_tcp_quaternions_do_not_jump_sign_when_the_hand_turns_down(sim):
    """Drake's quaternion has w >= 0; a TCP pointing down sits near w = 0, where that sign
    flips (balance_roller's seed 0 had 12 jumps of 1.4 in its end poses). The observer keeps
    the sign nearer the arm's home orientation: a hand turning down through w = 0 changes its
    quaternion smoothly, and at home the sign is Drake's."""
    sim.reset()
    home = sim.station.embodiment.home_action()
    start = {side: sim.tcp_pose(side)[3:] for side in ("left", "right")}
    target = home.copy()
    # both hands turned down past balance_roller's final pose (wrist pitch and rotate)
    target[0:6] = [-0.33, 0.66, -0.67, 0.0, 1.58, -2.3]
    target[7:13] = [0.1, 0.54, -0.46, 0.0, 1.49, -1.9]
    previous, crossed = dict(start), set()
    for k in range(1, 61):
        sim.step(home + (target - home) * min(1.0, k / 45))
        for side in ("left", "right"):
            q = sim.tcp_pose(side)[3:]
            assert q @ previous[side] > 0.9, (side, k, q, previous[side])
            if q[0] < 0:
                crossed.add(side)  # past w = 0: Drake's own sign would have jumped here
            previous[side] = q
    assert crossed == {"left", "right"}
    assert all(start[side][0] > 0 for side in start)
