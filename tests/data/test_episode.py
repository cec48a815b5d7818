"""Episode files: write/read round trip, atomic writes, schema checks, sidecars, manifest."""

import json

import h5py
import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.data import episode as ep
from bicoord_drake.data.episode import (
    SCHEMA_VERSION,
    EpisodeEntry,
    EpisodeLayout,
    EpisodeMeta,
    EpisodeRecorder,
    Manifest,
    decode_rgb,
    read_episode,
    read_manifest,
    save_episode,
    write_manifest,
)
from bicoord_drake.data.readers import read_trajectory
from bicoord_drake.metrics import episode_metrics, measure_paths
from bicoord_drake.models.scene import demo_scene

T, W, H, N_STATE = 12, 32, 24, 20
CAMS = ("head_camera", "left_camera", "right_camera")
COLORS = {"head_camera": (200, 30, 40), "left_camera": (20, 180, 60), "right_camera": (30, 60, 220)}
ROWS = [[0, 5, "lift", "grasp", "grasp", 0.5], [5, T, "place", "place", "release", 0.5]]
SCENE = demo_scene("demo")


def K() -> np.ndarray:
    return np.array([[30.0, 0, W / 2], [0, 30.0, H / 2], [0, 0, 1]])


def frame(t: int) -> dict:
    s = t / (T - 1)
    action = np.zeros(14)
    action[:6], action[7:13] = s, -s
    action[6], action[13] = (0.0, 1.0) if t >= 5 else (1.0, 1.0)
    images = {c: np.full((H, W, 3), COLORS[c], dtype=np.uint8) for c in CAMS}
    return dict(
        action=action,
        joint_state=action * 0.99,
        left_endpose=[-0.3 + 0.1 * s, 0.3, 0.9, 1, 0, 0, 0],
        right_endpose=[0.3 - 0.1 * s, 0.3, 0.9, 0, 1, 0, 0],
        object_poses={o.name: [0.1 * s, 0.0, 0.8, 1, 0, 0, 0] for o in SCENE.objects},
        images=images,
        depth={"head_camera": np.full((H, W), 1000 + t, dtype=np.uint16)},
        intrinsic_cv={c: K() for c in CAMS},
        extrinsic_cv={c: np.hstack([np.eye(3), [[0.0], [0.1], [float(t)]]]) for c in CAMS},
        plant_state=np.arange(N_STATE, dtype=float) + t,
    )


def recorder(n: int = T) -> EpisodeRecorder:
    rec = EpisodeRecorder(fps=15, initial_action=np.full(14, 0.5))
    for t in range(n):
        rec.add_frame(**frame(t))
    return rec


def meta(**overrides) -> EpisodeMeta:
    fields = dict(
        task="demo_task",
        seed=42,
        instruction="lift the cube and place it",
        embodiment="aloha_viperx",
        success=True,
        object_count=3,
        config=StationConfig(),
        scene=SCENE,
    )
    fields.update(overrides)
    return EpisodeMeta(**fields)


@pytest.fixture
def written(tmp_path):
    return recorder().write(tmp_path / "data" / "episode0.hdf5", ROWS, meta())


def test_every_product_key_with_shape_and_dtype(written):
    expected = {
        "joint_action/left_arm": (T, 6),
        "joint_action/right_arm": (T, 6),
        "joint_action/left_gripper": (T,),
        "joint_action/right_gripper": (T,),
        "joint_action/vector": (T, 14),
        "joint_state/vector": (T, 14),
        "endpose/left_endpose": (T, 7),
        "endpose/right_endpose": (T, 7),
        "stages/start": (2,),
        "stages/end": (2,),
        "stages/score": (2,),
        "stages/subgoal": (2,),
        "stages/left": (2,),
        "stages/right": (2,),
        "stages/initial_state": (2, N_STATE),
        "stages/initial_action": (2, 14),
        "stage_index": (T,),
        "observation/head_camera/depth": (T, H, W),
        **{f"objects/{o.name}/pose": (T, 7) for o in SCENE.objects},
    }
    for cam in CAMS:
        expected[f"observation/{cam}/rgb"] = (T,)
        expected[f"observation/{cam}/intrinsic_cv"] = (T, 3, 3)
        expected[f"observation/{cam}/extrinsic_cv"] = (T, 3, 4)
    with h5py.File(written, "r") as f:
        for key, shape in expected.items():
            assert key in f, key
            assert f[key].shape == shape, key
        assert "observation/left_camera/depth" not in f
        assert f["observation/head_camera/depth"].dtype == np.uint16
        assert f["observation/head_camera/rgb"].dtype.kind == "S"
        assert f["stage_index"].dtype == np.int64 and f["stages/start"].dtype == np.int64
        attrs = dict(f.attrs)
    assert attrs["schema_version"] == SCHEMA_VERSION
    for key in ("task", "seed", "instruction", "fps", "embodiment", "success", "object_count"):
        assert key in attrs
    assert {"package_version", "config", "scene", "frame_count"} <= set(attrs)
    assert json.loads(attrs["config"])["control_rate"] == 15.0


