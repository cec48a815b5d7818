"""StageMonitor on synthetic sequences: latching, persistence, dependencies, annotations."""

import numpy as np
import pytest

from bicoord_drake.data.stage_rows import check_rows
from bicoord_drake.stages import Stage, StageMonitor, WorldState, stage_index_from_rows
from tests.stages.helpers import scene

SCENE = scene()


def flags(**values) -> WorldState:
    """A state whose `step` encodes the test's predicate values (read through `FLAGS`)."""
    FLAGS.append(values)
    return WorldState.initial(SCENE, step=len(FLAGS) - 1)


FLAGS: list[dict] = []


def pred(key: str):
    return lambda s: FLAGS[s.step].get(key, False)


def run(stages, sequence, finish=None) -> StageMonitor:
    FLAGS.clear()
    monitor = StageMonitor(stages)
    for values in sequence:
        monitor.update(flags(**values))
    if finish is not None:
        monitor.finish(flags(**finish))
    return monitor


def two_stages(kind_a="transient", kind_b="persistent", depends_on=None):
    return [
        Stage("lift", "grasp", "grasp", 0.4, pred("a"), kind_a),
        Stage("place", "place", "hold", 0.6, pred("b"), kind_b, depends_on=depends_on),
    ]


def test_transient_is_latched_persistent_must_hold_at_end():
    m = run(two_stages(), [{"a": True}, {}, {"b": True}, {}])
    assert m.completed() == [True, False]
    assert m.score() == pytest.approx(0.4)
    assert not m.success
    m = run(two_stages(), [{"a": True}, {}, {"b": True}])
    assert m.completed() == [True, True] and m.success
    assert m.score() == pytest.approx(1.0)


def test_finish_state_judges_persistent_stages():
    m = run(two_stages(), [{"a": True}, {"b": True}], finish={})
    assert m.completed() == [True, False]
    m = run(two_stages(), [{"a": True}, {}], finish={"b": True})
    assert m.completed() == [True, True]
    assert m.frames == 2  # the finish state is not a frame


def test_dependencies_gate_counting():
    # the placement holds but the lift never happened: it does not count
    m = run(two_stages(), [{"b": True}])
    assert m.completed() == [False, False] and m.score() == 0.0
    # independent stage counts on its own
    m = run(two_stages(depends_on=()), [{"b": True}])
    assert m.completed() == [False, True] and m.score() == pytest.approx(0.6)


def test_given_stages_count_without_being_evaluated():
    def never_called(state):
        raise AssertionError("a given stage's predicate must not be evaluated")

    stages = [
        Stage("lift", "grasp", "grasp", 0.4, never_called, "persistent"),
        Stage("place", "place", "hold", 0.6, pred("b"), "persistent"),
    ]
    FLAGS.clear()
    monitor = StageMonitor(stages, given=1)
    monitor.update(flags())
    assert monitor.completed() == [True, False] and monitor.score() == 0.0  # given: unpaid
    monitor.update(flags(b=True))
    assert monitor.completed() == [True, True] and monitor.success
    assert monitor.score() == pytest.approx(0.6)
    with pytest.raises(ValueError, match="given"):
        StageMonitor(stages, given=3)


def test_explicit_dependencies_skip_stages():
    stages = [
        Stage("a", "", "", 0.2, pred("a"), "transient"),
        Stage("b", "", "", 0.3, pred("b"), "transient", depends_on=()),
        Stage("c", "", "", 0.5, pred("c"), "persistent", depends_on=(0,)),
    ]
    m = run(stages, [{"a": True}, {"c": True}])
    assert m.completed() == [True, False, True]
    assert m.score() == pytest.approx(0.7)
    assert m.dependencies == ((), (), (0,))


def test_partial_credit_counts_only_at_one():
    stages = [Stage("sort", "", "", 1.0, lambda s: FLAGS[s.step].get("f", 0.0), "persistent")]
    m = run(stages, [{"f": 0.5}])
    assert m.credit() == [0.5] and m.completed() == [False]
    assert m.score() == pytest.approx(0.5)


def test_validation():
    with pytest.raises(ValueError, match="sum to 1"):
        StageMonitor([Stage("x", "", "", 0.5, pred("a"), "transient")])
    with pytest.raises(ValueError, match="earlier stages"):
        StageMonitor(
            [
                Stage("x", "", "", 0.5, pred("a"), "transient", depends_on=(1,)),
                Stage("y", "", "", 0.5, pred("b"), "persistent"),
            ]
        )
    with pytest.raises(ValueError, match="at least one stage"):
        StageMonitor([])
    with pytest.raises(ValueError, match="kind"):
        Stage("x", "", "", 1.0, pred("a"), kind="sometimes")
    with pytest.raises(ValueError, match="score"):
        Stage("x", "", "", 1.5, pred("a"), "transient")


