"""Planning: bimanual IK, collision-free motion, ruckig timing and throws, grasps, skills."""

from bicoord_drake.planning.errors import PlanningError

__all__ = ["PlanningError"]
