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


# ------------------------------------------------------------------ bins and small objects
def _solid_volume(shape, n: int = 60) -> float:
    """Volume of the union of a shape's primitives (boxes, cylinders, capsules) on an n^3 grid."""
    from bicoord_drake.models.geometry import pose_matrix

    prims = shape.primitives()
    lo = np.min([p.trimesh().bounds[0] for p in prims], axis=0)
    hi = np.max([p.trimesh().bounds[1] for p in prims], axis=0)
    axes = [lo[i] + (np.arange(n) + 0.5) * (hi[i] - lo[i]) / n for i in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    inside = np.zeros(len(pts), bool)
    for p in prims:
        T = pose_matrix(p.pose.xyz, p.pose.rpy)
        local = (pts - T[:3, 3]) @ T[:3, :3]
        if p.kind == "box":
            inside |= np.all(np.abs(local) <= np.asarray(p.size) / 2, axis=1)
        else:
            r, half = p.size[0], p.size[1] / 2
            radial = np.hypot(local[:, 0], local[:, 1])
            if p.kind == "cylinder":
                inside |= (radial <= r) & (np.abs(local[:, 2]) <= half)
            else:  # capsule: within r of its axis segment
                z = np.clip(local[:, 2], -half, half)
                inside |= np.hypot(radial, local[:, 2] - z) <= r
    return float(inside.mean() * np.prod(hi - lo))


def test_bin_is_an_open_box_with_its_real_cavity():
    from bicoord_drake.models.objects import BinShape
    from bicoord_drake.stages.predicates import cavity_of

    bin_ = BinShape(size=(0.19, 0.17, 0.08), wall=0.006)
    prims = bin_.primitives()
    assert len(prims) == 5  # floor + four walls, never a hull
    cav = cavity_of(bin_)
    assert cav.kind == "box" and cav.floor == pytest.approx(0.006) and cav.rim == 0.08
    assert cav.half_xy == pytest.approx((0.089, 0.079))
    # nothing above the floor inside the walls: the opening is free down to the floor
    for p in prims[1:]:
        x, y, _ = p.pose.xyz
        assert abs(x) + p.size[0] / 2 > 0.0949 or abs(y) + p.size[1] / 2 > 0.0849
        assert abs(x) - p.size[0] / 2 >= 0.089 - 1e-9 or abs(y) - p.size[1] / 2 >= 0.079 - 1e-9
    # walls reach the rim
    assert max(p.pose.xyz[2] + p.size[2] / 2 for p in prims) == pytest.approx(0.08)
    with pytest.raises(ValidationError, match="no room"):
        BinShape(size=(0.01, 0.17, 0.08), wall=0.006)


def test_small_everyday_objects_are_small_and_simple():
    from bicoord_drake.tasks.clean_table import KINDS

    for name, (shape, mass, _) in KINDS.items():
        volume = _solid_volume(shape)
        assert 50e-6 < volume <= 125e-6, (name, volume * 1e6)
        assert len(shape.primitives()) <= 6, name
        assert 0.02 <= mass <= 0.1


def test_domed_box_is_a_box_with_a_ridge_on_top():
    from bicoord_drake.models.objects import domed_box

    shape = domed_box((0.085, 0.05, 0.02), 0.017)
    box, ridge = shape.primitives()
    assert ridge.kind == "capsule" and ridge.pose.xyz[2] == pytest.approx(0.02)
    # its bottom is the box's: flat on the table, frame on the bottom face
    assert min(p.trimesh().bounds[0][2] for p in (box, ridge)) == pytest.approx(0.0, abs=1e-9)
    # the ridge's lower half lies inside the box: volume = box + half a capsule
    capsule = np.pi * 0.017**2 * ridge.size[1] + 4 / 3 * np.pi * 0.017**3
    assert _solid_volume(shape, 80) == pytest.approx(0.085 * 0.05 * 0.02 + capsule / 2, rel=0.03)
    with pytest.raises(ValueError, match="dome radius"):
        domed_box((0.085, 0.05, 0.01), 0.017)


def test_toy_car_stands_on_its_wheels():
    from bicoord_drake.models.objects import toy_car

    parts = toy_car().primitives()
    wheels = [p for p in parts if p.kind == "cylinder"]
    assert len(wheels) == 4 and len(parts) == 6
    bottoms = {round(float(p.trimesh().bounds[0][2]), 6) for p in parts}
    assert min(bottoms) == pytest.approx(0.0, abs=1e-6)
    body_bottoms = [p.trimesh().bounds[0][2] for p in parts if p.kind == "box"]
    assert min(body_bottoms) > 0.003  # only the wheels touch the support


def test_box_rounding_changes_only_the_visual():
    plain, soap = (
        BoxShape(size=(0.08, 0.05, 0.025)),
        BoxShape(size=(0.08, 0.05, 0.025), rounding=0.01),
    )
    assert plain.primitives() == soap.primitives()
    assert soap.visual_mesh().volume < plain.visual_mesh().volume - 1e-6
    # the default visual is unchanged (6 % of the shortest side)
    from bicoord_drake.models.geometry import Primitive

    expected = Primitive(kind="box", size=plain.size).trimesh(smooth=0.06 * 0.025)
    np.testing.assert_allclose(plain.visual_mesh().vertices, expected.vertices)


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


def test_a_rigid_pot_keeps_the_base_its_walls_stand_on_compliant():
    from bicoord_drake.models.objects import PotShape, object_sdf

    pot = SceneObject(name="pot", shape=PotShape(radius=0.06, height=0.07))
    parts = object_sdf(pot, rigid=True).split("<collision ")[1:]
    assert len(parts) == len(pot.shape.primitives())
    assert "<drake:compliant_hydroelastic/>" in parts[0]  # the base disc
    assert all("<drake:rigid_hydroelastic/>" in p for p in parts[1:])  # walls and handles
    assert "<drake:compliant_hydroelastic/>" in object_sdf(pot)
    assert "<drake:rigid_hydroelastic/>" not in object_sdf(pot)


def test_an_object_may_ask_to_be_rigid_only_if_it_is_a_bowl_or_a_pot():
    from bicoord_drake.models.objects import object_sdf

    bowl = BowlShape(radius=0.058, base_radius=0.045, height=0.05)
    sdf = object_sdf(SceneObject(name="b", shape=bowl, rigid_hydroelastic=True))
    assert "<drake:compliant_hydroelastic/>" not in sdf  # its walls reach the support
    with pytest.raises(ValidationError, match="rigid_hydroelastic"):
        SceneObject(name="c", shape=BoxShape(size=(0.04, 0.04, 0.04)), rigid_hydroelastic=True)


def test_a_fixed_object_may_have_compliant_parts():
    from bicoord_drake.models.objects import object_sdf
    from bicoord_drake.tasks.clean_table import BIN as shape

    bin_ = SceneObject(name="bin", shape=shape, fixed=True, compliant_parts=(0,))
    parts = object_sdf(bin_).split("<collision ")[1:]
    assert "<drake:compliant_hydroelastic/>" in parts[0]  # the floor
    assert all("<drake:rigid_hydroelastic/>" in p for p in parts[1:])  # the walls
    with pytest.raises(ValidationError, match="fixed objects"):
        SceneObject(name="b", shape=shape, compliant_parts=(0,))
    with pytest.raises(ValidationError, match=r"\[5\] not in 0..4"):
        SceneObject(name="b", shape=shape, fixed=True, compliant_parts=(5,))


def _bounces(compliant: bool) -> list[float]:
    """Highest the block rose above where it rests on clean_table's bin floor (m) after
    landing, for each of DROP_HEIGHTS, the floor compliant or rigid."""
    from bicoord_drake.config import StationConfig
    from bicoord_drake.models.geometry import Pose
    from bicoord_drake.models.scene import TABLE_TOP
    from bicoord_drake.sim.simulation import Simulation
    from bicoord_drake.sim.station import build_station
    from bicoord_drake.tasks.clean_table import BIN

    rest = TABLE_TOP + BIN.floor_thickness + 0.0225
    bin_ = SceneObject(
        name="bin",
        shape=BIN,
        fixed=True,
        pose=Pose(xyz=(0.0, -0.05, TABLE_TOP)),
        compliant_parts=(0,) if compliant else (),
    )
    out = []
    for height in DROP_HEIGHTS:
        block = SceneObject(
            name="block",
            shape=BoxShape(size=(0.045, 0.045, 0.045)),
            mass=0.06,
            pose=Pose(xyz=(0.0, -0.05, rest + height)),
        )
        sim = Simulation(build_station(Scene(objects=(bin_, block)), StationConfig(render=False)))
        heights = []
        for _ in range(15):  # 1 s
            sim.step(sim.station.embodiment.home_action())
            heights.append(sim.object_poses()["block"][2] - rest)
        out.append(max(heights[3:]))  # landed by the third control step
    return out


#: Heights (m) the block is let go above where it rests flat on the bin's floor (landing at
#: 0.63-0.89 m/s, as clean_table's drops).
DROP_HEIGHTS = (0.020, 0.025, 0.038, 0.040)


def test_a_block_dropped_flat_into_a_bin_stays_on_its_compliant_floor():
    """Under SAP a compliant block landing flat on a rigid face at under 1 m/s can be thrown
    back up far over the rim (the rigid floor: the control); on a compliant floor it stays."""
    assert max(_bounces(compliant=True)) < 0.005
    assert max(_bounces(compliant=False)) > 0.06  # above the rim: the test can tell them apart


def _rise_after_release(contact_margin: float | None) -> tuple[float, float]:
    """(highest above its release height, final height above rest) in m of a block let go
    level and still 2.2 mm above the table, over 1 s."""
    from bicoord_drake.config import StationConfig
    from bicoord_drake.models.geometry import Pose
    from bicoord_drake.models.scene import TABLE_TOP
    from bicoord_drake.sim.simulation import Simulation
    from bicoord_drake.sim.station import build_station

    rest, release = TABLE_TOP + 0.0225, 0.0022
    block = SceneObject(
        name="block",
        shape=BoxShape(size=(0.045, 0.045, 0.045)),
        mass=0.06,
        pose=Pose(xyz=(0.0, -0.05, rest + release)),
        contact_margin=contact_margin,
    )
    sim = Simulation(build_station(Scene(objects=(block,)), StationConfig(render=False)))
    heights = []
    for _ in range(15):  # 1 s
        sim.step(sim.station.embodiment.home_action())
        heights.append(sim.object_poses()["block"][2] - rest)
    return max(heights) - release, heights[-1]


def test_an_object_with_a_contact_margin_is_not_thrown_up_when_let_go_just_above_the_table():
    """Under SAP with the station's 0.1 mm margin a block let go 2.2 mm above the rigid table
    comes back up 9 mm higher (the control); with a 5 mm contact margin of its own it comes
    down onto the table and stays."""
    rise, final = _rise_after_release(0.005)
    assert rise <= 0.0 and abs(final) < 0.0005
    rise, _ = _rise_after_release(None)
    assert rise > 0.005  # the test can tell them apart


def test_a_contact_margin_goes_to_that_object_s_geometries_only():
    from pydrake.all import Role

    from bicoord_drake.config import StationConfig
    from bicoord_drake.models.geometry import Pose
    from bicoord_drake.sim.station import build_station

    box = BoxShape(size=(0.04, 0.04, 0.04))
    a = SceneObject(name="a", shape=box, pose=Pose(xyz=(0.1, 0, 0.8)), contact_margin=0.005)
    b = SceneObject(name="b", shape=box, pose=Pose(xyz=(-0.1, 0, 0.8)))
    station = build_station(Scene(objects=(a, b)), StationConfig(render=False))
    inspector = station.scene_graph.model_inspector()
    margins = {}
    for geometry in inspector.GetAllGeometryIds(Role.kProximity):
        props = inspector.GetProximityProperties(geometry)
        if props.HasProperty("hydroelastic", "margin"):
            margins[inspector.GetName(geometry)] = props.GetProperty("hydroelastic", "margin")
    assert margins["a::a_collision_0"] == 0.005
    assert margins["b::b_collision_0"] == StationConfig().hydroelastic_margin
    with pytest.raises(ValidationError, match="contact_margin"):
        SceneObject(name="c", shape=box, contact_margin=0.05)


def test_transform_points_moves_rows_into_the_parent_frame():
    from pydrake.all import RigidTransform, RotationMatrix

    from bicoord_drake.models.geometry import transform_points

    X_AB = RigidTransform(RotationMatrix.MakeZRotation(np.pi / 2), [1.0, 2.0, 3.0])
    pts_B = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert np.allclose(transform_points(X_AB, pts_B), [[1.0, 3.0, 3.0], [1.0, 2.0, 4.0]])
    assert np.allclose(transform_points(X_AB, pts_B), [X_AB @ p for p in pts_B])
