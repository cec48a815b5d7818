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


@pytest.mark.parametrize("base_radius", [0.075, 0.05])
def test_walls_on_base_leave_only_the_base_on_the_support(base_radius):
    kw = dict(radius=0.075, base_radius=base_radius, height=0.03, wall=0.012, segments=12)
    standing, reaching = BowlShape(**kw, walls_on_base=True), BowlShape(**kw)
    for p in standing.primitives()[1:]:
        bottom = p.trimesh().bounds[0][2]
        assert standing.wall / 2 < bottom < standing.wall + 0.001  # on the disc, off the table
        top = p.trimesh().bounds[1][2]
        assert top == pytest.approx(standing.height, abs=0.005)  # the rim keeps its height
        # the wall still rises from the base's edge, where the rim grasp expects it
        assert np.hypot(*p.pose.xyz[:2]) == pytest.approx(
            base_radius + (0.075 - base_radius) * 0.7 - 0.006, abs=0.004
        )
    assert min(p.trimesh().bounds[0][2] for p in reaching.primitives()[1:]) < 0.002
    assert standing.primitives()[0] == reaching.primitives()[0]  # the same base disc


def test_walls_on_base_default_keeps_the_original_slabs():
    # other tasks' bowls (cook, handover) must keep bit-identical collision geometry
    bowl = BowlShape(radius=0.07, base_radius=0.045, height=0.05, segments=16)
    assert bowl == BowlShape(
        radius=0.07, base_radius=0.045, height=0.05, segments=16, walls_on_base=False
    )
    slab = bowl.primitives()[1]
    assert slab.pose.xyz[2] == bowl.height / 2
    assert slab.size[2] == float(np.hypot(0.07 - 0.045, 0.05))


def test_pot_is_an_open_round_wall_with_two_handles_at_the_rim():
    from bicoord_drake.models.objects import PotShape

    pot = PotShape(radius=0.07, height=0.08, segments=16)
    prims = pot.primitives()
    assert len(prims) == 1 + 16 + 2  # base disc, wall slabs, two handle plates
    left, right = (prims[i] for i in pot.handle_indices())
    for handle, sign in ((left, -1.0), (right, 1.0)):
        x, y, z = handle.pose.xyz
        assert handle.kind == "box" and sign * x > pot.radius and y == 0.0
        # reaches from the wall outward, its top just under the rim
        assert abs(x) - handle.size[0] / 2 < pot.radius < abs(x) + handle.size[0] / 2
        assert z + handle.size[2] / 2 == pytest.approx(pot.height - pot.handle_drop)
    # the wall slabs stand on the base: only the disc touches the support, the inside is open
    for p in prims[1:17]:
        assert p.pose.xyz[2] - p.size[2] / 2 >= pot.wall - 1e-9
        assert np.hypot(*p.pose.xyz[:2]) > pot.radius - pot.wall - 1e-9
    mesh = pot.visual_mesh()
    lo, hi = mesh.bounds
    assert hi[0] == pytest.approx(pot.radius + pot.handle_reach, abs=0.003)
    assert lo[0] == pytest.approx(-hi[0], abs=1e-6) and hi[2] == pytest.approx(pot.height)
    # open: every vertex inside the inner wall lies on the base (underside or inner floor)
    v = mesh.vertices
    inner = np.hypot(v[:, 0], v[:, 1]) < pot.radius - pot.wall - 1e-6
    assert inner.any() and np.all(np.isin(np.round(v[inner, 2], 9), [0.0, pot.wall]))


def test_pot_stands_in_physics_and_is_a_container():
    from bicoord_drake.config import StationConfig
    from bicoord_drake.models.geometry import Pose
    from bicoord_drake.models.objects import PotShape
    from bicoord_drake.models.scene import TABLE_TOP
    from bicoord_drake.sim.simulation import Simulation
    from bicoord_drake.sim.station import build_station
    from bicoord_drake.stages.predicates import cavity_of

    pot = PotShape(radius=0.07, height=0.08)
    cav = cavity_of(pot)
    assert cav.floor == pot.wall and cav.rim == pot.height
    assert cav.floor_radius == cav.rim_radius == pytest.approx(pot.radius - pot.wall)
    obj = SceneObject(name="pot", shape=pot, mass=0.3, pose=Pose(xyz=(0.0, 0.0, TABLE_TOP)))
    _, com, _ = inertial_of(pot.primitives(), 0.3)
    assert 0 < com[2] < pot.height / 2 and abs(com[0]) < 1e-9  # the handles balance
    sim = Simulation(build_station(Scene(objects=(obj,)), StationConfig(render=False)))
    for _ in range(10):
        sim.step(sim.station.embodiment.home_action())
    assert sim.object_poses()["pot"][2] == pytest.approx(TABLE_TOP, abs=0.002)
