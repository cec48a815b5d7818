"""slid_open / slid_closed read a sliding object's measured joint position."""

from dataclasses import replace

import pytest

from bicoord_drake.models.cabinet import cabinet
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.stages import WorldState
from bicoord_drake.stages.predicates import slid_closed, slid_open


@pytest.fixture(scope="module")
def state() -> WorldState:
    body, drawer = cabinet("cabinet", "drawer", (0.0, 0.15), TABLE_TOP)
    return WorldState.initial(Scene(objects=(body, drawer)))


def _at(state: WorldState, d: float) -> WorldState:
    return replace(state, joint_positions={"drawer": d})


def test_open_counts_from_the_distance(state):
    opened = slid_open("drawer", 0.12)
    assert not opened(state)  # starts closed
    assert opened(_at(state, 0.12)) and opened(_at(state, 0.16))
    assert not opened(_at(state, 0.119)) and not opened(_at(state, 0.0))


def test_closed_within_the_tolerance(state):
    closed = slid_closed("drawer", 0.02)
    assert closed(state) and closed(_at(state, 0.019))
    assert not closed(_at(state, 0.03)) and not closed(_at(state, 0.16))


def test_an_object_without_a_joint_has_no_position(state):
    with pytest.raises(KeyError, match="sliding objects"):
        slid_open("cabinet", 0.1)(state)
