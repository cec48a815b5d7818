"""Drawer skills: grasp the handle from above, slide along the joint axis, let go."""

import numpy as np
import pytest

from bicoord_drake.models.cabinet import HANDLE_PART, CabinetDims, cabinet
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.skills import SkillContext
from bicoord_drake.planning.skills.drawer import (
    grasp_handle,
    handle_opening,
    let_go_handle,
    slide_drawer,
)

DIMS = CabinetDims(handle_x=0.06)


@pytest.fixture(scope="module")
def scene() -> Scene:
    body, drawer = cabinet("cabinet", "drawer", (0.0, 0.15), TABLE_TOP, DIMS)
    return Scene(name="drawer", objects=(body, drawer, cube("inside", 0.3, -0.2)))


def _tcp_path(ctx, side, plan) -> np.ndarray:
    q = np.repeat(ctx.q[None], plan.num_steps, 0)
    q[:, ctx.model.side_slice(side)] = plan.q
    return np.array([ctx.model.tcp_pose(x, side).translation() for x in q])


def test_grasp_slide_and_let_go(scene):
    ctx = SkillContext(PlanningModel(scene), speed=0.7)
    bar = scene.object("drawer").shape.primitives()[HANDLE_PART]
    grasp = grasp_handle(ctx, "right", "drawer", HANDLE_PART)
    p_bar = ctx.model.object_pose("drawer") @ np.asarray(bar.pose.xyz)
    X = ctx.model.tcp_pose(ctx.q, "right")
    np.testing.assert_allclose(X.translation(), p_bar, atol=2e-3)  # TCP on the bar's centre
    assert X.rotation().col(0) @ [0, 0, -1] > 0.999  # from above
    assert abs(X.rotation().col(1)[1]) > 0.999  # fingers across the bar (along y)
    assert grasp.opening[0] > handle_opening(ctx, bar.size[1]) - 1e-9  # narrowed on the way
    assert grasp.opening[-1] == 0.0  # closed on it
    # open 12 cm: the TCP runs straight along -y at every sample, the drawer follows in the
    # model; what lies in it moves with it
    p0 = X.translation()
    X_in = ctx.model.object_pose("inside")
    out = slide_drawer(ctx, "right", "drawer", 0.12, carried=["inside"])
    path = _tcp_path(ctx, "right", out)
    np.testing.assert_allclose(path[0], p0, atol=1e-3)
    np.testing.assert_allclose(path[-1], p0 + [0.0, -0.12, 0.0], atol=2e-3)
    off_line = np.linalg.norm(path[:, [0, 2]] - p0[[0, 2]], axis=1)
    assert off_line.max() < 2e-3 and np.all(np.diff(path[:, 1]) <= 1e-4)
    assert ctx.model.slide_position("drawer") == pytest.approx(0.12)
    np.testing.assert_allclose(
        ctx.model.object_pose("inside").translation(), X_in.translation() + [0, -0.12, 0]
    )
    # it cannot go past its stop
    slide_drawer(ctx, "right", "drawer", 1.0)
    assert ctx.model.slide_position("drawer") == pytest.approx(DIMS.travel)
    with pytest.raises(PlanningError, match="slide_at_limit"):
        slide_drawer(ctx, "right", "drawer", 0.05)
    # pushed shut, then let go: the jaw opens only as wide as the handle allows, and rises
    back = slide_drawer(ctx, "right", "drawer", -DIMS.travel)
    assert ctx.model.slide_position("drawer") == pytest.approx(0.0)
    assert _tcp_path(ctx, "right", back)[-1] == pytest.approx(p0, abs=2e-3)
    up = let_go_handle(ctx, "right", "drawer", HANDLE_PART)
    assert up.opening[-1] == pytest.approx(handle_opening(ctx, bar.size[1]))
    assert ctx.model.tcp_pose(ctx.q, "right").translation()[2] == pytest.approx(p0[2] + 0.06)


def test_slide_needs_a_sliding_object(scene):
    ctx = SkillContext(PlanningModel(scene))
    with pytest.raises(ValueError, match="slide"):
        slide_drawer(ctx, "right", "cabinet", 0.1)
