"""The benchmark tasks, one per module, each registered with ``@register_task``.

To add a task, write ``bicoord_drake/tasks/<name>.py`` and add ``"<name>"`` to ``TASK_MODULES``.
"""

from importlib import import_module

from bicoord_drake.tasks.base import Task, WorldView
from bicoord_drake.tasks.registry import get_task, list_tasks, register_task

#: Task modules imported (and so registered) with this package.
TASK_MODULES: tuple[str, ...] = (
    "balance_roller",
    "build_bridge",
    "build_tower_with_blocks",
    "clean_table",
    "collect_pens",
    "cook",
    "divide_block_tower",
    "exchange_mics",
    "exchange_pots",
    "extract_bottom_block_to_top",
    "fetch_block_with_roller",
    "handover_block_with_bowls",
    "jigsaw",
    "match_blocks_with_signs",
    "place_plate_and_cup",
    "put_objects_cabinet",
    "stack_bowls",
    "sweep_block",
)

for _module in TASK_MODULES:
    import_module(f"{__name__}.{_module}")

__all__ = ["TASK_MODULES", "Task", "WorldView", "get_task", "list_tasks", "register_task"]
