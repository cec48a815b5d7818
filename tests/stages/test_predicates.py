"""Predicates on synthetic world states."""

import math

import numpy as np
import pytest

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.stages import predicates as P
from bicoord_drake.stages.stage import quat_to_matrix
from tests.stages.helpers import pose, quat_about, scene, state

# small cube: 4 cm at (-0.1, 0); large cube: 6 cm at (0.1, 0); bowl at (0.2, -0.1); roller along x
SMALL_ON_LARGE = pose(0.1, 0.0, TABLE_TOP + 0.06 + 0.02)


def test_lifted_relative_to_initial_and_table():
    s0 = state()
    up = state(poses={"small": pose(-0.1, 0.0, TABLE_TOP + 0.02 + 0.05)})
    assert not P.lifted("small", 0.03)(s0)
    assert P.lifted("small", 0.03)(up)
    assert not P.lifted("small", 0.06)(up)
    assert P.lifted("small", 0.04, reference="table")(up)
    with pytest.raises(ValueError):
        P.lifted("small", reference="floor")


def test_on_top_of_uses_sizes():
    on = state(poses={"small": SMALL_ON_LARGE})
    assert P.on_top_of("small", "large")(on)
    assert not P.on_top_of("large", "small")(on)
    assert not P.on_top_of("small", "large")(state())
    hovering = state(poses={"small": SMALL_ON_LARGE + [0, 0, 0.03, 0, 0, 0, 0]})
    assert not P.on_top_of("small", "large")(hovering)
    offset = state(poses={"small": SMALL_ON_LARGE + [0.025, 0, 0, 0, 0, 0, 0]})
    assert not P.on_top_of("small", "large", xy_tol=0.02)(offset)
    assert P.on_top_of("small", "large", xy_tol=0.03)(offset)


def test_on_table_and_above():
    assert P.on_table("small")(state())
    on = state(poses={"small": SMALL_ON_LARGE})
    assert not P.on_table("small")(on)
    assert P.above("small", "large", xy_tol=0.01, min_dz=0.02)(on)
    assert not P.above("large", "small")(on)


def test_inside_container_follows_its_tilt():
    in_bowl = state(poses={"small": pose(0.2, -0.1, TABLE_TOP + 0.026)})
    assert P.inside("small", "bowl")(in_bowl)
    assert not P.inside("small", "bowl")(state())
    assert not P.inside("small", "bowl")(state(poses={"small": pose(0.2, -0.1, TABLE_TOP + 0.2)}))
    # bowl tilted 25 deg about x, cube on its floor: judged in the bowl's frame
    q = quat_about("x", math.radians(25))
    R = quat_to_matrix(q)
    bowl = np.array([0.2, -0.1, TABLE_TOP + 0.1])
    floor = bowl + R @ [0, 0, 0.006 + 0.021]
    tilted = state(poses={"bowl": pose(*bowl, q), "small": pose(*floor, q)})
    assert P.inside("small", "bowl")(tilted)
    # the same contents with the bowl tipped on its side hold nothing
    tipped = pose(0.2, -0.1, 0.9, quat_about("x", math.pi / 2))
    into = state(poses={"bowl": tipped, "small": tipped + [0, -0.025, 0, 0, 0, 0, 0]})
    assert not P.inside("small", "bowl")(into)


def test_released_needs_open_grippers_and_no_contact():
    assert P.released("small")(state())
    assert not P.released("small")(state(openings=(0.2, 1.0)))
    assert not P.released("small")(state(contacts={"small": {"right"}}))
    assert P.released("small")(state(contacts={"large": {"right"}}))


def test_released_lets_a_hand_keep_a_named_tool():
    holding = {"large": {"right"}}  # the right's fingers closed on the tool
    kept = P.released("small", tools=["large"])
    assert kept(state(openings=(1.0, 0.2), contacts=holding, finger_contacts=holding))
    # without the tool named, or closed on nothing, or closed on something else: not released
    assert not P.released("small")(
        state(openings=(1.0, 0.2), contacts=holding, finger_contacts=holding)
    )
    assert not kept(state(openings=(1.0, 0.2)))
    assert not kept(state(openings=(0.2, 1.0), contacts={"large": {"right"}}))
    # the hand with the tool touching the placed object: not released
    both = {"large": {"right"}, "small": {"right"}}
    assert not kept(state(openings=(1.0, 0.2), contacts=both, finger_contacts=both))
    assert P.released("small")(state(openings=(0.5, 0.5)))


