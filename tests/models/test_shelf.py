"""The shelf: two walls and a top plate forming a tunnel along x, one fixed body."""

import numpy as np
import pytest

from bicoord_drake.models.objects import object_sdf
from bicoord_drake.models.shelf import ShelfDims, shelf, shelf_shape
from bicoord_drake.stages.predicates import local_bounds


def test_walls_leave_the_tunnel_and_carry_the_plate():
    dims = ShelfDims(length=0.15, width=0.2, gap=0.09, clearance=0.065, wall=0.02, plate=0.02)
    walls, plate = shelf_shape(dims).parts[:2], shelf_shape(dims).parts[2]
    for wall in walls:
        lo, hi = wall.trimesh().bounds
        assert lo[2] == pytest.approx(0.0) and hi[2] == pytest.approx(0.065)
        assert min(abs(lo[1]), abs(hi[1])) == pytest.approx(0.045)  # inner faces 9 cm apart
        assert hi[0] - lo[0] == pytest.approx(0.15)
    lo, hi = plate.trimesh().bounds
    assert lo[2] == pytest.approx(0.065) and hi[2] == pytest.approx(dims.top) == 0.085
    assert np.allclose(hi[:2] - lo[:2], [0.15, 0.2])


def test_box_centre_and_top_are_the_plates():
    lo, hi = local_bounds(shelf_shape())
    assert np.allclose((lo + hi)[:2] / 2, 0.0)
    assert hi[2] == pytest.approx(ShelfDims().top) and lo[2] == pytest.approx(0.0)


def test_shelf_is_a_fixed_body_with_three_collision_boxes():
    obj = shelf("shelf", (-0.075, 0.0), 0.75)
    assert obj.fixed and obj.pose.xyz == (-0.075, 0.0, 0.75)
    assert object_sdf(obj).count("<collision") == 3


def test_walls_must_fit_under_the_plate():
    with pytest.raises(ValueError):
        ShelfDims(width=0.1, gap=0.09, wall=0.02)
