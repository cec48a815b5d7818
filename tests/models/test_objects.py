"""Procedural objects: inertia, concave compounds, scene validation."""

import numpy as np
import pytest
from pydantic import ValidationError

from bicoord_drake.models.objects import BowlShape, BoxShape, SceneObject, inertial_of
from bicoord_drake.models.scene import Scene, cube, demo_scene


def test_box_inertia_matches_closed_form():
    size = (0.04, 0.06, 0.1)
    mass, com, diag = inertial_of(BoxShape(size=size).primitives(), 0.3)
    a, b, c = size
    expected = 0.3 / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(diag, expected, rtol=1e-6)
    np.testing.assert_allclose(com, 0, atol=1e-12)


def test_bowl_is_open_compound_with_low_centre_of_mass():
    bowl = BowlShape(radius=0.07, base_radius=0.045, height=0.05, segments=16)
    prims = bowl.primitives()
    assert len(prims) == 17  # base disc + 16 wall slabs, never a convex hull
    _, com, _ = inertial_of(prims, 0.15)
    assert 0 < com[2] < bowl.height / 2
    # the slabs stay outside the inner base radius: the opening is free down to the base
    for p in prims[1:]:
        assert np.hypot(*p.pose.xyz[:2]) > bowl.base_radius - bowl.wall


def test_scene_rejects_duplicate_names():
    with pytest.raises(ValidationError, match="duplicate"):
        Scene(objects=(cube("a", 0, 0), cube("a", 0.1, 0)))


def test_object_names_must_be_identifiers():
    with pytest.raises(ValidationError, match="name"):
        SceneObject(name="red cube", shape=BoxShape(size=(0.04, 0.04, 0.04)))


def test_unknown_demo_scene_lists_valid_names():
    with pytest.raises(ValueError, match="cubes"):
        demo_scene("kitchen")


def test_compound_shape_builds_a_simulated_object_from_its_parts():
    from bicoord_drake.config import StationConfig
    from bicoord_drake.models.geometry import Pose, Primitive
    from bicoord_drake.models.objects import CompoundShape
    from bicoord_drake.models.scene import TABLE_TOP
    from bicoord_drake.sim.simulation import Simulation
    from bicoord_drake.sim.station import build_station

    mic = CompoundShape(
        parts=(
            Primitive(kind="cylinder", size=(0.015, 0.12), pose=Pose(xyz=(0, 0, 0.06))),
            Primitive(kind="sphere", size=(0.025,), pose=Pose(xyz=(0, 0, 0.14))),
        )
    )
    obj = SceneObject(name="mic", shape=mic, mass=0.1, pose=Pose(xyz=(0, 0, TABLE_TOP)))
    _, com, _ = inertial_of(mic.primitives(), 0.1)
    assert 0.06 < com[2] < 0.14  # pulled up by the head
    sim = Simulation(build_station(Scene(objects=(obj,)), StationConfig(render=False)))
    for _ in range(10):
        sim.step(sim.station.embodiment.home_action())
    assert sim.object_poses()["mic"][2] == pytest.approx(TABLE_TOP, abs=0.002)  # stands on its base


def test_resolution_hint_overrides_the_shape_default():
    from bicoord_drake.models.objects import object_sdf

    plate = BowlShape(radius=0.075, base_radius=0.075, height=0.03, wall=0.012, segments=12)
    default = object_sdf(SceneObject(name="p", shape=plate))
    coarse = object_sdf(SceneObject(name="p", shape=plate, resolution_hint=0.03))
    assert "<drake:mesh_resolution_hint>0.01<" in default
    assert "<drake:mesh_resolution_hint>0.03<" in coarse
    assert "<drake:mesh_resolution_hint>0.01<" not in coarse
    with pytest.raises(ValidationError):
        SceneObject(name="p", shape=plate, resolution_hint=0.0)
