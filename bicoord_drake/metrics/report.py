"""Dataset-level coordination and long-horizon metrics: tables (Markdown, CSV, JSON) and STI curves.

Dataset level (PRODUCT.md): every metric is the mean of the per-trajectory values (SMP is the mean
of per-trajectory SMPs, not SMT / TL); TL = mean length, SN = mean stage count, ON = mean object
count; PL = mean joint-space path length in radians (:mod:`bicoord_drake.metrics.path_length`;
not in the paper's table). "overall" pools every trajectory, so tasks weigh by their number of
episodes. SN (ON, PL) of a group is ``None`` unless every trajectory in it knows its stages
(objects, joint positions).
"""

from __future__ import annotations

import io
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from bicoord_drake.data.readers import read_trajectories
from bicoord_drake.data.trajectory import Trajectory
from bicoord_drake.metrics.coordination import (
    CLOSED_BELOW,
    MOVE_TOL,
    CoordinationMetrics,
    coordination_metrics,
    smp_curve,
)
from bicoord_drake.metrics.path_length import joint_path_length

COLUMNS = ("SMT", "SMP", "MRD", "ARD", "STI", "TL", "SN", "ON")
"""The paper's Table 1 columns."""
TABLE_COLUMNS = (*COLUMNS, "PL")
"""The printed columns: Table 1's and the joint-space path length PL (rad)."""
PERCENT_COLUMNS = ("SMP", "MRD", "ARD", "STI")
_PAPER = {
    "RLBench2": (179, 97.10, 54.57, 114.93, 11.20, 186, 1.61, 2.23),
    "RoboTwin 2.0": (60, 26.10, 63.83, 82.37, 8.13, 221, 1.64, 2.02),
    "BiCoord": (329, 92.81, 29.59, 55.77, 42.16, 361, 4.27, 3.66),
}
PAPER_TABLE1 = {name: dict(zip(COLUMNS, row, strict=True)) for name, row in _PAPER.items()}
"""The paper's Table 1 (dataset means; SMP, MRD, ARD, STI in percent), for comparison."""


class TrajectoryLike(Protocol):
    """What the dataset functions read from a trajectory (e.g. a :class:`Trajectory`)."""

    source: str
    task: str
    left_xyz: np.ndarray
    right_xyz: np.ndarray
    left_gripper: np.ndarray
    right_gripper: np.ndarray
    n_stages: int | None
    n_objects: int | None


@dataclass(frozen=True)
class EpisodeMetrics:
    """Metrics of one trajectory with its task and long-horizon counts."""

    source: str
    task: str
    coordination: CoordinationMetrics
    n_stages: int | None
    n_objects: int | None
    path_length: float | None = None
    """Joint-space path length (rad), ``None`` when the trajectory has no joint positions."""


@dataclass(frozen=True)
class SummaryRow:
    """Means over a group of trajectories; SMP, MRD, ARD, STI as fractions."""

    n: int
    smt: float
    smp: float
    mrd: float
    ard: float
    sti: float
    tl: float
    sn: float | None
    on: float | None
    pl: float | None = None

    def as_dict(self, percent: bool = True) -> dict[str, float | None]:
        """``{"SMT", "SMP", "MRD", "ARD", "STI", "TL", "SN", "ON", "PL"}``; percent for
        SMP..STI."""
        values = (
            *(self.smt, self.smp, self.mrd, self.ard, self.sti),
            *(self.tl, self.sn, self.on, self.pl),
        )
        out = dict(zip(TABLE_COLUMNS, values, strict=True))
        if percent:
            for key in PERCENT_COLUMNS:
                out[key] = 100.0 * out[key]
        return out


