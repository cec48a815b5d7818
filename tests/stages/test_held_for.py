"""held_for (duration predicates) and the monitor's reset of predicates with memory."""

from dataclasses import replace

import pytest

from bicoord_drake.stages import Stage, StageMonitor, WorldState
from bicoord_drake.stages import predicates as P
from tests.stages.helpers import scene

SCENE = scene()


def at(t: float, flag: bool) -> WorldState:
    return WorldState.initial(
        SCENE, time=t, step=round(t * 15), contacts={"small": {"left"}} if not flag else {}
    )


def untouched():
    return P.Predicate(lambda s: not s.touching("small"), "untouched")


def test_held_for_needs_an_unbroken_run_of_the_duration():
    p = P.held_for(untouched(), 0.3)
    assert [p(at(k / 15, True)) for k in range(6)] == [False] * 4 + [False, True]
    assert not p(at(6 / 15, False))  # a break starts the count afresh
    assert [p(at(k / 15, True)) for k in range(7, 13)] == [False] * 5 + [True]


def test_held_for_refuses_time_going_back_without_a_reset():
    p = P.held_for(untouched(), 0.3)
    p(at(1.0, True))
    with pytest.raises(ValueError, match="reset"):
        p(at(0.0, True))
    p.reset()
    assert not p(at(0.0, True))


def test_monitor_reset_reaches_nested_stateful_predicates():
    nested = P.all_of(P.any_of(P.held_for(untouched(), 0.3), P.not_(P.lifted("small"))))
    stages = [Stage("rest", "", "", 1.0, P.held_for(untouched(), 0.3) & nested, "persistent")]
    first = StageMonitor(stages)
    for k in range(10):
        first.update(at(k / 15, True))
    assert first.success
    second = StageMonitor(stages)  # a new episode with the same stage list
    second.update(at(0.0, True))
    assert not second.success  # memory of the first episode is gone
    first.reset()
    first.update(at(0.0, True))
    assert first.completed() == [False]


def test_combinators_show_every_state_to_every_child():
    counter = P.held_for(untouched(), 0.0)
    seen = []
    spy = P.Predicate(lambda s: seen.append(s.time) or True, "spy")
    p = P.any_of(P.Predicate(lambda s: True, "yes"), spy) & P.count_true([counter], 1)
    p(at(0.0, True))
    assert seen == [0.0]


def test_settled_and_hands_free():
    moving = {"small": [0.05, 0, 0, 0, 0, 0]}
    base = WorldState.initial(SCENE)
    p = P.settled(["small", "large"])
    states = [replace(base, time=k / 15) for k in range(6)]
    assert [p(s) for s in states] == [False] * 5 + [True]
    p.reset()
    fast = WorldState.initial(SCENE, object_velocities={**base.object_velocities, **moving})
    assert not p(fast)
    assert P.hands_free(["small"])(base)
    assert not P.hands_free(["small"])(at(0.0, False))