def test_untouched_ignores_the_grippers_commands():
    # one arm let go of `small` while the other still holds something closed
    assert P.untouched("small")(state(openings=(1.0, 0.0), contacts={"large": {"right"}}))
    assert not P.untouched("small")(state(openings=(1.0, 1.0), contacts={"small": {"left"}}))
    assert not P.untouched("small")(state(openings=(0.0, 1.0), contacts={"small": {"left"}}))


def test_not_touched_by_looks_at_one_arm_and_all_its_bodies():
    left_off = P.not_touched_by("small", "left")
    assert left_off.name == "not_touched_by('small', 'left')"
    assert left_off(state())
    # the other arm holding it (a handover done), or the left touching something else: passes
    assert left_off(state(openings=(1.0, 0.0), contacts={"small": {"right"}}))
    assert left_off(state(contacts={"large": {"left"}}))
    # the left fingers on it fail, closed or open, alone or with the right's
    fingers = {"small": {"left"}}
    assert not left_off(state(openings=(0.0, 1.0), contacts=fingers, finger_contacts=fingers))
    assert not left_off(state(contacts=fingers, finger_contacts=fingers))
    both = {"small": {"left", "right"}}
    assert not left_off(state(contacts=both, finger_contacts=both))
    # so does the left's palm or wrist against it, without a finger
    assert not left_off(state(contacts=fingers, finger_contacts={}))
    assert P.not_touched_by("small", "right")(state(contacts=fingers, finger_contacts=fingers))
    with pytest.raises(ValueError):
        P.not_touched_by("small", "any")


def test_stacked_is_a_tower_from_the_table_up():
    on = state(poses={"small": SMALL_ON_LARGE})
    assert P.stacked(["large", "small"])(on)
    assert not P.stacked(["small", "large"])(on)  # wrong order
    assert not P.stacked(["large", "small"])(state())  # side by side on the table
    beside = state(poses={"small": SMALL_ON_LARGE + [0.035, 0, 0, 0, 0, 0, 0]})
    assert not P.stacked(["large", "small"])(beside)
    raised = pose(0.1, 0.0, TABLE_TOP + 0.03 + 0.04)  # the pair held 4 cm above the table
    lifted = state(poses={"large": raised, "small": raised + [0, 0, 0.05, 0, 0, 0, 0]})
    assert P.on_top_of("small", "large")(lifted)
    assert not P.stacked(["large", "small"])(lifted)
    # the top block leaning on an edge: its lowest corner on the lower block's top
    q = quat_about("y", math.radians(40))
    corner = 0.02 * (math.cos(math.radians(40)) + math.sin(math.radians(40)))
    toppled = state(poses={"small": pose(0.1, 0.0, TABLE_TOP + 0.06 + corner, q)})
    assert P.on_top_of("small", "large")(toppled)
    assert not P.stacked(["large", "small"])(toppled)
    with pytest.raises(ValueError):
        P.stacked(["large"])
    # a block turned onto another face still lies flat
    rolled = state(poses={"small": pose(0.1, 0.0, TABLE_TOP + 0.08, quat_about("x", math.pi / 2))})
    assert P.stacked(["large", "small"])(rolled)


def test_stands_in_needs_the_floor_upright_and_inside():
    # bowl at (0.2, -0.1): floor 6 mm up, floor radius 3.9 cm; small cube 4 cm
    floor = TABLE_TOP + 0.006 + 0.02
    stands = P.stands_in("small", "bowl", gap=0.008)
    assert stands(state(poses={"small": pose(0.2, -0.1, floor)}))
    assert stands(state(poses={"small": pose(0.21, -0.09, floor + 0.005)}))
    # held above the floor (not standing on it), or dropped beside the bowl on the table
    assert not stands(state(poses={"small": pose(0.2, -0.1, floor + 0.02)}))
    assert not stands(state(poses={"small": pose(0.32, -0.1, TABLE_TOP + 0.02)}))
    # toppled in the bowl (leaning 30 degrees), or the bowl tipped over with the cube in it
    leaning = pose(0.2, -0.1, floor + 0.01, quat_about("y", math.radians(30)))
    assert not stands(state(poses={"small": leaning}))
    tipped = quat_about("x", math.radians(20))
    assert not stands(
        state(poses={"bowl": pose(0.2, -0.1, TABLE_TOP, tipped), "small": pose(0.2, -0.1, floor)})
    )
    # under the bowl is not in it
    assert not stands(state(poses={"small": pose(0.2, -0.1, TABLE_TOP - 0.02)}))


