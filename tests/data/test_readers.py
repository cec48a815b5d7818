"""Readers for our, RoboTwin 2.0 and BiCoord episode layouts; fixture files are made in tmp_path."""

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from bicoord_drake.data.readers import (
    detect_format,
    find_episode_files,
    read_trajectories,
    read_trajectory,
    task_from_path,
)

T = 10
QUAT = np.tile([1.0, 0.0, 0.0, 0.0], (T, 1))


def signals():
    s = np.linspace(0.0, 1.0, T)[:, None]
    left = [-0.3, 0.5, 0.9] + s * [0.2, 0.0, 0.0]
    right = [0.3, 0.5, 0.9] - s * [0.2, 0.0, 0.0]
    left_grip = np.where(s[:, 0] > 0.5, 0.0, 1.0)
    return left, right, left_grip, left_grip[::-1].copy()


def write(path: Path, datasets: dict, attrs: dict | None = None) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as f:
        for key, value in datasets.items():
            f.create_dataset(key, data=value)
        f.attrs.update(attrs or {})
    return path


def robotwin_datasets() -> dict:
    left, right, lg, rg = signals()
    return {
        "endpose/left_endpose": np.hstack([left, QUAT]),
        "endpose/right_endpose": np.hstack([right, QUAT]),
        "joint_action/left_gripper": lg,
        "joint_action/right_gripper": rg,
    }


def ours_datasets() -> dict:
    strings = h5py.string_dtype()
    return {
        **robotwin_datasets(),
        "stages/start": np.array([0, 4, 7]),
        "stages/end": np.array([4, 7, T]),
        "stages/score": np.array([0.3, 0.3, 0.4]),
        "stages/subgoal": np.array(["grasp", "handover", "place"], dtype=strings),
        "objects/cube/pose": np.tile([0.0, 0.5, 0.8, 1, 0, 0, 0], (T, 1)),
        "objects/bin/pose": np.tile([0.2, 0.5, 0.8, 1, 0, 0, 0], (T, 1)),
    }


OURS_ATTRS = {"task": "handover_cube", "schema_version": "1.0", "object_count": 2, "success": True}


def bicoord_endpose() -> np.ndarray:
    left, right, lg, rg = signals()
    rpy = np.zeros((T, 3))
    return np.hstack([left, rpy, lg[:, None], right, rpy, rg[:, None]])


def test_reads_our_layout(tmp_path):
    path = write(tmp_path / "x" / "episode0.hdf5", ours_datasets(), OURS_ATTRS)
    assert detect_format(path) == "bicoord_drake"
    traj = read_trajectory(path)
    left, right, lg, rg = signals()
    assert (traj.layout, traj.task, traj.source) == ("bicoord_drake", "handover_cube", str(path))
    assert (traj.n_stages, traj.n_objects, traj.success, traj.length) == (3, 2, True, T)
    np.testing.assert_array_equal(traj.left_xyz, left)
    np.testing.assert_array_equal(traj.right_xyz, right)
    np.testing.assert_array_equal(traj.left_gripper, lg)
    np.testing.assert_array_equal(traj.right_gripper, rg)


def test_our_layout_counts_objects_without_the_attribute(tmp_path):
    attrs = {"task": "handover_cube", "schema_version": 1}
    traj = read_trajectory(write(tmp_path / "e.hdf5", ours_datasets(), attrs))
    assert (traj.n_objects, traj.success) == (2, None)


def test_our_layout_rejects_another_schema_major(tmp_path):
    path = write(tmp_path / "e.hdf5", ours_datasets(), {**OURS_ATTRS, "schema_version": "2.0"})
    with pytest.raises(ValueError, match=r"e\.hdf5: root attribute 'schema_version' is '2\.0'"):
        read_trajectory(path)


def test_our_layout_rejects_a_bad_object_count(tmp_path):
    path = write(tmp_path / "e.hdf5", ours_datasets(), {**OURS_ATTRS, "object_count": 2.5})
    with pytest.raises(ValueError, match=r"e\.hdf5: root attribute 'object_count' must be"):
        read_trajectory(path)