@dataclass(frozen=True)
class DatasetMetrics:
    """Per-task and overall summaries plus the per-episode values they come from."""

    per_task: dict[str, SummaryRow]
    overall: SummaryRow
    episodes: tuple[EpisodeMetrics, ...]

    def to_json_dict(self) -> dict:
        """``{"per_task": {task: row}, "overall": row}`` with percent SMP, MRD, ARD, STI."""
        return {
            "per_task": {task: row.as_dict() for task, row in self.per_task.items()},
            "overall": self.overall.as_dict(),
        }


def episode_metrics(
    trajectory: TrajectoryLike,
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
) -> EpisodeMetrics:
    """Coordination metrics of one trajectory; a ``ValueError`` names its source."""
    try:
        coordination = coordination_metrics(
            trajectory.left_xyz,
            trajectory.right_xyz,
            trajectory.left_gripper,
            trajectory.right_gripper,
            move_tol=move_tol,
            closed_below=closed_below,
        )
        left_q = getattr(trajectory, "left_q", None)
        right_q = getattr(trajectory, "right_q", None)
        path_length = (
            None if left_q is None or right_q is None else joint_path_length(left_q, right_q)
        )
    except ValueError as exc:
        raise ValueError(f"{trajectory.source}: {exc}") from None
    return EpisodeMetrics(
        source=trajectory.source,
        task=trajectory.task,
        coordination=coordination,
        n_stages=trajectory.n_stages,
        n_objects=trajectory.n_objects,
        path_length=path_length,
    )


def _mean_or_none(values: list[float | None]) -> float | None:
    if any(v is None for v in values):
        return None
    return float(np.mean(values))


def _summary(episodes: Sequence[EpisodeMetrics]) -> SummaryRow:
    table = np.array(
        [(c.smt, c.smp, c.mrd, c.ard, c.sti, c.length) for c in (e.coordination for e in episodes)],
        dtype=np.float64,
    )
    smt, smp, mrd, ard, sti, tl = table.mean(axis=0)
    return SummaryRow(
        n=len(episodes),
        smt=float(smt),
        smp=float(smp),
        mrd=float(mrd),
        ard=float(ard),
        sti=float(sti),
        tl=float(tl),
        sn=_mean_or_none([e.n_stages for e in episodes]),
        on=_mean_or_none([e.n_objects for e in episodes]),
        pl=_mean_or_none([e.path_length for e in episodes]),
    )


def summarize(episodes: Sequence[EpisodeMetrics]) -> DatasetMetrics:
    """Per-task (sorted by name) and overall means of per-episode metrics."""
    if not episodes:
        raise ValueError("no trajectories to summarize")
    by_task: dict[str, list[EpisodeMetrics]] = {}
    for episode in episodes:
        by_task.setdefault(episode.task, []).append(episode)
    return DatasetMetrics(
        per_task={task: _summary(by_task[task]) for task in sorted(by_task)},
        overall=_summary(episodes),
        episodes=tuple(episodes),
    )


def dataset_metrics(
    trajectories: Iterable[TrajectoryLike],
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
) -> DatasetMetrics:
    """Table 1 metrics per task and overall for trajectories carrying a ``task`` name.

    Raises ``ValueError`` (naming the trajectory's source) on the first bad trajectory or when
    there is none.
    """
    return summarize(
        [episode_metrics(t, move_tol=move_tol, closed_below=closed_below) for t in trajectories]
    )


def measure_paths(
    paths: Iterable[str | Path],
    format: str = "auto",
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
) -> tuple[DatasetMetrics | None, list[Trajectory], list[str]]:
    """Read and measure every episode under ``paths``, skipping bad files.

    Returns the metrics of the good trajectories (``None`` if there is none), those trajectories,
    and one error line per bad path or file.
    """
    trajectories, errors = read_trajectories(paths, format)
    good, episodes = [], []
    for trajectory in trajectories:
        try:
            episodes.append(
                episode_metrics(trajectory, move_tol=move_tol, closed_below=closed_below)
            )
        except ValueError as exc:
            errors.append(str(exc))
        else:
            good.append(trajectory)
    return (summarize(episodes) if episodes else None), good, errors


