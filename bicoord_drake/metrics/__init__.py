"""BiCoord metrics: coordination (SMT, SMP, MRD, ARD, STI), long-horizon (TL, SN, ON), the
joint-space path length (PL) and evaluation (SR, SSR, TL). Numpy, plus h5py to read episode
files; no Drake.

Example::

    from bicoord_drake.metrics import coordination_metrics
    m = coordination_metrics(left_xyz, right_xyz, left_gripper, right_gripper)
    print(m.smt, m.smp, m.mrd, m.ard, m.sti, m.length)
"""

from bicoord_drake.metrics.coordination import (
    CLOSED_BELOW,
    MOVE_TOL,
    CoordinationMetrics,
    coordination_metrics,
    smp_curve,
)
from bicoord_drake.metrics.evaluation import (
    stage_score,
    stage_success_rate,
    success_rate,
    trajectory_length,
)
from bicoord_drake.metrics.path_length import joint_path_length
from bicoord_drake.metrics.report import (
    DatasetMetrics,
    EpisodeMetrics,
    SummaryRow,
    dataset_metrics,
    episode_metrics,
    format_csv,
    format_table,
    measure_paths,
    plot_sti_curves,
    sti_curves,
    summarize,
)

__all__ = [
    "CLOSED_BELOW",
    "MOVE_TOL",
    "CoordinationMetrics",
    "DatasetMetrics",
    "EpisodeMetrics",
    "SummaryRow",
    "coordination_metrics",
    "dataset_metrics",
    "episode_metrics",
    "format_csv",
    "format_table",
    "joint_path_length",
    "measure_paths",
    "plot_sti_curves",
    "smp_curve",
    "stage_score",
    "stage_success_rate",
    "sti_curves",
    "success_rate",
    "summarize",
    "trajectory_length",
]
