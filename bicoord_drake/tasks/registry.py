"""The task registry: ``@register_task`` on each task class; ``list_tasks``; ``get_task``."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar, overload

from bicoord_drake.tasks.base import Task, check_task_class

T = TypeVar("T", bound=type[Task])

_TASKS: dict[str, type[Task]] = {}


@overload
def register_task(cls: T) -> T: ...
@overload
def register_task(cls: str) -> Callable[[T], T]: ...


def register_task(cls):
    """Register a :class:`Task` subclass under its ``name``.

    Use bare (``@register_task``) or with the name (``@register_task("jigsaw")``, which must match
    the class attribute if one is set). Rejects duplicates and incomplete task classes.
    """
    if isinstance(cls, str):
        name = cls

        def decorate(task_cls: T) -> T:
            declared = task_cls.__dict__.get("name")
            if declared is None:
                task_cls.name = name
            elif declared != name:
                raise ValueError(
                    f"register_task({name!r}) on {task_cls.__name__} whose name is {declared!r}"
                )
            return register_task(task_cls)

        return decorate
    check_task_class(cls)
    existing = _TASKS.get(cls.name)
    if existing is not None:
        raise ValueError(
            f"task {cls.name!r} is already registered by "
            f"{existing.__module__}.{existing.__qualname__}"
        )
    _TASKS[cls.name] = cls
    return cls


def list_tasks() -> list[str]:
    """Names of every registered task, sorted."""
    return sorted(_TASKS)


def get_task(name: str) -> Task:
    """A fresh instance of the task registered as `name`; ValueError lists the valid names."""
    try:
        return _TASKS[name]()
    except KeyError:
        valid = ", ".join(list_tasks()) or "(none registered)"
        raise ValueError(f"unknown task {name!r}; choose one of: {valid}") from None