def _cell(key: str, value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.1f}" if key in ("SMT", "TL") else f"{value:.2f}"


def _rows(metrics: DatasetMetrics) -> list[tuple[str, SummaryRow]]:
    return [*metrics.per_task.items(), ("overall", metrics.overall)]


def format_table(metrics: DatasetMetrics) -> str:
    """A Markdown table like the paper's Table 1 (percent for SMP, MRD, ARD, STI), plus PL (rad)."""
    header = ["Task", "N", *(f"{c} %" if c in PERCENT_COLUMNS else c for c in TABLE_COLUMNS)]
    lines = [
        "| " + " | ".join(header) + " |",
        "|" + "---|" + "---:|" * (len(header) - 1),
    ]
    for name, row in _rows(metrics):
        cells = [_cell(k, v) for k, v in row.as_dict().items()]
        lines.append("| " + " | ".join([name, str(row.n), *cells]) + " |")
    return "\n".join(lines)


def format_csv(metrics: DatasetMetrics) -> str:
    """The same table as CSV (percent for SMP, MRD, ARD, STI; empty where unknown)."""
    out = io.StringIO()
    out.write(",".join(["task", "n", *TABLE_COLUMNS]) + "\n")
    for name, row in _rows(metrics):
        cells = ["" if v is None else repr(float(v)) for v in row.as_dict().values()]
        out.write(",".join([name, str(row.n), *cells]) + "\n")
    return out.getvalue()


def sti_curves(
    trajectories: Iterable[TrajectoryLike],
    d: np.ndarray,
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
) -> dict[str, np.ndarray]:
    """Per task, the mean over its trajectories of ``SMP_<(1-d)`` at each d (the STI curve)."""
    thresholds = 1.0 - np.asarray(d, dtype=np.float64)
    sums: dict[str, np.ndarray] = {}
    counts: dict[str, int] = {}
    for t in trajectories:
        curve = smp_curve(
            t.left_xyz,
            t.right_xyz,
            t.left_gripper,
            t.right_gripper,
            thresholds,
            move_tol=move_tol,
            closed_below=closed_below,
        )
        sums[t.task] = sums.get(t.task, 0.0) + curve
        counts[t.task] = counts.get(t.task, 0) + 1
    return {task: sums[task] / counts[task] for task in sorted(sums)}


def plot_sti_curves(
    trajectories: Sequence[TrajectoryLike],
    out_path: str | Path,
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
    points: int = 201,
) -> Path:
    """Draw ``SMP_<(1-d)`` against d, one curve per task (plus "overall"), like the paper's Fig. 2.

    The area under each curve is the group's STI (shown, computed exactly, in the legend). Uses
    the Agg canvas; no display needed.
    """
    from matplotlib.figure import Figure

    tol = {"move_tol": move_tol, "closed_below": closed_below}
    d = np.linspace(0.0, 1.0, points)
    curves = sti_curves(trajectories, d, **tol)
    metrics = dataset_metrics(trajectories, **tol)
    rows = dict(metrics.per_task)
    if len(curves) > 1:
        curves["overall"] = sum(curves[task] * rows[task].n for task in rows) / metrics.overall.n
        rows["overall"] = metrics.overall

    fig = Figure(figsize=(5.0, 4.0), layout="constrained")
    ax = fig.add_subplot()
    for task, curve in curves.items():
        style = {"color": "black", "linestyle": "--"} if task == "overall" else {}
        label = f"{task} (STI {100.0 * rows[task].sti:.1f}%)"
        ax.plot(d, 100.0 * curve, label=label, **style)
    ax.set_xlabel("d")
    ax.set_ylabel(r"SMP$_{<1-d}$ (%)")
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 100.0)
    ax.set_title("STI curves")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    out_path = Path(out_path)
    fig.savefig(out_path, dpi=120)
    return out_path
