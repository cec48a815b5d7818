"""Closed-form inverse kinematics of the Franka Emika Panda (``franka_pair``), given joint 7.

The Panda has seven joints; a TCP pose fixes six. Fixing joint 7 at ``q7`` (the redundancy)
leaves a 6-joint problem with up to 8 exact solutions: :func:`panda_ik` returns all of them
within the joint limits, each verified by the planning model's forward kinematics, and
:func:`panda_ik_near` sweeps ``q7`` around a seed's and sorts the solutions by their joint
distance to it (IK seeds for the planner).

Derivation (Franka's modified DH table ``PANDA_DH``, frames ``Rx(alpha) Tx(a) Rz(q) Tz(d)``;
``O_i`` is frame i's origin, everything in the arm's base frame ``link0``):

1. Link 6. With q7 fixed, joint 7 and the hand are a fixed transform ``X_6T(q7)`` from
   link 6 to the TCP, so ``X_B6 = X_BT X_6T(q7)^-1``. Its origin is the wrist point
   ``W = O_5 = O_6``; the shoulder ``S = O_1 = O_2`` sits ``d1`` above the base.
2. Elbow (q4). S, the elbow ``O_4`` and W lie in the plane normal to joint 4's axis ``z4``:
   in frame 4, ``O_4 -> W = (a5, d5, 0)`` and ``O_4 -> S = Rz(-q4) (-a4, -d3, 0)``, so
   ``S - W = ex x4 + ey y4`` with ``(ex, ey) = Rz(-q4) (-a4, -d3) - (a5, d5)``, and
   ``|S - W|^2 = a4^2 + d3^2 + a5^2 + d5^2 + 2 (a4 a5 + d3 d5) cos q4 + 2 (a5 d3 - a4 d5)
   sin q4``: two roots.
3. Wrist (q6). The forearm axis ``y4 = z5`` is perpendicular to joint 6's axis: in link 6's
   frame ``z5 = (sin q6, cos q6, 0)``. Projecting ``S - W`` on it gives ey:
   ``(S - W).x6 sin q6 + (S - W).y6 cos q6 = ey`` - two roots.
4. Frame 4. ``x4 = ((S - W) - ey y4) / ex`` (ex > 0 within the limits, where sin q4 < 0),
   ``z4 = x4 x y4``; then ``Rz(q5) = Rx(pi/2) R_B4^T R_B5`` with ``R_B5 = R_B6 (Rx(pi/2)
   Rz(q6))^T``, and ``R_B3 = R_B4 Rz(-q4) Rx(-pi/2) = Rz(q1) Ry(q2) Rz(q3)`` - ZYZ Euler
   angles with two roots (the shoulder: ``(q1, q2, q3)`` or ``(q1 + pi, -q2, q3 + pi)``).

2 x 2 x 2 = 8 branches. Singular cases (nothing raises; a branch failing the final check is
dropped):

- The wrist point on joint 1's axis is no singularity here (q1 comes from frame 3's
  orientation, not from W's azimuth).
- ``sin q2 = 0`` (the upper arm on joint 1's axis): only ``q1 + q3`` counts; q1 is taken from
  ``near`` (shifted if q3 would pass a limit). For ``|sin q2| < 0.01`` that branch is tried
  besides the two exact ones, polished first with q1 kept, so a seed at or near the
  singularity comes back as it is.
- Tangent roots: ``q5 = +-pi/2`` (joint 6's axis in the arm plane: the two q6 roots merge) and
  the arm stretched (the q4 roots). Discriminants up to 1e-4 past 1 (the model's rounding)
  count, and both roots start a few mrad apart; on the exact tangent the answer is good to
  ~1e-4 rad in the joints (the pose error is quadratic there).
- ``q6 = 0`` (joint 5's axis along joint 7's) needs no care once q7 is fixed.

The project's model differs from Franka's table in two ways, both handled by reading the
kinematics from the planning model's own plant rather than from the table. (1) Link 7 and the
hand are one body ``hand`` whose frame G follows the gripper convention: G = link 7's frame
moved 0.107 m along its z (the flange), turned -45 deg about it (the hand mount), then
``R_HAND_G`` (G's x = link 7's z); joint 7 turns G about its x, and the TCP is 0.1034 m along
it. ``X_6T(q7)`` is therefore built from joint 7's plant frames and the ``tcp`` frame, exact
whatever the convention. (2) Its SDFormat writes joint-origin angles to six significant
digits (pi/2 as 1.5708, 3 pi/4 as 2.35619), which moves the TCP by up to ~6 um from the
ideal table. So each analytic branch is polished by a few Gauss-Newton steps on joints 1-6 of
the plant's exact chain (usually one), then checked against :meth:`PlanningModel.tcp_pose`
(position < 1e-6 m, rotation matrix < 1e-6).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.models.franka import PANDA_DH
from bicoord_drake.planning.model import PlanningModel

#: Default q7 offsets (rad) from the seed's q7 swept by :func:`panda_ik_near`.
Q7_OFFSETS: tuple[float, ...] = (
    0.0, -0.05, 0.05, -0.1, 0.1, -0.2, 0.2, -0.35, 0.35, -0.5, 0.5, -0.75, 0.75, -1.0, 1.0,
)  # fmt: skip
#: Acceptance of a solution: TCP position error (m) and rotation-matrix error (Frobenius).
POS_TOL = 1e-6
ROT_TOL = 1e-6
#: Gauss-Newton polish: at most this many steps, stopping below this pose error (m and rad
#: together), each step at most this long (rad, per joint).
POLISH_STEPS = 8
POLISH_TOL = 1e-10
MAX_STEP = 0.2
#: |sin q2| below which only q1 + q3 is determined (q1 is then taken from `near`), and below
#: which the branch with q1 from `near` is tried besides the two exact ones.
SINGULAR_S2 = 1e-9
NEAR_SINGULAR_S2 = 1e-2
#: Near-tangent roots (see :func:`_roots_sin_cos`): the discriminant tolerance beyond 1 (the
#: ideal DH arm vs the model) and the smallest kept gap (in sine: 1e-5 = 4.5 mrad apart).
TANGENT_TOL = 1e-4
TANGENT_GAP = 1e-5
#: Angles (rad) this far beyond a joint limit (polish round-off) are clipped onto it.
LIMIT_SLACK = 1e-8
#: Solutions closer than this (rad, every joint) are one.
DUPLICATE = 1e-6

_D1 = PANDA_DH[0][1]
_D3 = PANDA_DH[2][1]
_A4 = PANDA_DH[3][0]
_A5, _D5 = PANDA_DH[4][0], PANDA_DH[4][1]
#: |S - W|^2 = _C0 + 2 (_CA cos q4 + _CB sin q4)
_C0 = _A4**2 + _D3**2 + _A5**2 + _D5**2
_CA = _A4 * _A5 + _D3 * _D5
_CB = _A5 * _D3 - _A4 * _D5


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _terms(X_PF: np.ndarray, axis: np.ndarray, X_MC: np.ndarray) -> tuple[np.ndarray, ...]:
    """X_PF M X_MC for M = I, K, K^2 (4x4; K the cross-product matrix of `axis`)."""
    K = np.zeros((4, 4))
    K[:3, :3] = [[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]]
    return tuple(X_PF @ M @ X_MC for M in (np.eye(4), K, K @ K))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


_RX_PI_2 = _rx(np.pi / 2)
_RX_MINUS_PI_2 = _rx(-np.pi / 2)


@dataclass(frozen=True)
class _Chain:
    """One arm's exact kinematic chain as the planning model's plant holds it: per joint, the
    joint frame on the parent body (X_PF), the inverse of the one on the child (X_MC), the
    axis; the base in the world and the TCP in the last body. ``terms[i]`` = X_PF (I, K, K^2)
    X_MC with K the axis's cross-product matrix (Rodrigues: R(q) = I + sin q K + (1 - cos q)
    K^2)."""

    X_WB: np.ndarray
    X_PF: tuple[np.ndarray, ...]
    X_MC: tuple[np.ndarray, ...]
    axes: tuple[np.ndarray, ...]
    X_GT: np.ndarray
    terms: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]

    def joint_transform(self, i: int, q: float) -> np.ndarray:
        """Child body i in its parent body at joint angle q."""
        A0, A1, A2 = self.terms[i]
        return A0 + math.sin(q) * A1 + (1.0 - math.cos(q)) * A2

    def fk(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """X_WT (4x4), the world joint axes (7x3) and the joint origins (7x3) at q."""
        X = self.X_WB.copy()
        axes, origins = np.empty((7, 3)), np.empty((7, 3))
        for i in range(7):
            F = X @ self.X_PF[i]
            axes[i], origins[i] = F[:3, :3] @ self.axes[i], F[:3, 3]
            X = X @ self.joint_transform(i, q[i])
        return X @ self.X_GT, axes, origins


_CHAINS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _chain(model: PlanningModel, side: str) -> _Chain:
    per_model = _CHAINS.setdefault(model, {})
    if side not in per_model:
        plant, arm = model.plant, model.embodiment.arm
        inst = model.arms[side]
        joints = [plant.GetJointByName(name, inst) for name in arm.joint_names]
        for prev, joint in zip(joints[:-1], joints[1:], strict=True):
            if joint.parent_body().index() != prev.child_body().index():
                raise ValueError("panda_ik needs a serial chain of 7 revolute joints")
        ctx = plant.CreateDefaultContext()
        X_WB = joints[0].parent_body().EvalPoseInWorld(ctx).GetAsMatrix4()
        if not is_panda(model):
            raise ValueError(f"embodiment {model.embodiment.name!r} is not a Panda")
        tcp = model.tcp_frames[side]
        if tcp.body().index() != joints[-1].child_body().index():
            raise ValueError("the TCP frame must be on joint 7's child body")
        axes = tuple(np.asarray(j.revolute_axis(), float) for j in joints)
        X_PF = tuple(j.frame_on_parent().GetFixedPoseInBodyFrame().GetAsMatrix4() for j in joints)
        X_MC = tuple(
            j.frame_on_child().GetFixedPoseInBodyFrame().inverse().GetAsMatrix4() for j in joints
        )
        per_model[side] = _Chain(
            X_WB=X_WB,
            X_PF=X_PF,
            X_MC=X_MC,
            axes=axes,
            X_GT=tcp.GetFixedPoseInBodyFrame().GetAsMatrix4(),
            terms=tuple(_terms(*t) for t in zip(X_PF, axes, X_MC, strict=True)),
        )
    return per_model[side]


def is_panda(model: PlanningModel) -> bool:
    """Whether the model's arm has the Panda's 7 joints with Franka's DH origins (to 1e-4) on
    joints 1-6, i.e. whether :func:`panda_ik` applies."""
    joints = model.embodiment.arm.joints
    if len(joints) != 7:
        return False
    for j, (a, d, alpha) in zip(joints[:6], PANDA_DH[:6], strict=True):
        xyz = (a, -d * np.sin(alpha), d * np.cos(alpha))
        if not np.allclose(j.origin.xyz, xyz, atol=1e-4):
            return False
        if not np.allclose(j.origin.rpy, (alpha, 0.0, 0.0), atol=1e-4):
            return False
        if not np.allclose(j.axis, (0.0, 0.0, 1.0)):
            return False
    return True


def _roots_sin_cos(a: float, b: float, c: float) -> list[float]:
    """The angles x with a sin x + b cos x = c. Near tangency (|c| / hypot(a, b) beyond
    1 - TANGENT_GAP, up to 1 + TANGENT_TOL) the two roots are kept TANGENT_GAP apart in
    sine: the polish on the exact chain, whose roots may differ by ~1e-3 rad there, starts
    from both sides."""
    r = math.hypot(a, b)
    if r < 1e-12:
        return []
    s = c / r
    if abs(s) > 1.0 + TANGENT_TOL:
        return []
    base = math.asin(min(max(s, -1.0 + TANGENT_GAP), 1.0 - TANGENT_GAP))
    phi = math.atan2(b, a)
    return [base - phi, np.pi - base - phi]


def _zyz(R: np.ndarray, q1_near: float, q3_limits: tuple[float, float]) -> list:
    """[((q1, q2, q3), q1 from near?)] with R = Rz(q1) Ry(q2) Rz(q3): both roots; near
    sin q2 = 0 also the one with q1 = q1_near (only that one at sin q2 = 0, where only q1 + q3
    counts), q1 shifted by what brings q3 within `q3_limits` if it is not."""
    s2 = math.hypot(R[0, 2], R[1, 2])
    out = []
    if s2 >= SINGULAR_S2:
        for sign in (1.0, -1.0):
            q1 = math.atan2(sign * R[1, 2], sign * R[0, 2])
            q3 = math.atan2(sign * R[2, 1], -sign * R[2, 0])
            out.append((np.array([q1, math.atan2(sign * s2, R[2, 2]), q3]), False))
    if s2 < NEAR_SINGULAR_S2:
        N = _rz(-q1_near) @ R  # = Ry(q2) Rz(q3)
        q = np.array([q1_near, np.arctan2(N[0, 2], N[2, 2]), np.arctan2(N[1, 0], N[1, 1])])
        lo, hi = q3_limits[0] + 1e-3, q3_limits[1] - 1e-3
        if not lo <= q[2] <= hi:  # move q3 to its nearer limit (around the circle), q1 back
            above, below = (q[2] - hi) % (2 * np.pi), (lo - q[2]) % (2 * np.pi)
            shift = -above if above < below else below
            q[2] += shift
            q[0] -= shift
        out.append((q, True))
    return out


def _analytic(
    X_B6: np.ndarray, q1_near: float, q3_limits: tuple[float, float]
) -> list[tuple[np.ndarray, bool]]:
    """Joints 1-6 of the ideal DH arm putting link 6 at X_B6 (base frame), up to 8 (plus
    near-singular extras), each with the flag of :func:`_zyz`."""
    R6, W = X_B6[:3, :3], X_B6[:3, 3]
    v = np.array([0.0, 0.0, _D1]) - W  # S - W
    dist2 = float(v @ v)
    sols = []
    for q4 in _roots_sin_cos(2 * _CB, 2 * _CA, dist2 - _C0):
        c4, s4 = math.cos(q4), math.sin(q4)
        ex = -_A4 * c4 - _D3 * s4 - _A5
        ey = _A4 * s4 - _D3 * c4 - _D5
        if abs(ex) < 1e-9:  # S on the forearm axis: not within the joint limits
            continue
        for q6 in _roots_sin_cos(float(v @ R6[:, 0]), float(v @ R6[:, 1]), ey):
            y4 = math.sin(q6) * R6[:, 0] + math.cos(q6) * R6[:, 1]
            x4 = v - ey * y4
            x4 /= math.sqrt(float(x4 @ x4)) * math.copysign(1.0, ex)
            R4 = np.column_stack([x4, y4, _cross(x4, y4)])
            R5 = R6 @ (_RX_PI_2 @ _rz(q6)).T
            M = _RX_PI_2 @ R4.T @ R5
            q5 = math.atan2(M[1, 0], M[0, 0])
            R3 = R4 @ _rz(-q4) @ _RX_MINUS_PI_2
            for q123, fixed in _zyz(R3, q1_near, q3_limits):
                sols.append((np.array([*q123, q4, q5, q6]), fixed))
    return sols


def _rotation_error(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """World-frame rotation vector taking R to R_target (small-angle)."""
    E = R_target @ R.T
    return 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])


def _polish(chain: _Chain, q: np.ndarray, X_WT: np.ndarray, free: slice) -> tuple[np.ndarray, bool]:
    """Gauss-Newton on joints `free` (joint 7 stays) toward X_WT on the exact chain:
    least-squares steps (rank-deficient at sin q2 = 0) of at most MAX_STEP rad; the best
    iterate and whether it is below POLISH_TOL."""
    q = q.copy()
    best, best_err = q.copy(), np.inf
    for k in range(POLISH_STEPS + 1):
        X, axes, origins = chain.fk(q)
        err = np.concatenate([X_WT[:3, 3] - X[:3, 3], _rotation_error(X_WT[:3, :3], X[:3, :3])])
        e = math.sqrt(float(err @ err))
        if e < best_err:
            best, best_err = q.copy(), e
        if e < POLISH_TOL or k == POLISH_STEPS:
            break
        a, r = axes[:6], X[:3, 3] - origins[:6]
        J = np.empty((6, 6))
        J[0] = a[:, 1] * r[:, 2] - a[:, 2] * r[:, 1]  # axis x (TCP - joint origin)
        J[1] = a[:, 2] * r[:, 0] - a[:, 0] * r[:, 2]
        J[2] = a[:, 0] * r[:, 1] - a[:, 1] * r[:, 0]
        J[3:] = a.T
        dq = np.linalg.lstsq(J[:, free], err, rcond=1e-10)[0]
        q[free] += dq * min(1.0, MAX_STEP / max(float(np.max(np.abs(dq))), 1e-300))
    return best, best_err < POLISH_TOL


def _wrap(q: np.ndarray, lower: np.ndarray, upper: np.ndarray, near: np.ndarray):
    """Each angle shifted by multiples of 2 pi into [lower, upper] (clipped when beyond by at
    most LIMIT_SLACK), nearest `near`; None if some angle has no such representative."""
    k_lo = np.ceil((lower - LIMIT_SLACK - q) / (2 * np.pi))
    k_hi = np.floor((upper + LIMIT_SLACK - q) / (2 * np.pi))
    if np.any(k_lo > k_hi):
        return None
    k = np.clip(np.round((near - q) / (2 * np.pi)), k_lo, k_hi)
    return np.clip(q + 2 * np.pi * k, lower, upper)


def panda_ik(
    model: PlanningModel,
    side: str,
    X_WT: RigidTransform,
    q7: float,
    near: np.ndarray | None = None,
) -> list[np.ndarray]:
    """Every exact solution (7 joints, up to 8 branches) putting the TCP of `side` at X_WT
    with joint 7 at `q7`: within the joint limits, angles wrapped nearest `near` (default:
    home), each verified by :meth:`PlanningModel.tcp_pose`. Empty when unreachable.
    ValueError if the model's arm is not a Panda (:func:`is_panda`)."""
    sl = model.side_slice(side)
    lower, upper = model.lower[sl], model.upper[sl]
    near = model.home[sl] if near is None else np.asarray(near, dtype=float)
    chain = _chain(model, side)
    T = X_WT.GetAsMatrix4()
    X_BT = np.linalg.solve(chain.X_WB, T)
    X_6T = chain.joint_transform(6, q7) @ chain.X_GT
    X_B6 = X_BT @ np.linalg.inv(X_6T)
    q_both = model.home.copy()
    out: list[np.ndarray] = []
    for q16, q1_from_near in _analytic(X_B6, float(near[0]), (lower[2], upper[2])):
        q = np.append(q16, q7)
        # the polish moves joints by ~1e-5 rad: skip branches clearly beyond the limits
        if not np.all(np.mod(q - lower + 1e-3, 2 * np.pi) <= upper - lower + 2e-3):
            continue
        done = False
        if q1_from_near:  # keep q1 if the other joints can make up (exactly so at q2 = 0)
            q, done = _polish(chain, q, T, slice(1, 6))
        if not done:
            q, _ = _polish(chain, q, T, slice(0, 6))
        q = _wrap(q, lower, upper, near)
        if q is None or any(np.max(np.abs(q - p)) < DUPLICATE for p in out):
            continue
        q_both[sl] = q
        X = model.tcp_pose(q_both, side)
        if (
            np.linalg.norm(X.translation() - T[:3, 3]) < POS_TOL
            and np.linalg.norm(X.rotation().matrix() - T[:3, :3]) < ROT_TOL
        ):
            out.append(q)
    return out


def panda_ik_near(
    model: PlanningModel,
    side: str,
    X_WT: RigidTransform,
    seed: np.ndarray,
    q7_offsets: Sequence[float] = Q7_OFFSETS,
) -> list[np.ndarray]:
    """The solutions of :func:`panda_ik` for q7 = seed's q7 + each offset (those within the
    limits), wrapped nearest `seed` (the arm's 7 joints), sorted by joint distance to it."""
    seed = np.asarray(seed, dtype=float)
    sl = model.side_slice(side)
    lo, hi = model.lower[sl][6], model.upper[sl][6]
    sols = []
    for off in q7_offsets:
        q7 = seed[6] + off
        if lo <= q7 <= hi:
            sols.extend(panda_ik(model, side, X_WT, q7, near=seed))
    return sorted(sols, key=lambda q: float(np.linalg.norm(q - seed)))
