"""The collision checker carries exactly what the grippers hold, and adds shapes only when a
hold changes (PlanningModel._sync_checker_held)."""

from __future__ import annotations

import pytest
from pydrake.all import RigidTransform

from bicoord_drake.models.scene import demo_scene
from bicoord_drake.planning.model import HeldObject, PlanningModel


@pytest.fixture()
def model() -> PlanningModel:
    return PlanningModel(demo_scene("cubes"))


def added(m: PlanningModel) -> dict[str, int]:
    """Shapes the checker carries per group (empty groups left out)."""
    return {g: len(s) for g, s in m.checker.GetAllAddedCollisionShapes().items() if s}


class Spy:
    """Counts the checker's AddCollisionShapeToBody calls of one model."""

    def __init__(self, m: PlanningModel) -> None:
        self.calls = 0
        real = m.checker.AddCollisionShapeToBody

        def add(*args):
            self.calls += 1
            return real(*args)

        m.checker = _Proxy(m.checker, add)


class _Proxy:
    def __init__(self, checker, add) -> None:
        self._checker, self.AddCollisionShapeToBody = checker, add

    def __getattr__(self, name):
        return getattr(self._checker, name)


def test_the_checker_carries_what_is_held_and_nothing_else(model):
    q = model.home.copy()
    assert added(model) == {}
    model.attach("cube_0", "left", q)
    shapes = added(model)
    assert list(shapes) == ["held_left"] and shapes["held_left"] >= 1
    # A merged check holds something else for a while; afterwards the hold is as it was.
    other = HeldObject("cube_1", "right", RigidTransform([0.1, 0.0, 0.0]))
    with model.holding({"right": other}):
        assert set(added(model)) == {"held_right"}
    assert set(added(model)) == {"held_left"}
    # Ignored, a held object collides with nothing; afterwards it is back on the gripper.
    with model.ignoring(["cube_0"]):
        assert added(model) == {}
    assert set(added(model)) == {"held_left"}
    model.detach("left", q)
    assert added(model) == {}


def test_an_unchanged_hold_adds_no_shape(model):
    q = model.home.copy()
    model.attach("cube_0", "left", q)
    spy = Spy(model)
    model._sync_checker_held()
    model._sync_checker_held()
    assert spy.calls == 0
    # The same object at another grasp is a change.
    held = model.held["left"]
    moved = HeldObject(held.name, "left", held.X_GO @ RigidTransform([0.0, 0.0, 0.01]))
    with model.holding({"left": moved}):
        assert spy.calls >= 1
        calls = spy.calls
    assert spy.calls == 2 * calls  # put back: the original grasp's shapes again


def test_the_hands_filters_follow_a_two_handed_hold_through_arms_only(model):
    q = model.home.copy()
    pair = model._cluster_pairs[0]
    nominal = model._nominal_filtered[pair]
    with model.arms_only():
        model.attach_both("cube_0", q)
        assert model.checker.IsCollisionFilteredBetween(*pair)
    # arms_only put the filter matrix back as it was before the hold (not together) ...
    assert model.checker.IsCollisionFilteredBetween(*pair) == nominal
    # ... so the next sync must set the two-handed hold's filters again.
    model._sync_checker_held()
    assert model.checker.IsCollisionFilteredBetween(*pair)
    model.detach_both(q)
    assert model.checker.IsCollisionFilteredBetween(*pair) == nominal