def test_untouched_ignores_the_gripper_commands():
    assert P.untouched("small")(state(openings=(0.0, 0.0)))
    assert not P.untouched("small")(state(contacts={"small": {"left"}}))
    assert P.untouched("small")(state(contacts={"large": {"right"}}, openings=(0.0, 1.0)))


def test_a_palm_or_wrist_against_an_object_is_touching_but_not_holding():
    # the palm (not a finger) of the left arm pins `small`: not released, not untouched, not held
    palm = state(openings=(1.0, 1.0), contacts={"small": {"left"}}, finger_contacts={})
    assert not P.released("small")(palm)
    assert not P.untouched("small")(palm)
    assert not P.hands_free(["small"])(palm)
    closed_palm = state(openings=(0.0, 1.0), contacts={"small": {"left"}}, finger_contacts={})
    assert not P.held_by("small", "left")(closed_palm)
    fingers = state(
        openings=(0.0, 1.0), contacts={"small": {"left"}}, finger_contacts={"small": {"left"}}
    )
    assert P.held_by("small", "left")(fingers)


def test_finger_contacts_must_be_robot_contacts():
    with pytest.raises(ValueError, match="must also be robot contacts"):
        state(contacts={}, finger_contacts={"small": {"left"}})


def test_held_by_side():
    held = state(openings=(0.0, 1.0), contacts={"small": {"left"}})
    assert P.held_by("small", "left")(held)
    assert P.held_by("small", "any")(held)
    assert not P.held_by("small", "right")(held)
    assert not P.held_by("small", "both")(held)
    both = state(openings=(0.0, 0.1), contacts={"roller": {"left", "right"}})
    assert P.held_by("roller", "both")(both)
    touching_open = state(openings=(1.0, 1.0), contacts={"small": {"left"}})
    assert not P.held_by("small", "left")(touching_open)
    with pytest.raises(ValueError):
        P.held_by("small", "middle")


def test_upright_and_level():
    assert P.upright("small")(state())
    tilted = state(poses={"small": pose(-0.1, 0, 0.8, quat_about("x", math.radians(30)))})
    assert not P.upright("small", max_tilt=math.radians(15))(tilted)
    assert P.upright("small", max_tilt=math.radians(31))(tilted)
    # the roller lies along x: level about x, not upright
    assert P.level("roller", axis="z")(state())
    assert not P.upright("roller")(state())


def test_upright_means_the_right_way_up():
    bowl = (0.2, -0.1, 0.8)
    rim_down = state(poses={"bowl": pose(*bowl, quat_about("x", math.pi))})
    assert not P.upright("bowl")(rim_down)
    assert not P.upright("bowl", max_tilt=math.radians(30))(rim_down)
    nearly_rim_down = state(poses={"bowl": pose(*bowl, quat_about("y", math.radians(170)))})
    assert not P.upright("bowl")(nearly_rim_down)
    assert P.upright("bowl")(state(poses={"bowl": pose(*bowl, quat_about("y", 0.1))}))


def test_vertical_accepts_either_way_up_for_symmetric_shapes():
    flipped = state(poses={"small": pose(-0.1, 0, 0.8, quat_about("x", math.pi))})
    assert P.vertical("small")(flipped)
    assert not P.upright("small")(flipped)
    tilted = state(poses={"small": pose(-0.1, 0, 0.8, quat_about("x", math.radians(150)))})
    assert not P.vertical("small")(tilted)
    assert P.vertical("small", max_tilt=math.radians(31))(tilted)
    assert not P.vertical("roller")(state())


def test_at_rest_reads_velocities():
    assert P.at_rest("small")(state())
    moving = state(velocities={"small": [0.05, 0, 0, 0, 0, 0]})
    assert not P.at_rest("small")(moving)
    spinning = state(velocities={"small": [0, 0, 0, 0, 0, 1.0]})
    assert not P.at_rest("small")(spinning)


