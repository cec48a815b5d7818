"""The Panda's closed-form IK (bicoord_drake/planning/panda_ik.py) against the planning model's
forward kinematics: random configurations are recovered on their own q7, every answer is exact
and within the limits, singular configurations do not raise."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.all import RigidTransform

from bicoord_drake.models.franka import PANDA_DH
from bicoord_drake.models.scene import Scene
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.panda_ik import Q7_OFFSETS, is_panda, panda_ik, panda_ik_near

SIDES = ("left", "right")


@pytest.fixture(scope="module")
def model() -> PlanningModel:
    return PlanningModel(Scene(), "franka_pair")


def _with_arm(model: PlanningModel, side: str, q: np.ndarray) -> np.ndarray:
    q_both = model.home.copy()
    q_both[model.side_slice(side)] = q
    return q_both


def _assert_exact(model: PlanningModel, side: str, X_WT: RigidTransform, sols, q7=None):
    """Every solution is within the limits and puts the TCP at X_WT (model FK)."""
    sl = model.side_slice(side)
    for q in sols:
        assert q.shape == (7,)
        assert np.all(q >= model.lower[sl]) and np.all(q <= model.upper[sl])
        if q7 is not None:
            assert abs(q[6] - q7) < 1e-12
        X = model.tcp_pose(_with_arm(model, side, q), side)
        assert np.linalg.norm(X.translation() - X_WT.translation()) < 1e-6
        assert np.linalg.norm(X.rotation().matrix() - X_WT.rotation().matrix()) < 1e-6
    for i, a in enumerate(sols):  # distinct branches
        for b in sols[i + 1 :]:
            assert np.max(np.abs(a - b)) > 1e-6


def _contains(sols, q: np.ndarray) -> bool:
    return any(np.max(np.abs(s - q)) < 1e-6 for s in sols)


def test_model_is_a_panda(model):
    assert is_panda(model)


def test_recovers_random_configurations(model):
    rng = np.random.default_rng(0)
    counts = []
    for _ in range(100):
        q_both = rng.uniform(model.lower, model.upper)
        for side in SIDES:
            q = q_both[model.side_slice(side)]
            X_WT = model.tcp_pose(q_both, side)
            sols = panda_ik(model, side, X_WT, q[6], near=q)
            assert _contains(sols, q), (side, q, sols)
            _assert_exact(model, side, X_WT, sols, q7=q[6])
            counts.append(len(sols))
    # several branches are found, never more than the 8 of the geometry
    assert max(counts) == 8 and min(counts) >= 1
    assert np.mean(np.array(counts) >= 2) > 0.5


def test_branches_from_another_seed_are_the_same(model):
    """`near` only picks the representative of each angle, not which branches exist."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        q_both = rng.uniform(model.lower, model.upper)
        q = q_both[7:]
        X_WT = model.tcp_pose(q_both, "right")
        a = panda_ik(model, "right", X_WT, q[6], near=q)
        b = panda_ik(model, "right", X_WT, q[6])  # near = home
        assert len(a) == len(b) and all(_contains(b, s) for s in a)


def test_q7_is_wrapped_into_its_limits(model):
    q = np.array([0.3, 0.2, -0.4, -1.9, 0.5, 1.8, 2.5])
    X_WT = model.tcp_pose(_with_arm(model, "right", q), "right")
    sols = panda_ik(model, "right", X_WT, q[6] - 2 * np.pi, near=q)
    assert _contains(sols, q)


def test_unreachable_poses_return_nothing(model):
    home = model.home[7:]
    X_home = model.tcp_pose(model.home, "right")
    far = RigidTransform(X_home.rotation(), X_home.translation() + [0.0, 2.0, 0.0])
    assert panda_ik(model, "right", far, home[6]) == []
    assert panda_ik_near(model, "right", far, home) == []
    # out of reach: 1.2 m in front of the shoulder (the TCP is never 0.95 m from it)
    base = model.embodiment.base_pose("right").xyz
    shoulder = np.array(base) + [0.0, 0.0, PANDA_DH[0][1]]
    out = RigidTransform(X_home.rotation(), shoulder + [0.0, 1.2, 0.0])
    assert panda_ik_near(model, "right", out, home) == []


