"""Pens, markers and the pen holder (models/pens.py)."""

import math

import numpy as np
import pytest

from bicoord_drake.models.objects import BowlShape, SceneObject, object_sdf
from bicoord_drake.models.pens import PEN_KINDS, PenShape, max_lean, pen_holder, random_pen
from bicoord_drake.stages.predicates import cavity_of

PEN = PenShape(radius=0.007, length=0.14, tip_length=0.018, cap_length=0.02)


def test_the_tip_is_the_lowest_end_of_the_solid_along_z():
    lows = [p.trimesh().bounds[0][2] for p in PEN.primitives()]
    highs = [p.trimesh().bounds[1][2] for p in PEN.primitives()]
    assert min(lows) == pytest.approx(PEN.tip_point()[2]) == pytest.approx(-0.07)
    assert max(highs) == pytest.approx(0.07)
    tip = PEN.primitives()[1]
    assert tip.size[0] < PEN.radius  # the tip part is narrower than the body


def test_visual_has_body_and_accent_parts():
    sdf = object_sdf(SceneObject(name="pen", shape=PEN))
    assert sdf.count("<visual") == 2 and "pen_accent_0" in sdf
    ((accent, rgba),) = PEN.accent_visuals()
    assert rgba == PEN.accent
    assert accent.bounds[0][2] == pytest.approx(-0.07, abs=1e-6)  # the cone reaches the apex


def test_pen_survives_a_scene_round_trip_as_a_pen():
    obj = SceneObject(name="pen", shape=PEN)
    back = SceneObject.model_validate(obj.model_dump())
    assert isinstance(back.shape, PenShape) and back == obj


def test_tip_and_cap_must_fit_on_the_pen():
    with pytest.raises(ValueError):
        PenShape(radius=0.007, length=0.03, tip_length=0.02, cap_length=0.02)


def test_holder_is_a_straight_cup_with_a_real_cavity():
    h = pen_holder(radius=0.04, height=0.1, wall=0.004)
    assert isinstance(h, BowlShape) and h.base_radius == h.radius
    cav = cavity_of(h)
    assert cav.floor == pytest.approx(0.004) and cav.rim == pytest.approx(0.1)
    assert cav.floor_radius == pytest.approx(0.036) == pytest.approx(cav.rim_radius)


def test_max_lean_touches_the_rim_and_shrinks_with_thickness_and_depth():
    a = max_lean(0.036, 0.096, 0.007, 0.0035)
    d, h = 2 * 0.036 - 0.0035, 0.096
    # the rim's inner edge is exactly one pen radius from the leaning axis
    assert d * math.cos(a) - h * math.sin(a) == pytest.approx(0.007)
    assert math.radians(25) < a < math.radians(40)
    assert max_lean(0.036, 0.096, 0.009, 0.0045) < a  # a marker leans less
    assert max_lean(0.036, 0.12, 0.007, 0.0035) < a  # a deeper cup holds it straighter
    with pytest.raises(ValueError):
        max_lean(0.01, 0.01, 0.05, 0.01)


@pytest.mark.parametrize("seed", range(10))
def test_random_pens_are_thick_enough_to_grip_and_markers_thicker(seed):
    rng = np.random.default_rng(seed)
    pen, pen_mass, _ = random_pen(rng, "pen")
    marker, marker_mass, _ = random_pen(rng, "marker")
    assert 2 * pen.radius >= 0.012  # the closed jaw's gap is 8 mm
    assert marker.radius > pen.radius and marker_mass > pen_mass
    for shape, kind in ((pen, "pen"), (marker, "marker")):
        (r0, r1), (l0, l1), *_ = PEN_KINDS[kind]
        assert r0 <= shape.radius <= r1 and l0 <= shape.length <= l1