def test_at_rest_from_finite_differences():
    s0 = state(step=0)
    s1 = state(poses={"small": pose(-0.1 + 0.01, 0.0, TABLE_TOP + 0.02)}, step=1)
    derived = s1.with_velocities_from(s0)
    np.testing.assert_allclose(derived.velocity("small")[:3], [0.15, 0, 0], atol=1e-9)
    assert not P.at_rest("small")(derived)
    assert P.at_rest("large")(derived)
    s2 = state(poses={"large": pose(0.1, 0, TABLE_TOP + 0.03, quat_about("z", 0.1))}, step=1)
    np.testing.assert_allclose(s2.with_velocities_from(s0).velocity("large")[3:], [0, 0, 1.5])


def test_within_xy_and_cells():
    assert P.within_xy("small", (-0.1, 0.005), tol=0.01)(state())
    assert not P.within_xy("small", (-0.1, 0.02), tol=0.01)(state())
    cells = [(-0.1, 0.0), (0.1, 0.0), (0.0, 0.0)]
    s = state()
    assert P.filled_cells(s, ["small", "large"], cells) == 2
    assert P.cells_filled(["small", "large"], cells, 2)(s)
    assert not P.cells_filled(["small", "large"], cells, 3)(s)
    lifted = state(poses={"small": pose(-0.1, 0.0, TABLE_TOP + 0.1)})
    assert P.filled_cells(lifted, ["small", "large"], cells) == 1  # held above: not filled
    assert P.filled_cells(s, [], cells) == 0


def test_combinators_and_names():
    s = state(poses={"small": SMALL_ON_LARGE})
    on, rel = P.on_top_of("small", "large"), P.released("small")
    assert (on & rel)(s) and (on | ~rel)(s) and not (~on)(s)
    assert "on_top_of('small', 'large'" in repr(on & rel)
    preds = [P.on_table("small"), P.on_table("large"), P.on_table("bowl")]
    assert P.count_true(preds, 2)(s) and not P.count_true(preds, 3)(s)
    assert P.fraction_true(preds)(s) == pytest.approx(2 / 3)
    assert P.all_of(*preds)(state()) is True


def test_unknown_object_is_a_clear_error():
    with pytest.raises(KeyError, match="no object 'ghost'"):
        P.lifted("ghost")(state(scene()))


def _roller_on_large(roll: float = 0.0, dz: float = 0.0, dx: float = 0.0) -> np.ndarray:
    """The roller (r = 2 cm, along x) lying across the large cube, turned `roll` about its
    own axis."""
    q_axis = quat_to_matrix(quat_about("y", math.pi / 2))
    turn = quat_to_matrix(quat_about("x", roll))
    R = turn @ q_axis
    w = math.sqrt(max(0.0, 1 + np.trace(R))) / 2
    quat = (
        w,
        (R[2, 1] - R[1, 2]) / (4 * w),
        (R[0, 2] - R[2, 0]) / (4 * w),
        (R[1, 0] - R[0, 1]) / (4 * w),
    )
    return pose(0.1 + dx, 0.0, TABLE_TOP + 0.06 + 0.02 + dz, quat)


def test_lowest_z_is_exact_for_a_lying_cylinder_at_any_roll():
    for roll in (0.0, 0.4, math.pi / 4, 2.0):
        s = state(poses={"roller": _roller_on_large(roll)})
        assert P.lowest_z(s, "roller") == pytest.approx(TABLE_TOP + 0.06, abs=1e-9)
    # its box reaches lower once it has turned about its axis
    turned = state(poses={"roller": _roller_on_large(math.pi / 4)})
    assert P.bottom_z(turned, "roller") < TABLE_TOP + 0.06 - 0.008
    # standing on its end: half its length below the centre
    standing = state(poses={"roller": pose(0.0, -0.2, TABLE_TOP + 0.175)})
    assert P.lowest_z(standing, "roller") == pytest.approx(TABLE_TOP, abs=1e-9)


def test_rests_on_a_cube_and_not_beside_above_or_on_the_table():
    on = P.rests_on("roller", "large", xy_tol=0.03)
    assert on(state(poses={"roller": _roller_on_large()}))
    assert on(state(poses={"roller": _roller_on_large(roll=math.pi / 4)}))  # turned, still on it
    assert on(state(poses={"roller": _roller_on_large(dx=0.025)}))
    assert not on(state(poses={"roller": _roller_on_large(dx=0.04)}))  # off centre
    assert not on(state(poses={"roller": _roller_on_large(dz=0.015)}))  # held above it
    assert not on(state())  # on the table in front of it
    beside = _roller_on_large()
    beside[1:3] = (0.07, TABLE_TOP + 0.02)
    assert not on(state(poses={"roller": beside}))  # on the table, next to the cube


