"""Figures of the dataset report as PNG bytes (matplotlib's Agg canvas; no display)."""

from __future__ import annotations

import io
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bicoord_drake.metrics.coordination import CLOSED_BELOW, MOVE_TOL, arm_acting
from bicoord_drake.metrics.report import TrajectoryLike, plot_sti_curves

ARM_COLOURS = {
    "both": "#7b3294",
    "left": "#2b83ba",
    "right": "#fdae61",
    "neither": "#bababa",
}
"""Stage bar colours by which arm works during the stage."""
RECOVERY_COLOUR = "#d7191c"
"""The colour of a disturbance's recovery segment on a stage timeline."""


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def sti_png(trajectories: Sequence[TrajectoryLike]) -> bytes:
    """The STI curves (``metrics.report.plot_sti_curves``: one panel per movement test, the
    paper's and the jitter-free one) as PNG bytes."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sti.png"
        plot_sti_curves(trajectories, path)
        return path.read_bytes()


def length_histogram_png(lengths_by_task: dict[str, Sequence[int]]) -> bytes:
    """Episode lengths (frames), one stacked colour per task."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    fig = Figure(figsize=(5.0, 3.2), layout="constrained")
    ax = fig.add_subplot()
    everything = np.concatenate([np.asarray(v, dtype=float) for v in lengths_by_task.values()])
    lo, hi = float(everything.min()), float(everything.max())
    pad = max(5.0, 0.05 * (hi - lo))  # a few equal lengths still get a readable axis
    bins = np.histogram_bin_edges(everything, bins=20, range=(lo - pad, hi + pad))
    ax.hist(
        [np.asarray(v) for v in lengths_by_task.values()],
        bins=bins,
        stacked=True,
        label=list(lengths_by_task),
    )
    ax.set_xlabel("episode length (frames)")
    ax.set_ylabel("episodes")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title("Episode lengths")
    ax.legend(fontsize="small")
    ax.grid(alpha=0.3)
    return _png(fig)


def arm_states(
    left_xyz: np.ndarray,
    right_xyz: np.ndarray,
    left_gripper: np.ndarray,
    right_gripper: np.ndarray,
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
) -> np.ndarray:
    """Per frame, which arm works: "both", "left", "right" or "neither" (an arm works when it
    acts as in SMT: it moved more than ``move_tol`` since the previous frame, by default the
    jitter-free test, 0 for the paper's, or holds its gripper closed)."""
    tol = {"move_tol": move_tol, "closed_below": closed_below}
    left = arm_acting(left_xyz, left_gripper, **tol)
    right = arm_acting(right_xyz, right_gripper, **tol)
    names = np.array(["neither", "right", "left", "both"])
    return names[2 * left.astype(int) + right.astype(int)]


def _runs(states: np.ndarray, start: int, end: int) -> list[tuple[int, int, str]]:
    """Maximal runs ``(first, stop, state)`` of equal states in ``states[start:end]``."""
    runs, first = [], start
    for t in range(start + 1, end + 1):
        if t == end or states[t] != states[first]:
            runs.append((first, t, str(states[first])))
            first = t
    return runs


def timeline_png(
    title: str,
    rows: Sequence[Sequence],
    states: np.ndarray,
    test: str | None = None,
    recovery: Sequence[Sequence] = (),
) -> bytes:
    """One horizontal bar per stage over its frames ``[start, end)``; along the bar, the colour
    says which arm works at each frame (``states`` from :func:`arm_states`, under the movement
    test named ``test``, shown in the legend). Each row of `recovery` (a disturbance and the
    expert's recovery from it, ``stages/recovery``: start, end, subgoal, ...) is a bar of its
    own below the stages, hatched, with its frames shaded across the stage bars."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    bars = [*rows, *recovery]
    height = 1.0 + 0.32 * len(bars)
    fig = Figure(figsize=(8.0, height), layout="constrained")
    ax = fig.add_subplot()
    for k, (start, end, *_) in enumerate(rows):
        for first, stop, state in _runs(states, int(start), int(end)):
            ax.barh(k, stop - first, left=first, height=0.7, color=ARM_COLOURS[state], lw=0)
        ax.barh(k, end - start, left=start, height=0.7, fill=False, edgecolor="#333", lw=0.6)
    for k, (start, end, *_) in enumerate(recovery, start=len(rows)):
        ax.axvspan(int(start), int(end), color=RECOVERY_COLOUR, alpha=0.15, lw=0)
        ax.barh(
            k, int(end) - int(start), left=int(start), height=0.7, color="white",
            edgecolor=RECOVERY_COLOUR, hatch="///", lw=0.8,
        )  # fmt: skip
    ax.set_yticks(range(len(bars)), [str(r[2]) for r in bars], fontsize="small")
    ax.invert_yaxis()
    ax.set_xlim(0, max(int(r[1]) for r in bars))
    ax.set_xlabel("frame")
    ax.set_title(title, fontsize="medium")
    ax.grid(axis="x", alpha=0.3)
    handles = [Patch(color=c, label=a) for a, c in ARM_COLOURS.items()]
    if recovery:
        handles.append(
            Patch(facecolor="white", edgecolor=RECOVERY_COLOUR, hatch="///", label="recovery")
        )
    ax.legend(
        handles=handles,
        fontsize="x-small",
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        title="arm working" if test is None else f"arm working\n({test} test)",
        title_fontsize="x-small",
    )
    return _png(fig)