def test_annotations_contiguous_and_cover_all_frames():
    seq = [{}, {}, {"a": True}, {"a": True}, {}, {"b": True}, {"b": True}]
    m = run(two_stages(), seq)
    rows = m.annotations()
    assert rows == [[0, 3, "lift", "grasp", "grasp", 0.4], [3, 7, "place", "place", "hold", 0.6]]
    check_rows(rows, 7)
    np.testing.assert_array_equal(m.stage_index(), [0, 0, 0, 1, 1, 1, 1])
    assert m.annotations(10)[-1][:2] == [3, 10]  # the last stage runs to T


def test_annotation_stage_completing_with_its_predecessor_gets_one_frame():
    stages = [
        Stage("a", "", "", 0.5, pred("a"), "transient"),
        Stage("b", "", "", 0.0, pred("b"), "transient"),
        Stage("c", "", "", 0.5, pred("c"), "persistent"),
    ]
    m = run(stages, [{}, {"a": True, "b": True}, {"b": True}, {}, {"c": True}])
    assert m.completion_frames() == [1, 2, 4]
    assert [r[:2] for r in m.annotations()] == [[0, 2], [2, 3], [3, 5]]
    np.testing.assert_array_equal(m.stage_index(), [0, 0, 1, 2, 2])


def test_annotations_fail_on_incomplete_demo():
    m = run(two_stages(), [{}, {}])
    with pytest.raises(ValueError, match="did not count"):
        m.annotations()
    m = run(two_stages(), [{}, {"a": True}])
    with pytest.raises(ValueError, match="did not count"):
        m.annotations()  # nothing left for the last stage
    m = run(two_stages(), [{"a": True}, {"b": True}])
    with pytest.raises(ValueError, match="would span"):
        m.annotations(T=1)


def test_same_events_in_the_wrong_order_give_the_dependent_stage_nothing():
    three = [
        Stage("pick", "", "", 0.2, pred("a"), "transient"),
        Stage("handover", "", "", 0.3, pred("b"), "transient"),
        Stage("place", "", "", 0.5, pred("c"), "persistent"),
    ]
    right = run(three, [{"a": True}, {"b": True}, {"c": True}])
    assert right.completed() == [True, True, True] and right.success
    wrong = run(three, [{"b": True}, {"a": True}, {"c": True}])
    assert wrong.credit()[1] == 0.0 and wrong.completed() == [True, False, False]
    assert wrong.score() == pytest.approx(0.2) and not wrong.success
    # at the same update as its dependency is not after it either
    same = run(three, [{"a": True, "b": True}, {"c": True}])
    assert same.completed() == [True, False, False]


def test_partial_credit_latches_only_after_the_dependency():
    stages = [
        Stage("pick", "", "", 0.0, pred("a"), "transient"),
        Stage("throw", "", "", 1.0, lambda s: FLAGS[s.step].get("f", 0.0), "transient"),
    ]
    m = run(stages, [{"f": 0.5}, {"a": True}, {"f": 0.0}])
    assert m.credit() == [1.0, 0.0]
    m = run(stages, [{"a": True}, {"f": 0.5}, {"f": 0.0}])
    assert m.credit() == [1.0, 0.5] and m.score() == pytest.approx(0.5)


@pytest.mark.parametrize(
    "seq",
    [
        [{"a": True}, {"b": True}],
        [{"a": True, "b": True}],
        [{"b": True}, {"a": True}, {"b": True}],
        [{"a": True}, {}, {"b": True}, {"b": True}],
        [{"b": True}, {"a": True}],
        [{"a": True}],
    ],
)
@pytest.mark.parametrize("kinds", [("transient", "persistent"), ("transient", "transient")])
def test_success_and_annotations_never_disagree(seq, kinds):
    m = run(two_stages(*kinds), seq)
    if m.success:
        rows = m.annotations()
        check_rows(rows, m.frames)
    else:
        with pytest.raises(ValueError):
            m.annotations()


def test_stage_index_from_rows_and_row_checks():
    rows = [[0, 2, "a", "", "", 0.5], [2, 5, "b", "", "", 0.5]]
    np.testing.assert_array_equal(stage_index_from_rows(rows), [0, 0, 1, 1, 1])
    with pytest.raises(ValueError, match="contiguous"):
        check_rows([[0, 2, "a", "", "", 0.5], [3, 5, "b", "", "", 0.5]])
    with pytest.raises(ValueError, match="cover"):
        check_rows(rows, 6)


def test_reset_and_no_updates():
    m = run(two_stages(), [{"a": True}])
    m.reset()
    assert m.frames == 0 and m.credit() == [0.0, 0.0] and not m.success
