"""Task stages: sub-goals with named predicates, monitored every control step.

The same predicates annotate demonstrations (frame ranges), score rollouts (SSR) and decide
success, so labels and scores can never disagree.
"""

from bicoord_drake.data.stage_rows import check_rows, stage_index_from_rows
from bicoord_drake.metrics.evaluation import stage_score
from bicoord_drake.stages import predicates
from bicoord_drake.stages.monitor import StageMonitor
from bicoord_drake.stages.stage import (
    Stage,
    StageKind,
    WorldState,
    resolve_dependencies,
)

__all__ = [
    "Stage",
    "StageKind",
    "StageMonitor",
    "WorldState",
    "check_rows",
    "predicates",
    "resolve_dependencies",
    "stage_index_from_rows",
    "stage_score",
]
