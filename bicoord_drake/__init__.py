"""bicoord-drake: the BiCoord bimanual manipulation benchmark on Drake.

Subpackages: ``models`` (robot, objects, scenes), ``sim`` (station, cameras, stepping),
``planning`` (IK, motion, timing, grasps, skills), ``metrics`` (coordination and evaluation
metrics; no Drake), ``data`` (episode files and readers).
"""

from bicoord_drake import metrics

__version__ = "0.1.0"

__all__ = ["metrics", "__version__"]
