"""Planning: bimanual IK, collision-free motion, ruckig timing, grasps and skills."""

from bicoord_drake.planning.errors import PlanningError

__all__ = ["PlanningError"]
