"""The articulated cabinet: a drawer on a prismatic joint, in the scene, the plant, the world
state, the episode file and the planning model."""

import h5py
import numpy as np
import pytest
from pydrake.all import ExternallyAppliedSpatialForce, SpatialForce

from bicoord_drake.config import StationConfig
from bicoord_drake.data.episode import EpisodeMeta, EpisodeRecorder, read_episode
from bicoord_drake.models.cabinet import HANDLE_PART, CabinetDims, cabinet
from bicoord_drake.models.objects import SceneObject, Slide
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.sim.simulation import Simulation, build_station
from bicoord_drake.stages import WorldState

DIMS = CabinetDims(handle_x=0.05)
XY = (0.02, 0.15)


def cabinet_scene(*extra: SceneObject) -> Scene:
    body, drawer = cabinet("cabinet", "drawer", XY, TABLE_TOP, DIMS)
    return Scene(name="cabinet", objects=(body, drawer, *extra))


@pytest.fixture(scope="module")
def sim():
    return Simulation(build_station(cabinet_scene(), StationConfig(render=False)))


# ------------------------------------------------------------------ scene
def test_slide_needs_a_unit_axis_and_limits_around_zero():
    with pytest.raises(ValueError, match="unit"):
        Slide(parent="c", axis=(0.0, -2.0, 0.0), upper=0.1)
    with pytest.raises(ValueError, match="contain 0"):
        Slide(parent="c", axis=(0.0, -1.0, 0.0), lower=0.05, upper=0.1)


def test_a_sliding_object_needs_a_fixed_parent_listed_before_it():
    body, drawer = cabinet("cabinet", "drawer", XY, TABLE_TOP, DIMS)
    with pytest.raises(ValueError, match="parent"):
        Scene(objects=(drawer, body))  # parent after it
    with pytest.raises(ValueError, match="parent"):
        Scene(objects=(body.model_copy(update={"fixed": False}), drawer))
    with pytest.raises(ValueError, match="parent"):
        Scene(objects=(body, drawer.model_copy(update={"fixed": True})))
    scene = Scene(objects=(body, drawer))
    assert [o.name for o in scene.sliding_objects] == ["drawer"]
    np.testing.assert_allclose(scene.slide_axis("drawer"), [0.0, -1.0, 0.0])
    assert Scene.model_validate_json(scene.model_dump_json()) == scene


def test_closed_drawer_sits_in_the_cabinet_clear_of_its_walls():
    scene = cabinet_scene()
    body, drawer = scene.object("cabinet"), scene.object("drawer")
    sx, sy, sz = DIMS.outer
    lo = np.array([-sx / 2, -sy / 2, 0.0]) + body.pose.xyz
    hi = np.array([sx / 2, sy / 2, sz]) + body.pose.xyz
    for i, prim in enumerate(drawer.shape.primitives()):
        if i >= HANDLE_PART:
            continue  # the handle is in front
        c = np.asarray(drawer.pose.xyz) + prim.pose.xyz
        half = np.asarray(prim.size) / 2
        assert np.all(c - half >= lo - 1e-9) and np.all(c + half <= hi + 1e-9)
    # the front is flush with the cabinet's front; the handle bar is in front of it
    front = drawer.pose.xyz[1] - DIMS.depth / 2
    assert front == pytest.approx(lo[1])
    bar = drawer.shape.primitives()[HANDLE_PART]
    assert bar.pose.xyz[1] + drawer.pose.xyz[1] == pytest.approx(front - DIMS.standoff)
    assert bar.pose.xyz[0] == pytest.approx(DIMS.handle_x)


# ------------------------------------------------------------------ physics
def _pull(sim: Simulation, force_y: float, steps: int) -> list[float]:
    """Apply a constant world force along y at the drawer's origin for `steps` control steps."""
    st = sim.station
    body = st.object_bodies["drawer"]
    f = ExternallyAppliedSpatialForce()
    f.body_index = body.index()
    f.p_BoBq_B = np.zeros(3)
    f.F_Bq_W = SpatialForce(np.zeros(3), np.array([0.0, force_y, 0.0]))
    port = st.plant.get_applied_spatial_force_input_port()
    port.FixValue(sim.plant_context, [f])
    action = st.embodiment.home_action()
    out = []
    for _ in range(steps):
        sim.step(action)
        out.append(sim.joint_positions()["drawer"])
    port.FixValue(sim.plant_context, [])
    return out


def test_drawer_rests_closed_and_does_not_sag(sim):
    sim.reset()
    z0 = sim.object_poses()["drawer"][2]
    _pull(sim, 0.0, 15)
    assert sim.joint_positions()["drawer"] == pytest.approx(0.0, abs=1e-4)
    assert sim.object_poses()["drawer"][2] == pytest.approx(z0, abs=1e-4)