def test_round_trip(written):
    e = read_episode(written)
    frames = [frame(t) for t in range(T)]
    assert (e.task, e.seed, e.fps, e.success, e.length) == ("demo_task", 42, 15.0, True, T)
    assert e.instruction == "lift the cube and place it"
    assert e.attrs["object_count"] == 3 and e.attrs["embodiment"] == "aloha_viperx"
    assert e.scene == SCENE
    assert e.config == StationConfig().model_dump(mode="json")
    np.testing.assert_array_equal(e.joint_action, [f["action"] for f in frames])
    np.testing.assert_array_equal(e.joint_state, [f["joint_state"] for f in frames])
    np.testing.assert_array_equal(e.right_endpose, [f["right_endpose"] for f in frames])
    np.testing.assert_array_equal(e.objects["bowl"], [f["object_poses"]["bowl"] for f in frames])
    np.testing.assert_array_equal(
        e.extrinsic_cv["left_camera"][3], frames[3]["extrinsic_cv"]["left_camera"]
    )
    np.testing.assert_array_equal(e.intrinsic_cv["head_camera"], np.tile(K(), (T, 1, 1)))
    np.testing.assert_array_equal(e.depth["head_camera"][7], frames[7]["depth"]["head_camera"])
    assert e.stages == ROWS
    np.testing.assert_array_equal(e.stage_index, [0] * 5 + [1] * (T - 5))
    np.testing.assert_array_equal(
        e.initial_state, [frames[0]["plant_state"], frames[5]["plant_state"]]
    )
    np.testing.assert_array_equal(e.initial_action, [np.full(14, 0.5), frames[4]["action"]])
    with h5py.File(written, "r") as f:
        np.testing.assert_array_equal(f["joint_action/left_gripper"][()], e.joint_action[:, 6])
        np.testing.assert_array_equal(f["joint_action/right_arm"][()], e.joint_action[:, 7:13])


def test_jpeg_decodes_to_rgb(written):
    e = read_episode(written)
    for cam, color in COLORS.items():
        img = e.image(cam, 3)
        assert img.shape == (H, W, 3) and img.dtype == np.uint8
        assert np.abs(img.astype(int) - color).max() <= 6, cam
    raw = e.rgb["head_camera"][0]
    assert isinstance(raw, bytes) and raw[:2] == b"\xff\xd8"  # a standard JPEG stream
    np.testing.assert_array_equal(decode_rgb(raw), decode_rgb(np.frombuffer(raw, np.uint8)))
    assert read_episode(written, images=False).rgb == {}


def test_metrics_reader_reads_our_file(written):
    traj = read_trajectory(written)
    assert traj.layout == "bicoord_drake" and traj.task == "demo_task"
    assert (traj.length, traj.n_stages, traj.n_objects, traj.success) == (T, 2, 3, True)
    np.testing.assert_array_equal(traj.left_gripper, read_episode(written).joint_action[:, 6])
    m = episode_metrics(traj)
    assert m.coordination.length == T
    metrics, good, errors = measure_paths([written.parent])
    assert errors == [] and len(good) == 1 and metrics is not None


@pytest.mark.parametrize("exc", [RuntimeError("disk full"), KeyboardInterrupt()])
def test_atomic_write_leaves_nothing_on_failure(tmp_path, monkeypatch, exc):
    path = tmp_path / "episode0.hdf5"

    def boom(self, f, rows):
        raise exc

    monkeypatch.setattr(EpisodeRecorder, "_write_stages", boom)
    with pytest.raises(type(exc)):
        recorder().write(path, ROWS, meta())
    assert list(tmp_path.iterdir()) == []