def test_reads_robotwin_layout_and_task_from_directories(tmp_path):
    path = write(
        tmp_path / "stack_bowls" / "demo_clean" / "data" / "episode3.hdf5", robotwin_datasets()
    )
    assert detect_format(path) == "robotwin"
    traj = read_trajectory(path)
    assert (traj.task, traj.n_stages, traj.n_objects, traj.success) == (
        "stack_bowls",
        None,
        None,
        None,
    )
    np.testing.assert_array_equal(traj.left_xyz, signals()[0])


def test_reads_bicoord_layout_with_stage_sidecar(tmp_path):
    config = tmp_path / "pour_water" / "demo"
    path = write(config / "data" / "episode0.hdf5", {"endpose": bicoord_endpose()})
    assert detect_format(path) == "bicoord"
    assert read_trajectory(path).n_stages is None
    rows = [[0, 4, "grasp", "grasp cup", "hold", 0.5], [4, T, "pour", "pour", "hold", 0.5]]
    (config / "stages").mkdir()
    (config / "stages" / "episode0.json").write_text(json.dumps(rows))
    traj = read_trajectory(path)
    left, right, lg, rg = signals()
    assert (traj.layout, traj.task, traj.n_stages, traj.n_objects) == (
        "bicoord",
        "pour_water",
        2,
        None,
    )
    np.testing.assert_array_equal(traj.left_xyz, left)
    np.testing.assert_array_equal(traj.right_xyz, right)
    np.testing.assert_array_equal(traj.left_gripper, lg)
    np.testing.assert_array_equal(traj.right_gripper, rg)


def test_bad_stage_sidecar_names_the_json(tmp_path):
    path = write(tmp_path / "t" / "data" / "episode0.hdf5", {"endpose": bicoord_endpose()})
    (tmp_path / "t" / "stages").mkdir()
    (tmp_path / "t" / "stages" / "episode0.json").write_text('{"not": "rows"}')
    with pytest.raises(ValueError, match=r"episode0\.json: expected a list of \[start, end"):
        read_trajectory(path)


def joint_vector() -> np.ndarray:
    """(T, 14) ViperX-pair rows: left joint 0 climbs 0 -> 0.9 rad, right joint 5 falls 0 ->
    -0.45, both grippers swing open and shut (not arm joints)."""
    s = np.linspace(0.0, 1.0, T)
    vec = np.zeros((T, 14))
    vec[:, 0], vec[:, 12] = 0.9 * s, -0.45 * s
    vec[:, 6] = vec[:, 13] = np.arange(T) % 2
    return vec


def test_our_layout_reads_arm_joints_from_the_measured_joint_state(tmp_path):
    vec = joint_vector()
    data = {**ours_datasets(), "joint_state/vector": vec, "joint_action/vector": 2 * vec}
    traj = read_trajectory(write(tmp_path / "e.hdf5", data, OURS_ATTRS))
    np.testing.assert_array_equal(traj.left_q, vec[:, 0:6])
    np.testing.assert_array_equal(traj.right_q, vec[:, 7:13])
    assert read_trajectory(write(tmp_path / "f.hdf5", ours_datasets(), OURS_ATTRS)).left_q is None
    bad = {**ours_datasets(), "joint_state/vector": vec[:-1]}
    with pytest.raises(ValueError, match="mismatched lengths: .*'joint_state/vector' has 9"):
        read_trajectory(write(tmp_path / "g.hdf5", bad, OURS_ATTRS))
    odd = {**ours_datasets(), "joint_state/vector": vec[:, :13]}
    with pytest.raises(ValueError, match=r"'joint_state/vector' has shape \(10, 13\)"):
        read_trajectory(write(tmp_path / "h.hdf5", odd, OURS_ATTRS))


def test_robotwin_arm_joints_and_bicoord_has_none(tmp_path):
    vec = joint_vector()
    data = {
        **robotwin_datasets(),
        "joint_action/left_arm": vec[:, 0:6],
        "joint_action/right_arm": vec[:, 7:13],
    }
    traj = read_trajectory(write(tmp_path / "r" / "episode0.hdf5", data))
    assert traj.layout == "robotwin"
    np.testing.assert_array_equal(traj.right_q, vec[:, 7:13])
    assert read_trajectory(write(tmp_path / "r1.hdf5", robotwin_datasets())).right_q is None
    bicoord = read_trajectory(write(tmp_path / "b.hdf5", {"endpose": bicoord_endpose()}))
    assert (bicoord.left_q, bicoord.right_q) == (None, None)


