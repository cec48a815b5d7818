"""Cameras: headless images, wrist views that follow their arm, OpenCV intrinsics/extrinsics."""

import numpy as np
import pytest

from bicoord_drake.config import CameraConfig, StationConfig
from bicoord_drake.models.scene import demo_scene
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station

WRISTS = ("left_camera", "right_camera")


@pytest.fixture(scope="module")
def sim():
    config = StationConfig(cameras=CameraConfig(depth=True))
    return Simulation(build_station(demo_scene("cubes"), config))


def test_every_camera_renders_a_non_constant_image(sim):
    sim.reset()
    images = sim.images(depth=True)
    for name in ("head_camera", *WRISTS):
        rgb = images[name]
        assert rgb.shape == (240, 320, 3) and rgb.dtype == np.uint8
        assert rgb.std() > 10, f"{name} is (nearly) constant"
        depth = images[f"{name}_depth"]
        assert depth.dtype == np.uint16 and depth.shape == (240, 320)


def test_head_depth_is_in_millimetres(sim):
    sim.reset()
    depth = sim.images(depth=True)["head_camera_depth"]
    # the camera looks along (0, 0.6, -0.8) at the table centre, 0.86 m below it and 0.645 m
    # ahead: the table centre is 1.075 m away; cube_2 stands there, its top ~3 cm nearer
    centre = depth[120, 160]
    assert 1015 < centre < 1075


@pytest.mark.parametrize("moving", ["left", "right"])
def test_wrist_image_follows_its_own_arm_only(sim, moving):
    sim.reset()
    home = sim.station.embodiment.home_action()
    for _ in range(15):  # settle
        sim.step(home)
    before = sim.images()
    a = home.copy()
    k = 0 if moving == "left" else 7
    a[k] += 0.4 if moving == "left" else -0.4  # waist
    for _ in range(15):
        sim.step(a)
    after = sim.images()
    own, other = f"{moving}_camera", f"{'right' if moving == 'left' else 'left'}_camera"
    assert np.abs(after[own].astype(int) - before[own]).mean() > 5
    # the other arm only settles by micro-radians: its view is unchanged to the eye
    assert np.abs(after[other].astype(int) - before[other]).mean() < 0.05


@pytest.mark.parametrize("camera", WRISTS)
def test_wrist_view_shows_fingertips_and_gripper_covers_under_a_quarter(sim, camera):
    sim.reset()
    plant = sim.station.plant
    side = camera.split("_")[0]
    inst = sim.station.arms[side]
    labels = sim.label_image(camera)
    own = {
        int(plant.GetBodyByName(n, inst).index())
        for n in ("gripper_link", "left_finger", "right_finger", "wrist_link")
    }
    fingers = [int(plant.GetBodyByName(n, inst).index()) for n in ("left_finger", "right_finger")]
    assert np.isin(labels, list(own)).mean() <= 0.25
    for f in fingers:
        assert (labels == f).sum() > 100, "fingertip not visible"
    assert (labels == int(plant.GetBodyByName("table_top").index())).mean() > 0.4


def test_intrinsics_follow_the_field_of_view(sim):
    K = sim.intrinsic_cv("head_camera")
    fy = 120 / np.tan(np.deg2rad(42.0) / 2)
    assert K[1, 1] == pytest.approx(fy)
    assert K[0, 2] == pytest.approx(159.5) and K[1, 2] == pytest.approx(119.5)


@pytest.mark.parametrize("camera", ["head_camera", "left_camera"])
def test_extrinsics_project_objects_onto_their_pixels(sim, camera):
    """A world point projected with K [R|t] lands on the pixel labelled with its body."""
    sim.reset()
    K, E = sim.intrinsic_cv(camera), sim.extrinsic_cv(camera)
    labels = sim.label_image(camera)
    plant = sim.station.plant
    robot = {
        int(body.index())
        for inst in sim.station.arms.values()
        for body in (plant.get_body(i) for i in plant.GetBodyIndices(inst))
    }
    hits = 0
    for name, pose in sim.object_poses().items():
        p_cam = E @ np.append(pose[:3], 1.0)
        if p_cam[2] <= 0:
            continue
        u, v, w = K @ p_cam
        col, row = int(round(u / w)), int(round(v / w))
        if 0 <= row < labels.shape[0] and 0 <= col < labels.shape[1]:
            if labels[row, col] in robot:  # the arm in front of it (the wrist camera's fingers)
                continue
            body = int(sim.station.object_bodies[name].index())
            assert labels[row, col] == body, f"{name} not at its projected pixel in {camera}"
            hits += 1
    assert hits >= 2
