"""The head camera sees both grippers at home and every task object of every task.

Checked by projecting world points through the head camera's OpenCV ``K [R | t]`` (no
rendering), plus one rendered scene whose label image must agree.
"""

import numpy as np
import pytest

from bicoord_drake.config import CameraConfig, StationConfig
from bicoord_drake.models.appearance import Appearance
from bicoord_drake.models.scene import Scene
from bicoord_drake.sim.cameras import (
    camera_mounts,
    extrinsic_matrix,
    intrinsic_matrix,
    intrinsics,
)
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station
from bicoord_drake.tasks import get_task, list_tasks

CONFIG = CameraConfig()
W, H = CONFIG.width, CONFIG.height
#: Pixels kept clear of the image border by the plain (un-jittered) head camera.
MARGIN = 16
SEEDS = range(5)
FINGERS = ("left_finger", "right_finger")


@pytest.fixture(scope="module")
def robot():
    """A station with the arms at home and no objects (no cameras: nothing renders)."""
    return Simulation(build_station(Scene(), StationConfig(render=False)))


@pytest.fixture(scope="module")
def gripper_points(robot) -> dict[str, np.ndarray]:
    """World positions at home: both arms' finger body origins and TCP."""
    st, ctx = robot.station, robot.plant_context
    points = {}
    for side, inst in st.arms.items():
        for name in FINGERS:
            body = st.plant.GetBodyByName(name, inst)
            points[f"{side} {name}"] = st.plant.EvalBodyPoseInWorld(ctx, body).translation()
        points[f"{side} tcp"] = (
            st.plant.GetFrameByName("tcp", inst).CalcPoseInWorld(ctx).translation()
        )
    return points


def head_pixels(robot, points: np.ndarray, appearance: Appearance | None = None) -> np.ndarray:
    """(N, 2) pixel coordinates (u right, v down) of world points (N, 3) in the head camera."""
    mount = camera_mounts(robot.station.embodiment, CONFIG, appearance)[0]
    assert mount.name == "head_camera" and mount.body_name is None
    K = intrinsic_matrix(intrinsics(CONFIG, mount.fov_y_deg))
    p_C = extrinsic_matrix(mount.X_PC) @ np.c_[points, np.ones(len(points))].T
    assert (p_C[2] > 0.2).all(), "a point is behind (or at) the camera"
    uvw = K @ p_C
    return (uvw[:2] / uvw[2]).T


def border_distance(uv: np.ndarray) -> np.ndarray:
    """Pixels from each point to the nearest image border (negative: outside)."""
    return np.minimum.reduce([uv[:, 0], W - uv[:, 0], uv[:, 1], H - uv[:, 1]])


def task_objects(scene: Scene) -> dict[str, np.ndarray]:
    return {o.name: np.array(o.pose.xyz) for o in scene.objects if not o.distractor}


def test_head_camera_defaults_are_a_d435_like_view(robot):
    assert (W, H) == (320, 240)
    K = intrinsic_matrix(intrinsics(CONFIG, CONFIG.head_fov_y_deg))
    fov_x = np.rad2deg(2 * np.arctan(W / 2 / K[0, 0]))
    fov_y = np.rad2deg(2 * np.arctan(H / 2 / K[1, 1]))
    assert fov_y == pytest.approx(42.0)
    assert 52 < fov_x < 56
    mount = camera_mounts(robot.station.embodiment, CONFIG)[0]
    assert mount.X_PC.translation()[0] == pytest.approx(0.0)  # centred between the arms


def test_both_grippers_are_in_view_at_home(robot, gripper_points):
    names = list(gripper_points)
    uv = head_pixels(robot, np.array(list(gripper_points.values())))
    d = border_distance(uv)
    assert d.min() >= MARGIN, dict(zip(names, d.round(1), strict=True))
    # left arm on the image's left, right arm on its right
    left = [i for i, n in enumerate(names) if n.startswith("left")]
    right = [i for i, n in enumerate(names) if n.startswith("right")]
    assert uv[left, 0].max() < W / 2 < uv[right, 0].min()


@pytest.mark.parametrize("task", list_tasks())
def test_every_task_object_is_in_view(robot, gripper_points, task):
    """Seeds 0-4 by the plain camera with a margin; the randomized scenes (camera moved by
    centimetres and tilted by up to 0.03 rad, table raised or lowered) still inside the image."""
    fingers = np.array(list(gripper_points.values()))
    for seed in SEEDS:
        scene = get_task(task).sample_scene(seed)
        objects = task_objects(scene)
        d = border_distance(head_pixels(robot, np.array(list(objects.values()))))
        assert d.min() >= MARGIN, f"seed {seed}: {dict(zip(objects, d.round(1), strict=True))}"
        for split in ("seen", "unseen"):
            randomized = scene.randomized(split)
            jittered = randomized.appearance
            assert task_objects(randomized).keys() == objects.keys()
            points = np.concatenate([np.array(list(objects.values())), fingers])
            d = border_distance(head_pixels(robot, points, jittered))
            assert d.min() > 0, f"seed {seed} {split}: a task object or finger leaves the image"


def test_rendered_labels_show_both_grippers_and_every_object():
    """One rendered scene (sweep_block spans the table's width): the label image holds each
    finger and each task object, and the station's head camera matrices are the ones the
    projection tests use."""
    scene = get_task("sweep_block").sample_scene(0)
    sim = Simulation(build_station(scene, StationConfig()))
    st = sim.station
    mount = camera_mounts(st.embodiment, st.config.cameras)[0]
    np.testing.assert_allclose(sim.extrinsic_cv("head_camera"), extrinsic_matrix(mount.X_PC))
    np.testing.assert_allclose(
        sim.intrinsic_cv("head_camera"), intrinsic_matrix(intrinsics(CONFIG, mount.fov_y_deg))
    )
    labels = sim.label_image("head_camera")
    assert labels.shape == (H, W)
    for side, inst in st.arms.items():
        for name in FINGERS:
            body = int(st.plant.GetBodyByName(name, inst).index())
            assert (labels == body).sum() >= 50, f"{side} {name} not visible"
    for name in task_objects(scene):
        body = int(st.object_bodies[name].index())
        assert (labels == body).sum() >= 200, f"{name} not visible"
