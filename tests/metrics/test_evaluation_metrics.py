"""SR, SSR and TL of rollouts."""

import numpy as np
import pytest

from bicoord_drake.metrics import stage_success_rate, success_rate, trajectory_length


def test_success_rate():
    assert success_rate([True, False, True, True]) == 0.75
    assert success_rate(np.array([0, 1])) == 0.5
    with pytest.raises(ValueError, match="at least one"):
        success_rate([])
    with pytest.raises(ValueError, match="booleans"):
        success_rate([0.3, 1.0])


def test_stage_success_rate_shared_scores():
    scores = [0.2, 0.3, 0.5]
    completed = [[True, True, True], [True, False, False], [False, False, False]]
    # (1.0 + 0.2 + 0.0) / 3
    assert stage_success_rate(scores, completed) == pytest.approx(0.4)


def test_stage_success_rate_per_rollout_scores():
    scores = [[0.5, 0.5], [0.1, 0.9]]
    completed = np.array([[1, 0], [0, 1]])
    assert stage_success_rate(scores, completed) == pytest.approx((0.5 + 0.9) / 2)


def test_stage_success_rate_all_completed_is_score_sum():
    scores = np.array([0.25, 0.25, 0.5])
    assert stage_success_rate(scores, np.ones((4, 3), bool)) == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("scores", "completed", "match"),
    [
        ([0.5, 0.5], [[True, True, True]], "scores must have shape"),
        ([[0.5, 0.5]], [[True, True], [True, True]], "scores must have shape"),
        ([0.5, 0.5], [True, True], "completed must be 2-D"),
        ([0.5, np.nan], [[True, True]], "finite"),
        ([0.5, -0.5], [[True, True]], "non-negative"),
        ([0.5, 0.5], np.zeros((0, 2), bool), "at least one"),
    ],
)
def test_stage_success_rate_bad_input(scores, completed, match):
    with pytest.raises(ValueError, match=match):
        stage_success_rate(scores, completed)


def test_trajectory_length():
    assert trajectory_length([100, 200, 300]) == 200.0
    assert trajectory_length([100, 200, 300], [True, False, True]) == 200.0
    assert trajectory_length([100, 200, 300], [False, True, False]) == 200.0
    assert trajectory_length([100, 200], [False, False]) is None
    with pytest.raises(ValueError, match="differ in shape"):
        trajectory_length([100, 200], [True])
