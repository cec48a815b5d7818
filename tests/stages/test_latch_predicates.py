"""latched, near_start, within_square and weighted on synthetic world states."""

import math

import pytest

from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.stages import predicates as P
from tests.stages.helpers import pose, quat_about, state

UP = pose(-0.1, 0.0, TABLE_TOP + 0.02 + 0.05)  # the small cube lifted 5 cm
DOWN = pose(0.05, 0.1, TABLE_TOP + 0.02)  # the small cube set down elsewhere


def test_latched_holds_from_the_first_time_until_reset():
    lift = P.latched(P.lifted("small", 0.03))
    assert not lift(state())
    assert lift(state(poses={"small": UP}))
    assert lift(state(poses={"small": DOWN}))  # set down again: it has been lifted
    P.reset_predicate(lift)
    assert not lift(state(poses={"small": DOWN}))
    # a partial value never latches
    half = P.latched(P.fraction_true([P.lifted("small"), P.lifted("large")]))
    assert not half(state(poses={"small": UP})) and not half(state())


def test_latched_inside_combinators_is_reset_by_the_monitor_reset():
    both = P.all_of(P.latched(P.lifted("small")), P.latched(P.lifted("large")))
    assert not both(state(poses={"small": UP}))
    big_up = pose(0.1, 0.0, TABLE_TOP + 0.03 + 0.05)
    assert both(state(poses={"large": big_up}))  # the small one was lifted before
    P.reset_predicate(both)
    assert not both(state(poses={"large": big_up}))


def test_near_start_within_a_centimetre():
    assert P.near_start("small")(state())
    assert P.near_start("small")(state(poses={"small": pose(-0.1 + 0.007, 0.0, TABLE_TOP + 0.02)}))
    assert not P.near_start("small")(state(poses={"small": pose(-0.1, 0.012, TABLE_TOP + 0.02)}))
    # knocked off: fallen and tipped over
    toppled = pose(-0.14, 0.0, TABLE_TOP + 0.02, quat_about("y", math.pi / 2))
    assert not P.near_start("small")(state(poses={"small": toppled}))
    assert not P.near_start("small")(state(poses={"small": UP}))


def test_within_square_both_axes_and_turned():
    near = state(poses={"small": pose(0.025, -0.025, TABLE_TOP + 0.02)})
    assert P.within_square("small", (0.0, 0.0), 0.03)(near)
    assert not P.within_square("small", (0.0, 0.0), 0.02)(near)
    beside = state(poses={"small": pose(0.0, 0.04, TABLE_TOP + 0.02)})
    assert not P.within_square("small", (0.0, 0.0), 0.03)(beside)
    # a square turned by 45 deg: the corner direction reaches further
    corner = state(poses={"small": pose(0.0, 0.035, TABLE_TOP + 0.02)})
    assert not P.within_square("small", (0.0, 0.0), 0.03)(corner)
    assert P.within_square("small", (0.0, 0.0), 0.03, yaw=math.pi / 4)(corner)


def test_weighted_partial_credit():
    credit = P.weighted([P.lifted("small"), P.lifted("large"), P.on_table("small")], [1, 1, 2])
    assert credit(state()) == pytest.approx(0.5)  # only the small cube on the table
    assert credit(state(poses={"small": UP})) == pytest.approx(0.25)
    big_up = pose(0.1, 0.0, TABLE_TOP + 0.03 + 0.05)
    assert credit(state(poses={"small": UP, "large": big_up})) == pytest.approx(0.5)
    with pytest.raises(ValueError):
        P.weighted([P.lifted("small")], [1, 2])
    with pytest.raises(ValueError):
        P.weighted([P.lifted("small")], [0])