def test_pulling_opens_the_drawer_along_its_axis_up_to_its_stop(sim):
    sim.reset()
    p0 = sim.object_poses()["drawer"][:3].copy()
    d = _pull(sim, -0.5, 6)  # 0.5 N against 4 N s/m of damping: about 0.12 m/s
    assert 0.0 < d[2] < d[-1] < DIMS.travel
    moved = sim.object_poses()["drawer"][:3] - p0
    np.testing.assert_allclose(moved, [0.0, -d[-1], 0.0], atol=1e-4)  # straight along -y
    d = _pull(sim, -20.0, 30)  # hard: it ends at the stop, not beyond
    assert max(d) <= DIMS.travel + 0.003 and d[-1] == pytest.approx(DIMS.travel, abs=0.003)
    # let go: damped, no spring - it stays out
    d = _pull(sim, 0.0, 10)
    assert d[-1] == pytest.approx(DIMS.travel, abs=0.003)
    # pushed shut: it stops at closed, not inside the back wall
    d = _pull(sim, 20.0, 30)
    assert min(d) >= -0.003 and d[-1] == pytest.approx(0.0, abs=0.003)


def test_joint_position_is_in_the_world_state_and_the_episode_file(sim, tmp_path):
    sim.reset()
    action = sim.station.embodiment.home_action()
    rec = EpisodeRecorder(fps=15, initial_action=action)
    st = sim.station
    f = ExternallyAppliedSpatialForce()
    f.body_index = st.object_bodies["drawer"].index()
    f.p_BoBq_B = np.zeros(3)
    f.F_Bq_W = SpatialForce(np.zeros(3), np.array([0.0, -1.0, 0.0]))
    st.plant.get_applied_spatial_force_input_port().FixValue(sim.plant_context, [f])
    measured = []
    for _ in range(5):
        rec.capture(sim, action)
        measured.append(sim.joint_positions()["drawer"])
        sim.step(action)
    st.plant.get_applied_spatial_force_input_port().FixValue(sim.plant_context, [])
    state = WorldState.capture(sim, action)
    assert state.joint_position("drawer") == sim.joint_positions()["drawer"] > measured[-1]
    assert WorldState.initial(sim.station.scene).joint_position("drawer") == 0.0
    meta = EpisodeMeta(
        task="t", seed=0, instruction="i", embodiment="aloha_viperx", success=True,
        object_count=2, scene=sim.station.scene,
    )  # fmt: skip
    rows = [[0, 5, "open", "wait", "pull", 1.0]]
    path = rec.write(tmp_path / "e.hdf5", rows, meta)
    e = read_episode(path)
    np.testing.assert_array_equal(e.joints["drawer"], measured)
    assert e.scene == sim.station.scene
    # the plant state holds the joint too: restoring a frame restores the drawer
    sim.restore(rec.plant_states[4], action, action, 4)
    assert sim.joint_positions()["drawer"] == pytest.approx(measured[4])
    # an episode file without joints (older, or a scene without a drawer) reads as none
    with h5py.File(path, "a") as fh:
        del fh["joints"]
    assert read_episode(path).joints == {}


def test_recorder_requires_the_same_joints_every_frame():
    rec = EpisodeRecorder(fps=15)
    frame = dict(
        action=np.zeros(14),
        joint_state=np.zeros(14),
        left_endpose=[0, 0, 1, 1, 0, 0, 0],
        right_endpose=[0, 0, 1, 1, 0, 0, 0],
        object_poses={},
    )
    rec.add_frame(**frame, joint_positions={"drawer": 0.0})
    with pytest.raises(ValueError, match="joints"):
        rec.add_frame(**frame)


# ------------------------------------------------------------------ planning model
def test_planning_model_puts_the_drawer_at_its_joint_position():
    from pydrake.all import RigidTransform, RollPitchYaw, RotationMatrix

    from bicoord_drake.planning.ik import BimanualIK, TcpTarget
    from bicoord_drake.planning.model import PlanningModel

    scene = cabinet_scene()
    model = PlanningModel(scene)
    X0 = model.object_pose("drawer")
    assert model.slide_position("drawer") == pytest.approx(0.0)
    model.set_slide("drawer", 0.12)
    assert model.slide_position("drawer") == pytest.approx(0.12)
    np.testing.assert_allclose(
        model.object_pose("drawer").translation(), X0.translation() + [0.0, -0.12, 0.0]
    )
    model.set_slide("drawer", 1.0)  # clipped to the stop
    assert model.slide_position("drawer") == pytest.approx(DIMS.travel)
    with pytest.raises(ValueError, match="slide"):
        model.set_slide("cabinet", 0.1)
    # collision checks see it where it is: an open jaw (fingers along y, 4.5-5.7 cm from the
    # TCP) in front of the shut drawer, one finger in its front wall once it is 12 cm out
    model.set_slide("drawer", 0.0)
    front = X0.translation()[1] - DIMS.depth / 2
    down = RotationMatrix(RollPitchYaw(0.0, np.pi / 2, 0.0))
    X = RigidTransform(down, [XY[0] - 0.06, front - 0.07, TABLE_TOP + 0.05])
    ik = BimanualIK(model)
    q = ik.solve_single(
        "right", TcpTarget(X), model.home[:6], seed=model.home, clearance=0.0, env_clearance=0.0
    )
    assert model.collision_free(q)
    model.set_slide("drawer", 0.12)
    assert not model.collision_free(q)
    assert any("drawer" in pair for pair in model.colliding_pairs(q))
