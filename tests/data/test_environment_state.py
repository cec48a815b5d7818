"""The environment-state layout: names, positional slots, the order check."""

import numpy as np
import pytest

from bicoord_drake.data.environment_state import (
    environment_state,
    feature_names,
    layout_names,
    mismatch,
    objects_of,
    positional,
    state_objects,
)
from bicoord_drake.models.scene import demo_scene


def test_names_and_values_follow_the_scene_order():
    scene = demo_scene("demo")
    objects = state_objects(scene)
    assert objects == ("red_cube", "green_cube", "blue_cube", "bowl")
    randomized = scene.model_copy(update={"seed": 3}).randomized("seen")
    assert randomized.distractors and state_objects(randomized) == objects
    names = feature_names(objects)
    assert names[:8] == [
        "red_cube_x",
        "red_cube_y",
        "red_cube_z",
        "red_cube_qw",
        "red_cube_qx",
        "red_cube_qy",
        "red_cube_qz",
        "green_cube_x",
    ]
    assert objects_of(names) == objects
    poses = {n: np.arange(7.0) + 10 * i for i, n in enumerate(reversed(objects))}
    state = environment_state(poses, objects)
    assert state.shape == (28,) and state[0] == 30.0 and state[-7] == 0.0
    with pytest.raises(ValueError, match=r"no pose for \['bowl'\]"):
        environment_state({n: poses[n] for n in objects[:3]}, objects)
    with pytest.raises(ValueError, match="7 per object"):
        objects_of(names[:-1])


def test_varying_names_give_a_positional_layout():
    assert layout_names([("a", "b"), ("a", "b")]) == feature_names(("a", "b"))
    assert layout_names([("a", "b"), ("a", "c")]) == feature_names(("object_0", "object_1"))
    with pytest.raises(ValueError, match="different numbers"):
        layout_names([("a", "b"), ("a",)])
    assert mismatch(("a", "b"), ("a", "b")) is None
    assert "same objects in another order" in mismatch(("a", "b"), ("b", "a"))
    assert "missing ['b'], unexpected ['c']" in mismatch(("a", "b"), ("a", "c"))
    assert mismatch(positional(2), ("x", "y")) is None
    assert "2 objects expected" in mismatch(positional(2), ("x",))