def test_task_from_path():
    assert task_from_path("/d/lift_pot/demo_clean/data/episode0.hdf5") == "lift_pot"
    assert task_from_path("/d/lift_pot/episode0.hdf5") == "lift_pot"


def corrupt(datasets: dict, key: str, value) -> dict:
    out = dict(datasets)
    if value is None:
        del out[key]
    else:
        out[key] = value
    return out


@pytest.mark.parametrize(
    ("datasets", "message"),
    [
        (
            corrupt(ours_datasets(), "joint_action/right_gripper", None),
            "missing key 'joint_action/right_gripper'",
        ),
        (
            corrupt(ours_datasets(), "endpose/right_endpose", np.zeros((T, 6)) + 1.0),
            r"key 'endpose/right_endpose' has shape \(10, 6\), expected \(T, 7\)",
        ),
        (
            corrupt(ours_datasets(), "joint_action/left_gripper", np.full(T, np.nan)),
            "key 'joint_action/left_gripper' contains NaN",
        ),
        (
            corrupt(ours_datasets(), "joint_action/left_gripper", np.ones(T - 1)),
            "mismatched lengths: .*'joint_action/left_gripper' has 9",
        ),
        (
            corrupt(
                ours_datasets(),
                "endpose/right_endpose",
                robotwin_datasets()["endpose/left_endpose"],
            ),
            "'endpose/left_endpose' and 'endpose/right_endpose' coincide at frame 0",
        ),
        (
            corrupt(ours_datasets(), "stages/start", None),
            "missing key 'stages/start'",
        ),
    ],
    ids=["missing-key", "wrong-shape", "nan", "mismatched-lengths", "zero-distance", "no-start"],
)
def test_bad_files_name_file_and_key(tmp_path, datasets, message):
    path = write(tmp_path / "bad.hdf5", datasets, OURS_ATTRS)
    with pytest.raises(ValueError, match=rf"bad\.hdf5: .*{message}"):
        read_trajectory(path)


def test_not_hdf5_missing_file_and_unknown_layout(tmp_path):
    text = tmp_path / "notes.hdf5"
    text.write_text("not hdf5")
    with pytest.raises(ValueError, match=r"notes\.hdf5: not an HDF5 file"):
        read_trajectory(text)
    with pytest.raises(ValueError, match="no such file"):
        read_trajectory(tmp_path / "missing.hdf5")
    odd = write(tmp_path / "odd.hdf5", {"qpos": np.zeros((T, 14))})
    with pytest.raises(ValueError, match=r"odd\.hdf5: unknown layout"):
        read_trajectory(odd)
    bicoord = write(tmp_path / "b.hdf5", {"endpose": bicoord_endpose()})
    with pytest.raises(ValueError, match=r"b\.hdf5: .*'endpose/left_endpose'"):
        read_trajectory(bicoord, "robotwin")
    with pytest.raises(ValueError, match="unknown format"):
        read_trajectory(bicoord, "lerobot")


def test_find_and_read_many(tmp_path):
    root = tmp_path / "data"
    for i in (10, 2, 1):
        write(root / "a" / "cfg" / "data" / f"episode{i}.hdf5", robotwin_datasets())
    (root / "a" / "cfg" / "data" / "broken.hdf5").write_text("x")
    (tmp_path / "empty").mkdir()
    files, errors = find_episode_files([root, tmp_path / "empty", tmp_path / "nope"])
    assert [f.name for f in files] == [
        "broken.hdf5",
        "episode1.hdf5",
        "episode2.hdf5",
        "episode10.hdf5",
    ]
    assert errors == [
        f"{tmp_path / 'empty'}: no *.hdf5 files found",
        f"{tmp_path / 'nope'}: no such file or directory",
    ]
    trajectories, errors = read_trajectories([root])
    assert [t.task for t in trajectories] == ["a", "a", "a"]
    assert len(errors) == 1 and "broken.hdf5: not an HDF5 file" in errors[0]