def test_failed_overwrite_keeps_the_old_file(tmp_path, monkeypatch):
    path = recorder().write(tmp_path / "episode0.hdf5", ROWS, meta(seed=1))
    monkeypatch.setattr(EpisodeRecorder, "_write_objects", lambda self, f: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        recorder().write(path, ROWS, meta(seed=2))
    assert read_episode(path).seed == 1
    assert [p.name for p in tmp_path.iterdir()] == ["episode0.hdf5"]


def test_bad_annotations_rejected_before_writing(tmp_path):
    path = tmp_path / "episode0.hdf5"
    with pytest.raises(ValueError, match="cover"):
        recorder().write(path, ROWS[:1], meta())
    with pytest.raises(ValueError, match="contiguous"):
        recorder().write(path, [ROWS[1], ROWS[0]], meta())
    with pytest.raises(ValueError, match="no frames"):
        EpisodeRecorder(fps=15).write(path, [], meta())
    assert not path.exists()


def test_schema_version_mismatch_says_what_is_wrong(written):
    with h5py.File(written, "a") as f:
        f.attrs["schema_version"] = 2
    with pytest.raises(ValueError, match=r"schema_version is 2 .*reads schema_version 1"):
        read_episode(written)
    with h5py.File(written, "a") as f:
        del f.attrs["schema_version"]
    with pytest.raises(ValueError, match="not a bicoord-drake episode file"):
        read_episode(written)


def test_missing_key_and_missing_file(written, tmp_path):
    with h5py.File(written, "a") as f:
        del f["joint_state/vector"]
    with pytest.raises(ValueError, match="missing key 'joint_state/vector'"):
        read_episode(written)
    with pytest.raises(ValueError, match="no such file"):
        read_episode(tmp_path / "nope.hdf5")


def test_recorder_rejects_inconsistent_frames():
    rec = recorder(1)
    bad = frame(1)
    bad["images"].pop("left_camera")
    with pytest.raises(ValueError, match="cameras changed"):
        rec.add_frame(**bad)
    bad = frame(1)
    bad["action"] = np.zeros(13)
    with pytest.raises(ValueError, match="action must have shape"):
        rec.add_frame(**bad)
    bad = frame(1)
    bad.pop("plant_state")
    with pytest.raises(ValueError, match="plant_state"):
        rec.add_frame(**bad)
    bad = frame(1)
    bad["intrinsic_cv"] = {}
    with pytest.raises(ValueError, match="intrinsic_cv"):
        rec.add_frame(**bad)
    assert len(rec) == 1  # rejected frames leave no trace


def test_minimal_frames_without_cameras(tmp_path):
    rec = EpisodeRecorder(fps=10)
    for t in range(3):
        f = frame(t)
        rec.add_frame(
            action=f["action"],
            joint_state=f["joint_state"],
            left_endpose=f["left_endpose"],
            right_endpose=f["right_endpose"],
            object_poses={},
        )
    path = rec.write(
        tmp_path / "e.hdf5", [[0, 3, "all", "", "", 1.0]], meta(scene=None, config=None)
    )
    e = read_episode(path)
    assert e.rgb == {} and e.objects == {} and e.initial_state is None and e.scene is None
    np.testing.assert_array_equal(e.initial_action, [frame(0)["action"]])


def test_layout_sidecars_and_save_episode(tmp_path):
    pytest.importorskip("av")
    layout = EpisodeLayout(tmp_path, "demo_task", "default")
    paths = save_episode(layout, 3, recorder(), ROWS, meta(), instructions_unseen=["other words"])
    assert paths == {
        "instructions": tmp_path / "demo_task/default/instructions/episode3.json",
        "stages": tmp_path / "demo_task/default/stages/episode3.json",
        "video": tmp_path / "demo_task/default/video/episode3.mp4",
        "episode": tmp_path / "demo_task/default/data/episode3.hdf5",
    }
    assert json.loads(paths["stages"].read_text()) == ROWS
    assert json.loads(paths["instructions"].read_text()) == {
        "seen": ["lift the cube and place it"],
        "unseen": ["other words"],
    }
    # the metrics reader finds the stage count beside data/ as well
    assert read_trajectory(paths["episode"]).n_stages == 2
    leftovers = [p for p in layout.root.rglob("*") if p.name.startswith(".")]
    assert leftovers == []


def test_video_has_every_frame(tmp_path):
    av = pytest.importorskip("av")
    path = recorder().write_video(tmp_path / "video" / "episode0.mp4")
    with av.open(str(path)) as container:
        decoded = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    assert len(decoded) == T and decoded[0].shape == (H, W, 3)
    assert np.abs(decoded[0].astype(int) - COLORS["head_camera"]).mean() < 12
    with pytest.raises(KeyError, match="no camera"):
        recorder(1).write_video(tmp_path / "x.mp4", camera="top_camera")


def test_manifest_round_trip(tmp_path):
    manifest = Manifest(
        task="demo_task",
        config_name="default",
        config={"episodes": 2},
        episodes=[
            EpisodeEntry(seed=0, success=True, index=0, frames=120, timings={"plan": 1.5}),
            EpisodeEntry(seed=1, success=False, reason="ik_infeasible: left arm"),
        ],
    )
    path = write_manifest(tmp_path, manifest)
    assert path == tmp_path / "manifest.json"
    back = read_manifest(tmp_path)
    assert back == manifest
    assert [e.seed for e in back.successes] == [0]
    assert back.failures[0].reason.startswith("ik_infeasible")
    assert back.package_version == ep.package_version()
    write_manifest(tmp_path, {"task": "t", "config_name": "c"})
    assert read_manifest(path).episodes == []
    path.write_text(path.read_text().replace('"schema_version": 1', '"schema_version": 9'))
    with pytest.raises(ValueError, match="schema_version is 9"):
        read_manifest(tmp_path)


def test_capture_from_a_simulation_and_restore_a_stage_start(tmp_path):
    """The one Drake test here: recorder and WorldState read a real Simulation."""
    from bicoord_drake.config import CameraConfig
    from bicoord_drake.sim.simulation import Simulation, build_station
    from bicoord_drake.stages import Stage, StageMonitor, WorldState
    from bicoord_drake.stages.predicates import at_rest, on_table, released
    from bicoord_drake.tasks import WorldView

    config = StationConfig(cameras=CameraConfig(width=64, height=48, depth=True))
    sim = Simulation(build_station(demo_scene("cubes"), config))
    home = sim.station.embodiment.home_action()
    rec = EpisodeRecorder(fps=config.control_rate, initial_action=home)
    settled = on_table("cube_0") & at_rest("cube_0", 0.05, 0.5) & released("cube_0")
    monitor = StageMonitor([Stage("settle", "wait", "wait", 1.0, settled, "persistent")])
    for _ in range(3):
        rec.capture(sim, home, depth=True)
        sim.step(home)
        state = WorldState.capture(sim, home)
        monitor.update(state)
    assert state.step == 3 and state.velocity("cube_0").shape == (6,)
    view = WorldView(sim)  # what experts see: read-only copies of the same state
    np.testing.assert_array_equal(view.object_pose("cube_0"), state.pose("cube_0"))
    np.testing.assert_array_equal(
        view.object_transforms()["cube_0"].translation(), state.position("cube_0")
    )
    np.testing.assert_array_equal(view.arm_positions()[:6], state.joint_state[:6])
    assert view.steps == 3 and view.finger_contacts()["cube_0"] == set()
    assert monitor.success
    path = rec.write(tmp_path / "e.hdf5", monitor.annotations(), meta(scene=sim.station.scene))
    e = read_episode(path)
    assert e.depth["head_camera"].shape == (3, 48, 64)
    assert e.image("left_camera", 2).shape == (48, 64, 3)
    assert e.scene == sim.station.scene
    plant = sim.station.plant
    plant.SetPositionsAndVelocities(sim.plant_context, e.initial_state[0])
    for name, poses in e.objects.items():
        np.testing.assert_allclose(sim.object_poses()[name], poses[0], atol=1e-12)


def test_a_seven_joint_robot_writes_its_own_layout(tmp_path, monkeypatch):
    """Widths, slices and gripper columns follow the recorder's layout; the reader, the metrics
    reader and the LeRobot features follow the file's robot."""
    from bicoord_drake.data import export
    from bicoord_drake.models.layout import ActionLayout

    layout = ActionLayout(7, tuple(f"j{i}" for i in range(1, 8)))
    rec = EpisodeRecorder(fps=15, initial_action=np.full(16, 0.5), layout=layout)
    for t in range(T):
        f = frame(t)
        action = layout.compose(
            {"left": np.full(7, t / T), "right": np.full(7, -t / T)},
            {"left": f["action"][6], "right": 1.0},
        )
        rec.add_frame(**{**f, "action": action, "joint_state": action * 0.99})
    with pytest.raises(ValueError, match=r"action must have shape \(16,\)"):
        rec.add_frame(**frame(0))  # a 14-vector of the ViperX pair
    path = rec.write(tmp_path / "episode0.hdf5", ROWS, meta(embodiment="seven"))
    with h5py.File(path, "r") as f:
        assert f["joint_action/vector"].shape == (T, 16)
        assert f["joint_action/left_arm"].shape == f["joint_action/right_arm"].shape == (T, 7)
        np.testing.assert_array_equal(f["joint_action/left_gripper"][()], rec.actions[:, 7])
        np.testing.assert_array_equal(f["joint_action/right_arm"][()], rec.actions[:, 8:15])
        assert f["stages/initial_action"].shape == (2, 16)
    episode = read_episode(path)
    assert episode.embodiment == "seven" and episode.joint_state.shape == (T, 16)
    traj = read_trajectory(path)
    np.testing.assert_array_equal(traj.left_gripper, rec.actions[:, 7])
    monkeypatch.setattr(export, "layout_of", lambda name: layout)
    features = export.lerobot_features(episode)
    assert features["action"]["shape"] == features["observation.state"]["shape"] == (16,)
    assert features["action"]["names"][7] == "left_gripper"
    assert features["observation.endpose"]["shape"] == (14,)
