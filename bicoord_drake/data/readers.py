"""Read the signals the coordination metrics need from episode files of three layouts.

Layouts (``format``):

``bicoord_drake``
    Our episode files (PRODUCT.md, Data): ``endpose/{left,right}_endpose`` (T, 7) xyz + quaternion
    wxyz, ``joint_action/{left,right}_gripper`` (T,), ``stages/start`` (S,), root attributes
    ``task``, ``schema_version``, ``object_count`` (ON), ``success``; arm joint positions (path
    length) from the measured ``joint_state/vector`` when present. Detected by a root attribute
    ``schema_version`` or ``task`` next to ``endpose/left_endpose``.
``robotwin``
    RoboTwin 2.0: ``endpose/{left,right}_endpose`` (T, 7) and ``joint_action/{left,right}_gripper``
    (T,), no stages (SN is None), no object count (ON is None); arm joint positions from
    ``joint_action/{left,right}_arm`` (T, n) when present. Detected by those keys without our root
    attributes.
``bicoord``
    BiCoord's release: ``endpose`` (T, 14) = per arm [x, y, z, roll, pitch, yaw, gripper], left
    then right. Stage count from the sidecar ``stages/episodeN.json`` when present (rows
    ``[start, end, subgoal, left, right, score]``), ON is None, no joint positions (path length
    unknown). Detected by a 2-D ``endpose``
    dataset of width 14.

Task names: our files carry the ``task`` root attribute. Otherwise (and as a fallback) the name
comes from the directory, following RoboTwin 2.0's ``<task>/<config>/data/episodeN.hdf5``: when the
file sits in a directory called ``data`` the task is the directory two levels above it, else it is
the file's parent directory.

Every problem with a file raises ``ValueError`` whose message starts with the file name and names
the offending key.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path

import h5py
import numpy as np

from bicoord_drake.data.trajectory import MIN_INITIAL_DISTANCE, Trajectory

LAYOUTS = ("bicoord_drake", "robotwin", "bicoord")
FORMATS = ("auto", *LAYOUTS)
SCHEMA_MAJOR = 1
"""Major schema version of our episode files this reader understands."""

#: Width of a BiCoord-release ``endpose`` row: per arm xyz, rpy and the gripper (that dataset's
#: fixed format, whatever the robot).
_BICOORD_ENDPOSE_WIDTH = 14
_LEFT_POSE, _RIGHT_POSE = "endpose/left_endpose", "endpose/right_endpose"
_LEFT_GRIP, _RIGHT_GRIP = "joint_action/left_gripper", "joint_action/right_gripper"
_JOINT_STATE = "joint_state/vector"
_LEFT_ARM, _RIGHT_ARM = "joint_action/left_arm", "joint_action/right_arm"


def task_from_path(path: str | Path) -> str:
    """Task name from ``<task>/<config>/data/episodeN.hdf5``, else the parent directory name."""
    parent = Path(path).resolve().parent
    if parent.name == "data" and parent.parent.parent.name:
        return parent.parent.parent.name
    return parent.name or "unknown"


def _open(path: Path) -> h5py.File:
    if not path.exists():
        raise ValueError(f"{path}: no such file or directory")
    if not path.is_file():
        raise ValueError(f"{path}: not a file")
    try:
        if not h5py.is_hdf5(path):
            raise ValueError(f"{path}: not an HDF5 file")
        return h5py.File(path, "r")
    except OSError as exc:
        raise ValueError(f"{path}: cannot open HDF5 file ({exc})") from None


def _array(f: h5py.File, key: str, path: Path) -> np.ndarray:
    obj = f.get(key)
    if obj is None:
        raise ValueError(f"{path}: missing key '{key}'")
    if not isinstance(obj, h5py.Dataset):
        raise ValueError(f"{path}: key '{key}' is a group, expected a dataset")
    try:
        raw = obj[()]
    except OSError as exc:
        raise ValueError(f"{path}: cannot read key '{key}' ({exc})") from None
    try:
        arr = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: key '{key}' is not numeric (dtype {obj.dtype})") from None
    if not np.isfinite(arr).all():
        raise ValueError(f"{path}: key '{key}' contains NaN or inf")
    return arr


def _matrix(f: h5py.File, key: str, width: int, path: Path) -> np.ndarray:
    arr = _array(f, key, path)
    if arr.ndim != 2 or arr.shape[1] != width:
        raise ValueError(f"{path}: key '{key}' has shape {arr.shape}, expected (T, {width})")
    return arr


def _vector(f: h5py.File, key: str, path: Path) -> np.ndarray:
    arr = _array(f, key, path)
    if arr.ndim == 2 and arr.shape[1] == 1:
        arr = arr[:, 0]
    if arr.ndim != 1:
        raise ValueError(f"{path}: key '{key}' has shape {arr.shape}, expected (T,)")
    return arr


def _attr_str(f: h5py.File, name: str) -> str | None:
    value = f.attrs.get(name)
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.item()
    if isinstance(value, bytes):
        value = value.decode()
    return None if value is None else str(value)


def _detect(f: h5py.File, path: Path) -> str:
    has_ours = "schema_version" in f.attrs or "task" in f.attrs
    if has_ours and _LEFT_POSE in f:
        return "bicoord_drake"
    if _LEFT_POSE in f and _LEFT_GRIP in f:
        return "robotwin"
    endpose = f.get("endpose")
    if (
        isinstance(endpose, h5py.Dataset)
        and endpose.ndim == 2
        and endpose.shape[1] == _BICOORD_ENDPOSE_WIDTH
    ):
        return "bicoord"
    raise ValueError(
        f"{path}: unknown layout: expected '{_LEFT_POSE}' with root attribute 'task' "
        f"(bicoord_drake), '{_LEFT_POSE}' + '{_LEFT_GRIP}' (robotwin) or a (T, 14) 'endpose' "
        "dataset (bicoord)"
    )


def detect_format(path: str | Path) -> str:
    """The layout of an episode file: one of ``LAYOUTS``."""
    path = Path(path)
    with _open(path) as f:
        return _detect(f, path)


def _sidecar_stage_count(path: Path) -> int | None:
    """Rows in ``stages/episodeN.json`` beside the ``data/`` directory (or the file), if any."""
    name = path.with_suffix(".json").name
    for candidate in (path.parent.parent / "stages" / name, path.parent / "stages" / name):
        if candidate.is_file():
            break
    else:
        return None
    try:
        rows = json.loads(candidate.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{candidate}: cannot read stage annotation ({exc})") from None
    if not isinstance(rows, list) or not all(
        isinstance(row, list) and len(row) == 6 for row in rows
    ):
        raise ValueError(
            f"{candidate}: expected a list of [start, end, subgoal, left, right, score] rows"
        )
    return len(rows)


def _check_schema(f: h5py.File, path: Path) -> None:
    version = _attr_str(f, "schema_version")
    if version is None:
        return
    major = version.split(".")[0].strip()
    if major != str(SCHEMA_MAJOR):
        raise ValueError(
            f"{path}: root attribute 'schema_version' is {version!r}; "
            f"this reader supports {SCHEMA_MAJOR}.x"
        )


def _read_endpose_gripper(f: h5py.File, path: Path) -> dict:
    return {
        "left_xyz": _matrix(f, _LEFT_POSE, 7, path)[:, :3],
        "right_xyz": _matrix(f, _RIGHT_POSE, 7, path)[:, :3],
        "left_gripper": _vector(f, _LEFT_GRIP, path),
        "right_gripper": _vector(f, _RIGHT_GRIP, path),
        "keys": (_LEFT_POSE, _RIGHT_POSE, _LEFT_GRIP, _RIGHT_GRIP),
    }


def _joints_of_state(f: h5py.File, path: Path) -> dict:
    """Arm joint positions from the measured ``joint_state/vector``, if the file has one."""
    if _JOINT_STATE not in f:
        return {}
    arr = _array(f, _JOINT_STATE, path)
    if arr.ndim != 2 or arr.shape[1] < 4 or arr.shape[1] % 2:
        raise ValueError(
            f"{path}: key '{_JOINT_STATE}' has shape {arr.shape}, expected (T, 2 (n + 1))"
        )
    n = arr.shape[1] // 2 - 1  # [left q (n), left opening, right q (n), right opening]
    left_q, right_q = arr[:, :n], arr[:, n + 1 : 2 * n + 1]
    return {"left_q": left_q, "right_q": right_q, "q_keys": (_JOINT_STATE, _JOINT_STATE)}


def _joints_of_arms(f: h5py.File, path: Path) -> dict:
    """Arm joint positions from ``joint_action/{left,right}_arm`` if the file has both."""
    if _LEFT_ARM not in f or _RIGHT_ARM not in f:
        return {}
    left_q, right_q = _array(f, _LEFT_ARM, path), _array(f, _RIGHT_ARM, path)
    for key, arr in ((_LEFT_ARM, left_q), (_RIGHT_ARM, right_q)):
        if arr.ndim != 2 or arr.shape[1] < 1:
            raise ValueError(f"{path}: key '{key}' has shape {arr.shape}, expected (T, n)")
    return {"left_q": left_q, "right_q": right_q, "q_keys": (_LEFT_ARM, _RIGHT_ARM)}


def _read_ours(f: h5py.File, path: Path) -> dict:
    _check_schema(f, path)
    signals = dict(_read_endpose_gripper(f, path), **_joints_of_state(f, path))
    if "stages" in f:
        n_stages = len(_vector(f, "stages/start", path))
    else:
        n_stages = _sidecar_stage_count(path)
    if "object_count" in f.attrs:
        count = np.asarray(f.attrs["object_count"])
        if count.size != 1 or not np.issubdtype(count.dtype, np.integer) or count.item() < 0:
            raise ValueError(
                f"{path}: root attribute 'object_count' must be a non-negative integer, "
                f"got {count.tolist()!r}"
            )
        n_objects = int(count.item())
    elif isinstance(f.get("objects"), h5py.Group):
        n_objects = len(f["objects"])
    else:
        n_objects = None
    success = f.attrs.get("success")
    return dict(
        signals,
        task=_attr_str(f, "task") or task_from_path(path),
        n_stages=n_stages,
        n_objects=n_objects,
        success=None if success is None else bool(np.asarray(success).item()),
    )


def _read_robotwin(f: h5py.File, path: Path) -> dict:
    return dict(
        _read_endpose_gripper(f, path), **_joints_of_arms(f, path), task=task_from_path(path)
    )


def _read_bicoord(f: h5py.File, path: Path) -> dict:
    endpose = _matrix(f, "endpose", _BICOORD_ENDPOSE_WIDTH, path)
    return {
        "left_xyz": endpose[:, 0:3],
        "right_xyz": endpose[:, 7:10],
        "left_gripper": endpose[:, 6],
        "right_gripper": endpose[:, 13],
        "keys": ("endpose[:, 0:3]", "endpose[:, 7:10]", "endpose[:, 6]", "endpose[:, 13]"),
        "task": task_from_path(path),
        "n_stages": _sidecar_stage_count(path),
    }


_READERS = {"bicoord_drake": _read_ours, "robotwin": _read_robotwin, "bicoord": _read_bicoord}


def _check_signals(path: Path, fields: dict) -> None:
    keys = list(fields.pop("keys"))
    names = ["left_xyz", "right_xyz", "left_gripper", "right_gripper"]
    if "q_keys" in fields:
        keys += fields.pop("q_keys")
        names += ["left_q", "right_q"]
    arrays = [fields[n] for n in names]
    lengths = [len(a) for a in arrays]
    if len(set(lengths)) != 1:
        shown = ", ".join(f"'{k}' has {n}" for k, n in zip(keys, lengths, strict=True))
        raise ValueError(f"{path}: mismatched lengths: {shown} frames")
    if lengths[0] == 0:
        raise ValueError(f"{path}: key '{keys[0]}' has no frames")
    if np.linalg.norm(arrays[0][0] - arrays[1][0]) <= MIN_INITIAL_DISTANCE:
        raise ValueError(
            f"{path}: keys '{keys[0]}' and '{keys[1]}' coincide at frame 0 "
            "(zero initial distance between the arms)"
        )


def read_trajectory(path: str | Path, format: str = "auto") -> Trajectory:
    """Read one episode file; ``format`` is ``"auto"`` or one of ``LAYOUTS``."""
    if format not in FORMATS:
        raise ValueError(f"unknown format {format!r}; choose one of {', '.join(FORMATS)}")
    path = Path(path)
    with _open(path) as f:
        layout = _detect(f, path) if format == "auto" else format
        fields = _READERS[layout](f, path)
    _check_signals(path, fields)
    return Trajectory(source=str(path), layout=layout, **fields)


def _natural_key(path: Path) -> list:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", str(path))]


def find_episode_files(paths: Iterable[str | Path]) -> tuple[list[Path], list[str]]:
    """Expand files and directories (recursively, ``*.hdf5``) into episode files.

    Returns the files in natural order and one error line per path that does not exist or is a
    directory without episode files. Files given explicitly are kept whatever their suffix.
    """
    files: dict[Path, None] = {}
    errors: list[str] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            found = sorted(path.rglob("*.hdf5"), key=_natural_key)
            if not found:
                errors.append(f"{path}: no *.hdf5 files found")
            files.update(dict.fromkeys(found))
        elif path.exists():
            files[path] = None
        else:
            errors.append(f"{path}: no such file or directory")
    return list(files), errors


def read_trajectories(
    paths: Iterable[str | Path], format: str = "auto"
) -> tuple[list[Trajectory], list[str]]:
    """Read every episode under ``paths``; each bad file becomes one error line that names the
    file and why it could not be read (an unexpected error included), never an exception."""
    if format not in FORMATS:
        raise ValueError(f"unknown format {format!r}; choose one of {', '.join(FORMATS)}")
    files, errors = find_episode_files(paths)
    trajectories = []
    for file in files:
        try:
            trajectories.append(read_trajectory(file, format))
        except ValueError as exc:
            text = str(exc)
            errors.append(text if text.startswith(str(file)) else f"{file}: {text}")
        except Exception as exc:  # noqa: BLE001 - a corrupt file must not end the whole read
            errors.append(f"{file}: cannot read ({type(exc).__name__}: {exc})")
    return trajectories, errors