def _bridge_scene():
    from bicoord_drake.models.geometry import Pose
    from bicoord_drake.models.objects import BoxShape, SceneObject
    from bicoord_drake.models.scene import Scene, cube

    beam = SceneObject(
        name="beam",
        shape=BoxShape(size=(0.30, 0.05, 0.05)),
        pose=Pose(xyz=(0.0, 0.1, TABLE_TOP + 0.025)),
    )
    return Scene(
        name="bridge",
        objects=(beam, cube("a", -0.125, 0.0, size=0.05), cube("b", 0.125, 0.0, size=0.05)),
    )


def test_spans_both_piers_and_not_one_end_beside_or_hovering():
    sc = _bridge_scene()
    across = P.spans("beam", ["a", "b"])
    top = TABLE_TOP + 0.05 + 0.025  # the beam's centre when it lies on the piers
    assert across(state(sc, poses={"beam": pose(0.0, 0.0, top)}))
    # shifted 2 cm along or across: both piers still under it
    assert across(state(sc, poses={"beam": pose(0.02, 0.015, top)}))
    # turned 10 degrees about z: still across both
    assert across(state(sc, poses={"beam": pose(0.0, 0.0, top, quat_about("z", 0.17))}))
    # the initial state: on the table beside the piers
    assert not across(state(sc))
    # slid 4 cm across: the piers' centres are no longer under it
    assert not across(state(sc, poses={"beam": pose(0.0, 0.04, top)}))
    # slid along so that one end is past pier b: pier a's centre beyond the beam's end
    assert not across(state(sc, poses={"beam": pose(0.16, 0.0, top)}))
    # hovering 2 cm above them (still held)
    assert not across(state(sc, poses={"beam": pose(0.0, 0.0, top + 0.02)}))
    # one end on pier b, the other on the table: tilted, its lowest corner below pier a's top
    tilt = math.atan2(0.05, 0.25)
    tilted = pose(0.0, 0.0, TABLE_TOP + 0.05, quat_about("y", tilt))
    assert not across(state(sc, poses={"beam": tilted}))
    # pier a tipped onto an edge (its top 2 cm above the beam's bottom) under one end
    low = pose(-0.125, 0.0, TABLE_TOP + 0.035, quat_about("x", math.pi / 4))
    assert not across(state(sc, poses={"beam": pose(0.0, 0.0, top), "a": low}))
    with pytest.raises(ValueError):
        P.spans("beam", [])


def test_spaced_measures_the_xy_distance_of_the_centres():
    sc = _bridge_scene()
    assert P.spaced("a", "b", 0.25, tol=0.01)(state(sc))
    assert not P.spaced("a", "b", 0.20, tol=0.04)(state(sc))
    lifted = pose(0.125, 0.0, TABLE_TOP + 0.2)  # height does not count
    assert P.spaced("a", "b", 0.25, tol=0.01)(state(sc, poses={"b": lifted}))
    closer = pose(0.05, 0.0, TABLE_TOP + 0.025)
    assert not P.spaced("a", "b", 0.25, tol=0.04)(state(sc, poses={"b": closer}))


def _platform_scene():
    """A fixed 8 x 8 x 6 cm platform at the origin and a 5 cm cube on it."""
    platform = SceneObject(
        name="platform",
        shape=BoxShape(size=(0.08, 0.08, 0.06)),
        fixed=True,
        pose=Pose(xyz=(0.0, 0.0, TABLE_TOP + 0.03)),
    )
    return Scene(name="platform", seed=0, objects=(platform, cube("block", 0.0, 0.0, size=0.05)))


