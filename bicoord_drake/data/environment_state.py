"""The privileged ``observation.environment_state`` feature: the task objects' poses.

One definition, used by the LeRobot export (from an episode file's ``objects/<name>/pose``), by
the environments (from the live simulation's object poses, the same output port the recorder
reads) and by the LeRobot policy adapter (to check a checkpoint's layout)::

    [obj_1 x, y, z, qw, qx, qy, qz, obj_2 x, ..., obj_K qz]     (7 K,)

The objects are the scene's task objects in the scene's own order (:func:`state_objects`:
fixtures and movable objects as the task declares them; randomization's distractors left out).
Position in metres, world frame; quaternion wxyz as Drake gives it. The feature's names
(``<object>_<field>``, :func:`feature_names`) are stored in the export's ``meta/info.json`` and
checked against the environment's scene at evaluation (:func:`mismatch`).

Every task but one names the same objects for every seed. jigsaw names its cubes after the
cells they belong in, which depend on the seed (the same count, 18 objects, in the same roles
by position); an export whose episodes name different objects therefore names the slots by
position, ``object_<i>_<field>`` (:func:`layout_names`), and then only the count is checked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from bicoord_drake.models.scene import Scene

ENVIRONMENT_STATE = "observation.environment_state"
#: The fields of one object's pose, in order.
POSE_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz")
POSE_SIZE = len(POSE_FIELDS)


def state_objects(scene: Scene) -> tuple[str, ...]:
    """The objects whose poses make the environment state: the scene's objects in scene order,
    distractors left out."""
    return tuple(o.name for o in scene.objects if not o.distractor)


def feature_names(objects: Sequence[str]) -> list[str]:
    """``<object>_<field>`` for every object and pose field, in the state's order."""
    return [f"{name}_{field}" for name in objects for field in POSE_FIELDS]


def positional(count: int) -> tuple[str, ...]:
    """``object_0 .. object_<count-1>``: the slot names of a layout whose objects' names vary."""
    return tuple(f"object_{i}" for i in range(count))


def layout_names(object_lists: Sequence[Sequence[str]]) -> list[str]:
    """The feature names of a dataset whose episodes have `object_lists`: the objects' names if
    every episode has the same, else positional ones (:func:`positional`); ValueError if the
    counts differ."""
    first = tuple(object_lists[0])
    if all(tuple(o) == first for o in object_lists):
        return feature_names(first)
    counts = sorted({len(o) for o in object_lists})
    if len(counts) > 1:
        raise ValueError(f"the episodes have different numbers of task objects: {counts}")
    return feature_names(positional(len(first)))


def mismatch(trained: Sequence[str], objects: Sequence[str]) -> str | None:
    """Why an environment state of `objects` does not fit a layout of `trained` objects (None
    if it fits): the same objects in the same order, or, for a positional layout, as many."""
    trained, objects = tuple(trained), tuple(objects)
    if trained == positional(len(trained)):
        if len(objects) == len(trained):
            return None
        return f"{len(trained)} objects expected, the scene has {len(objects)} ({list(objects)})"
    return None if objects == trained else describe_mismatch(trained, objects)


def objects_of(names: Sequence[str]) -> tuple[str, ...]:
    """The objects of a feature-name list (the inverse of :func:`feature_names`); ValueError
    if the list is not such a layout."""
    if len(names) % POSE_SIZE:
        raise ValueError(f"{len(names)} names are not {POSE_SIZE} per object")
    objects = tuple(str(n).rsplit("_", 1)[0] for n in names[::POSE_SIZE])
    if list(names) != feature_names(objects):
        raise ValueError(f"not an environment-state layout: {list(names)[:POSE_SIZE]} ...")
    return objects


def environment_state(
    poses: Mapping[str, Any], objects: Sequence[str], dtype: Any = np.float64
) -> np.ndarray:
    """The (7 K,) state of `objects` from their poses (name -> xyz + wxyz); ValueError naming
    the objects `poses` lacks."""
    missing = [name for name in objects if name not in poses]
    if missing:
        raise ValueError(
            f"no pose for {missing} (the poses are of {sorted(poses)}): the environment state "
            f"of this scene has other objects than {list(objects)}"
        )
    if not objects:
        return np.zeros(0, dtype=dtype)
    return np.concatenate(
        [np.asarray(poses[n], dtype=float).reshape(POSE_SIZE) for n in objects]
    ).astype(dtype)


def describe_mismatch(want: Sequence[str], got: Sequence[str]) -> str:
    """What differs between two object lists (for error messages)."""
    if sorted(want) == sorted(got):
        return f"the same objects in another order: {list(want)} vs {list(got)}"
    lacks = [n for n in want if n not in got]
    extra = [n for n in got if n not in want]
    return f"missing {lacks}, unexpected {extra} (expected {list(want)}, got {list(got)})"
