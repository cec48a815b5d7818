"""Rendering a recorded episode afterwards shows exactly what the simulating cameras saw."""

import numpy as np
import pytest

from bicoord_drake.config import CameraConfig, StationConfig
from bicoord_drake.data.episode import EpisodeRecorder
from bicoord_drake.models.scene import demo_scene
from bicoord_drake.sim.frame_renderer import CameraFrame, FrameRenderer
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station

CONFIG = StationConfig(cameras=CameraConfig(depth=True))


@pytest.fixture(scope="module")
def recorded():
    """Six frames of both arms moving, recorded with live cameras (the reference)."""
    scene = demo_scene("cubes")
    sim = Simulation(build_station(scene, CONFIG))
    home = sim.station.embodiment.home_action()
    recorder = EpisodeRecorder(fps=CONFIG.control_rate, initial_action=home)
    for k in range(6):
        action = home.copy()
        action[0] += 0.08 * k  # left waist
        action[8] -= 0.05 * k  # right shoulder
        action[13] = 1.0 - 0.15 * k  # right gripper closing
        recorder.capture(sim, action, depth=True)
        sim.step(action)
    return scene, recorder


def test_rendered_afterwards_equals_live_cameras_pixel_for_pixel(recorded):
    scene, live = recorded
    renderer = FrameRenderer(scene, CONFIG, depth=True)
    frames = list(renderer.render_all(live.plant_states))
    assert len(frames) == len(live) == 6
    for cam in ("head_camera", "left_camera", "right_camera"):
        live_frames = list(live.frames(cam))
        assert not np.array_equal(live_frames[0], live_frames[-1]), "the arms did not move"
        for t, frame in enumerate(frames):
            # the live recorder stores JPEGs: compare through the same encoder
            assert np.array_equal(_jpeg_roundtrip(frame.images[cam]), live_frames[t]), (cam, t)
            assert np.array_equal(frame.depth[cam], live._depth[cam][t])  # noqa: SLF001
            assert np.array_equal(frame.extrinsic_cv[cam], live._extrinsic[cam][t])  # noqa: SLF001
    assert renderer.seconds > 0


def _jpeg_roundtrip(image: np.ndarray) -> np.ndarray:
    from bicoord_drake.data.episode import decode_rgb, encode_jpeg

    return decode_rgb(encode_jpeg(image, 90))


def test_attach_images_gives_a_camera_less_recording_the_live_recordings_images(recorded):
    scene, live = recorded
    blind = EpisodeRecorder(fps=CONFIG.control_rate)
    sim = Simulation(build_station(scene, CONFIG.model_copy(update={"render": False})))
    for action in live.actions:
        blind.capture(sim, action)
        sim.step(action)
    assert blind.cameras == []
    np.testing.assert_array_equal(np.stack(blind.plant_states), np.stack(live.plant_states))
    blind.attach_images(FrameRenderer(scene, CONFIG, depth=True).render_all(blind.plant_states))
    assert sorted(blind.cameras) == sorted(live.cameras)
    for cam in live.cameras:
        for a, b in zip(blind.frames(cam), live.frames(cam), strict=True):
            assert np.array_equal(a, b)


def _frame(cams=("head_camera",)) -> CameraFrame:
    img = np.zeros((24, 32, 3), np.uint8)
    return CameraFrame(
        images={c: img for c in cams},
        depth={},
        intrinsic_cv={c: np.eye(3) for c in cams},
        extrinsic_cv={c: np.zeros((3, 4)) for c in cams},
    )


def _blind_recording(frames: int) -> EpisodeRecorder:
    rec = EpisodeRecorder(fps=15)
    for _ in range(frames):
        rec.add_frame(
            action=np.zeros(14),
            joint_state=np.zeros(14),
            left_endpose=np.r_[0, 0, 0, 1, 0, 0, 0],
            right_endpose=np.r_[0, 0, 0, 1, 0, 0, 0],
            object_poses={},
            plant_state=np.zeros(3),
        )
    return rec


@pytest.mark.parametrize(
    "frames, match",
    [
        ([_frame()] * 2, "2 camera frames for 3 recorded"),
        ([_frame()] * 4, "more camera frames than the 3"),
        ([_frame(), _frame(("head_camera", "left_camera")), _frame()], "cameras changed"),
    ],
)
def test_attach_images_rejects_a_mismatch_and_keeps_nothing(frames, match):
    rec = _blind_recording(3)
    with pytest.raises(ValueError, match=match):
        rec.attach_images(frames)
    assert rec.cameras == []
    rec.attach_images([_frame()] * 3)
    assert rec.cameras == ["head_camera"]
    with pytest.raises(ValueError, match="already has camera images"):
        rec.attach_images([_frame()] * 3)


def test_renderer_refuses_a_state_of_another_scene_and_a_config_without_cameras(recorded):
    scene, _ = recorded
    with pytest.raises(ValueError, match="render=True"):
        FrameRenderer(scene, CONFIG.model_copy(update={"render": False}))
    with pytest.raises(ValueError, match="depth was not enabled"):
        FrameRenderer(scene, StationConfig(), depth=True)
    with pytest.raises(ValueError, match="another scene"):
        FrameRenderer(scene, StationConfig()).render(np.zeros(5))