def test_clear_of_needs_the_whole_footprint_off_the_support():
    sc = _platform_scene()
    clear = P.clear_of("block", "platform")
    z = TABLE_TOP + 0.06 + 0.025
    # on the platform (its start): not clear
    assert not clear(state(sc, poses={"block": pose(0.0, 0.0, z)}))
    # pulled out 10 cm along x, held at the same height: clear
    assert clear(state(sc, poses={"block": pose(0.10, 0.0, z)}))
    # pulled 6 cm: its inner 1.5 cm still over the platform
    assert not clear(state(sc, poses={"block": pose(0.06, 0.0, z)}))
    # exactly edge to edge (4 + 2.5 cm): clear, but not with a 1 cm margin
    assert clear(state(sc, poses={"block": pose(0.065, 0.0, z)}))
    assert not P.clear_of("block", "platform", margin=0.01)(
        state(sc, poses={"block": pose(0.065, 0.0, z)})
    )
    # off along the diagonal, turned 45 degrees: its corner reaches back over the platform
    turned = quat_about("z", math.pi / 4)
    assert not clear(state(sc, poses={"block": pose(0.055, 0.055, z, turned)}))
    assert clear(state(sc, poses={"block": pose(0.075, 0.075, z, turned)}))
    # toppled over the edge (tilted 45 degrees about y), centre 5 cm out: a corner over it
    tipped = quat_about("y", math.pi / 4)
    assert not clear(state(sc, poses={"block": pose(0.05, 0.0, z, tipped)}))
    # under the platform's footprint at any height (held above it, or below it): not clear
    assert not clear(state(sc, poses={"block": pose(0.0, 0.02, z + 0.2)}))


def test_footprint_gap_measures_the_separation_of_convex_polygons():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert P.footprint_gap(square, square + [3.0, 0.0]) == pytest.approx(2.0)
    assert P.footprint_gap(square, square + [0.5, 0.5]) < 0
    diamond = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]) + [2.5, 2.5]
    # the diamond's nearest vertex (2.5, 1.5) lies beside the square's corner: apart along a
    # diagonal normal, which only the diamond's edges provide
    assert P.footprint_gap(square, diamond) == pytest.approx(np.sqrt(2))


def _long_scene() -> Scene:
    """A 5 x 5 x 12 cm cuboid (long axis = its z), lying along y at the start."""
    bar = SceneObject(
        name="bar",
        shape=BoxShape(size=(0.05, 0.05, 0.12)),
        pose=Pose(xyz=(0.0, 0.0, TABLE_TOP + 0.025), rpy=(math.pi / 2, 0.0, 0.0)),
    )
    return Scene(name="synthetic_long", seed=0, objects=(bar,))


def test_stands_upright_at_needs_an_end_down_on_the_spot_untouched_and_still():
    sc = _long_scene()
    spot = (0.15, 0.03)
    standing = pose(0.15, 0.03, TABLE_TOP + 0.06)
    pred = P.stands_upright_at("bar", spot, 0.03)
    assert not pred(state(sc))  # lying where it started
    assert pred(state(sc, poses={"bar": standing}))
    # upside down is still standing on an end; 10 deg of lean is within 15 deg
    flipped = pose(0.15, 0.03, TABLE_TOP + 0.06, quat_about("x", math.pi))
    assert pred(state(sc, poses={"bar": flipped}))
    lean = pose(0.15, 0.03, TABLE_TOP + 0.061, quat_about("y", math.radians(10)))
    assert pred(state(sc, poses={"bar": lean}))
    # toppled (leaning 30 deg on a neighbour) or lying on the spot
    toppled = pose(0.15, 0.03, TABLE_TOP + 0.06, quat_about("y", math.radians(30)))
    assert not pred(state(sc, poses={"bar": toppled}))
    lying = pose(0.15, 0.03, TABLE_TOP + 0.025, quat_about("x", math.pi / 2))
    assert not pred(state(sc, poses={"bar": lying}))
    # beside the spot (3.5 cm off), held up in the air, still held, still moving
    assert not pred(state(sc, poses={"bar": pose(0.15, 0.065, TABLE_TOP + 0.06)}))
    assert pred(state(sc, poses={"bar": pose(0.15, 0.055, TABLE_TOP + 0.06)}))
    assert not pred(state(sc, poses={"bar": pose(0.15, 0.03, TABLE_TOP + 0.09)}))
    held = state(sc, poses={"bar": standing}, openings=(1.0, 0.0), contacts={"bar": {"right"}})
    assert not pred(held)
    other_hand_busy = state(sc, poses={"bar": standing}, openings=(0.0, 1.0))
    assert pred(other_hand_busy)
    moving = state(sc, poses={"bar": standing}, velocities={"bar": [0, 0, 0, 0.5, 0, 0]})
    assert not pred(moving)