def _singular_cases(model: PlanningModel, rng: np.random.Generator) -> list[np.ndarray]:
    """Right-arm configurations at or next to the singularities: the upper arm on joint 1's
    axis (q2 ~ 0), the wrist point on joint 1's axis (q3 = 0, q2 chosen for it: the wrist
    above the shoulder), joint 6 at or near 0 and at its lower limit, q5 at or near +-pi/2
    (the q6 double root of the fixed-q7 problem)."""
    sl = model.side_slice("right")
    lo, hi = model.lower[sl], model.upper[sl]
    cases = []
    for q2 in (0.0, 1e-9, 1e-6, 1e-3):
        for _ in range(5):
            q = rng.uniform(lo, hi)
            q[1] = q2
            cases.append(q)
    a4, d3, a5, d5 = PANDA_DH[3][0], PANDA_DH[2][1], PANDA_DH[4][0], PANDA_DH[4][1]
    while len(cases) < 30:
        q = rng.uniform(lo, hi)
        c4, s4 = np.cos(q[3]), np.sin(q[3])
        # shoulder -> wrist in frame 3 is (vx, 0, vz) at q3 = 0: tilt it onto the z axis
        vx, vz = a4 + a5 * c4 - d5 * s4, d3 + a5 * s4 + d5 * c4
        q[1], q[2] = np.arctan2(-vx, vz), 0.0
        if lo[1] <= q[1] <= hi[1]:
            cases.append(q)
    for q6 in (0.0, 1e-7, 1e-4, lo[5]):
        for _ in range(5):
            q = rng.uniform(lo, hi)
            q[5] = q6
            cases.append(q)
    for q5 in (np.pi / 2, -np.pi / 2, np.pi / 2 + 1e-3, -np.pi / 2 - 1e-5):
        for _ in range(5):
            q = rng.uniform(lo, hi)
            q[4] = q5
            cases.append(q)
    return cases


def test_singular_configurations(model):
    rng = np.random.default_rng(2)
    cases = _singular_cases(model, rng)
    assert len(cases) == 70
    for q in cases:
        X_WT = model.tcp_pose(_with_arm(model, "right", q), "right")
        sols = panda_ik(model, "right", X_WT, q[6], near=q)
        _assert_exact(model, "right", X_WT, sols, q7=q[6])
        if abs(abs(q[4]) - np.pi / 2) < 1e-4:  # on the q6 double root: the pose fixes q to
            # the square root of its tolerance
            assert any(np.max(np.abs(s - q)) < 1e-3 for s in sols), q
        else:
            assert _contains(sols, q), q
        # from another seed there are still exact solutions (on the singular continuum)
        assert panda_ik(model, "right", X_WT, q[6])


def test_wrist_on_joint1_axis_case_is_what_it_says(model):
    """The wrist-above-shoulder cases of _singular_cases put joint 6's origin on joint 1's axis
    (to the micrometres by which the model's rounded angles differ from the DH table)."""
    rng = np.random.default_rng(2)
    cases = _singular_cases(model, rng)[20:30]
    plant = model.plant
    ctx = plant.CreateDefaultContext()
    inst = model.arms["right"]
    base = np.array(model.embodiment.base_pose("right").xyz)
    for q in cases:
        plant.SetPositions(ctx, model.full_q(_with_arm(model, "right", q)))
        w = plant.GetBodyByName("link6", inst).EvalPoseInWorld(ctx).translation()
        assert np.hypot(*(w - base)[:2]) < 1e-5
        assert w[2] > base[2] + PANDA_DH[0][1]


def test_near_sweep_sorted_and_exact(model):
    sl = model.side_slice("right")
    home = model.home[sl]
    X_home = model.tcp_pose(model.home, "right")
    sols = panda_ik_near(model, "right", X_home, home)
    assert np.max(np.abs(sols[0] - home)) < 1e-6  # the seed itself comes first
    _assert_exact(model, "right", X_home, sols)
    d = [np.linalg.norm(s - home) for s in sols]
    assert d == sorted(d)
    offsets = {round(float(s[6] - home[6]), 9) for s in sols}
    assert offsets <= {round(o, 9) for o in Q7_OFFSETS} and len(offsets) > 5
    # a target 10 cm from home: solutions near the seed, on more than one q7
    X = RigidTransform(X_home.rotation(), X_home.translation() + [0.05, 0.05, -0.07])
    sols = panda_ik_near(model, "right", X, home)
    _assert_exact(model, "right", X, sols)
    assert len({round(float(s[6]), 9) for s in sols}) > 5
    assert np.linalg.norm(sols[0] - home) < 0.6
    # only the offsets given, and none beyond joint 7's limits
    sols = panda_ik_near(model, "right", X, home, q7_offsets=(0.0,))
    assert sols and all(abs(s[6] - home[6]) < 1e-12 for s in sols)
    at_limit = home.copy()
    at_limit[6] = model.upper[sl][6] - 0.01
    sols = panda_ik_near(model, "right", X, at_limit, q7_offsets=(0.0, 0.5))
    assert all(abs(s[6] - at_limit[6]) < 1e-12 for s in sols)


def test_other_arms_are_refused():
    viperx = PlanningModel(Scene())
    assert not is_panda(viperx)
    with pytest.raises(ValueError, match="not a Panda"):
        panda_ik(viperx, "right", viperx.tcp_pose(viperx.home, "right"), 0.0)
