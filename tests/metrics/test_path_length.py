"""Joint-space path length of a hand-built trajectory with a known value."""

import numpy as np
import pytest

from bicoord_drake.metrics import joint_path_length


def test_known_path_length_sums_every_joints_travel_of_both_arms():
    # Left: joint 0 goes 0 -> 1 -> 0.5 (1.5 rad), joint 2 goes 0 -> 0 -> -0.25 (0.25 rad);
    # right: joint 1 goes 0.3 -> 0.1 -> 0.1 (0.2 rad). Total 1.95 rad: an L1 sum, not the
    # Euclidean length of the steps (which would be 1 + sqrt(0.5^2 + 0.25^2) + 0.2 = 1.76).
    left = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.0, -0.25]])
    right = np.array([[0.0, 0.3, 0.0], [0.0, 0.1, 0.0], [0.0, 0.1, 0.0]])
    assert joint_path_length(left, right) == pytest.approx(1.95)
    assert joint_path_length(left[:1], right[:1]) == 0.0


def test_bad_inputs_raise():
    q = np.zeros((3, 6))
    with pytest.raises(ValueError, match="mismatched trajectory lengths"):
        joint_path_length(q, q[:2])
    with pytest.raises(ValueError, match="shape"):
        joint_path_length(q[:, 0], q)
    with pytest.raises(ValueError, match="empty"):
        joint_path_length(q[:0], q[:0])
    with pytest.raises(ValueError, match="NaN"):
        joint_path_length(np.full((3, 6), np.nan), q)
