"""Episode files: the HDF5 schema (in this one place), its writer and reader, and the sidecars.

Directory layout (:class:`EpisodeLayout`)::

    <out>/<task>/<config_name>/
        data/episode{i}.hdf5        one episode (schema below)
        video/episode{i}.mp4        head camera
        instructions/episode{i}.json   {"seen": [...], "unseen": [...]}
        stages/episode{i}.json      [[start, end, subgoal, left, right, score], ...]
        manifest.json               seeds, successes, failures with reasons, timings, config

Inside an episode file (T frames, S stages; PRODUCT.md, Data)::

    observation/<cam>/rgb            (T,) S<n>     JPEG bytes (zero-padded, as RoboTwin 2.0)
    observation/<cam>/depth          (T, H, W) uint16, mm (optional)
    observation/<cam>/intrinsic_cv   (T, 3, 3)
    observation/<cam>/extrinsic_cv   (T, 3, 4)    world -> camera, OpenCV
    joint_action/{left,right}_arm    (T, n)       n arm joints (6 for the ViperX pair)
    joint_action/{left,right}_gripper (T,)        commanded opening, 1 = open
    joint_action/vector              (T, A)       [left n, left grip, right n, right grip]
                                                  (A = 2 (n + 1): 14 for the ViperX pair)
    joint_action/executed            (T, A)       what the station executed, same layout, when
                                                  it differs from the label: the expert's
                                                  actions with action noise (DART; only
                                                  episodes generated with noise). ``vector``
                                                  and the per-arm datasets stay the label
    joint_state/vector               (T, A)       measured, same layout
    endpose/{left,right}_endpose     (T, 7)       TCP xyz + quaternion wxyz, world (the
                                                  sign nearer the arm's home orientation)
    objects/<name>/pose              (T, 7)
    joints/<name>/position           (T,)         a sliding object's joint position, m
                                                  (only scenes with one; optional on read)
    stages/{start,end}               (S,) int64   frames [start, end)
    stages/score                     (S,) float64
    stages/{subgoal,left,right}      (S,) str
    stages/initial_state             (S, n)       plant [q; v] at each stage's start frame
    stages/initial_action            (S, A)       action in effect before that frame (the
                                                  executed one, when recorded)
    stage_index                      (T,) int64
    disturbances/kind                (K,) str     push, drop or knock (only episodes generated
                                                  with disturbances: bicoord_drake.sim.
                                                  disturbances; K of them)
    disturbances/body                (K,) str     the object pushed, knocked or dropped
    disturbances/side                (K,) str     a drop's gripper (empty for the others)
    disturbances/step                (K,) int64   the first control step it acts in
    disturbances/duration            (K,) int64   control steps it acts for
    disturbances/wrench              (K, 6)       [torque, force] in the world frame, N m and N
                                                  (zero for a drop)
    disturbances/point               (K, 3)       where the force acts, body frame, m
    stages/recovery/{start,end}      (K,) int64   the recovery from each disturbance: frames
    stages/recovery/{subgoal,left,right} (K,) str [start, end), from its step to the expert's
    stages/recovery/score            (K,) float64 next plan (a row beside the stage rows)
    attrs: schema_version, task, seed, instruction, fps, embodiment, success, object_count,
           package_version, config (JSON), scene (JSON), frame_count,
           scenario (YAML: the full scenario that made the episode, bicoord_drake.scenario;
           absent from files written before it was recorded),
           action_noise (the noise level, rad, of an episode generated with action noise),
           disturb (the disturbance kinds, a comma list, of an episode generated with them)

The vector layout is the embodiment's (:class:`~bicoord_drake.models.layout.ActionLayout`;
:attr:`Episode.layout` from the ``embodiment`` attribute). Frame ``t`` holds the observation
*before* action ``t`` and action ``t`` itself. Replaying ``joint_action/executed`` where it exists,
else ``joint_action/vector`` (:attr:`Episode.replay_action`), with the recorded disturbances
applied again (:attr:`Episode.disturbances`; the environment does), reproduces the episode. A
drop's open gripper is in ``joint_action/executed``. Every file is
written atomically: a temporary file in the same directory, then ``os.replace``; nothing partial
ever appears under the final name. The recorder knows nothing about the task it records.
"""

from __future__ import annotations

import io
import json
import os
import tempfile
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np
from PIL import Image
from pydantic import BaseModel, ConfigDict, Field

from bicoord_drake.data.stage_rows import check_rows, stage_index_from_rows
from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.layout import ActionLayout, default_embodiment, layout_of
from bicoord_drake.models.scene import Scene
from bicoord_drake.version import package_version

if TYPE_CHECKING:
    from bicoord_drake.sim.frame_renderer import CameraFrame
    from bicoord_drake.sim.simulation import Simulation

SCHEMA_VERSION = 1
"""Version of the episode-file schema written here; bump it on any incompatible change."""

_STR = h5py.string_dtype()


# --------------------------------------------------------------------------- atomic files
@contextmanager
def atomic_path(path: str | Path, mode: int = 0o644) -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success fsync it and move it onto `path`.

    On any exception (KeyboardInterrupt included) the temporary file is removed and the final
    name is left untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_json(path: str | Path, obj: Any) -> Path:
    """Write JSON atomically (indented, UTF-8)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


# --------------------------------------------------------------------------- images
def encode_jpeg(rgb: np.ndarray, quality: int = 90) -> bytes:
    """A standard (RGB) JPEG of an (H, W, 3) uint8 image."""
    arr = np.asarray(rgb)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 image, got {arr.shape} {arr.dtype}")
    buf = io.BytesIO()
    Image.fromarray(arr, "RGB").save(buf, format="JPEG", quality=quality)
    return buf.getvalue()


def decode_rgb(data: bytes | np.ndarray) -> np.ndarray:
    """Decode one stored JPEG (bytes, np.bytes_ or a uint8 array) to (H, W, 3) uint8 RGB."""
    raw = data.tobytes() if isinstance(data, np.ndarray) else bytes(data)
    with Image.open(io.BytesIO(raw)) as img:
        return np.asarray(img.convert("RGB"))


# --------------------------------------------------------------------------- video
def write_video(
    path: str | Path, frames: Iterable[np.ndarray], fps: float, codec: str = "libx264"
) -> Path:
    """Encode (H, W, 3) uint8 RGB frames to an MP4 (yuv420p) atomically. Needs PyAV (``av``)."""
    try:
        import av
    except ImportError:
        raise ImportError(
            "writing MP4 videos needs PyAV: pip install av (its wheel bundles ffmpeg)"
        ) from None
    path = Path(path)
    with atomic_path(path) as tmp:
        container = av.open(str(tmp), mode="w", format="mp4")
        try:
            stream = None
            for frame in frames:
                frame = np.ascontiguousarray(frame, dtype=np.uint8)
                h, w = frame.shape[:2]
                if stream is None:
                    stream = container.add_stream(codec, rate=Fraction(fps).limit_denominator(1001))
                    stream.width, stream.height = w - w % 2, h - h % 2  # yuv420p: even sizes
                    stream.pix_fmt = "yuv420p"
                frame = frame[: stream.height, : stream.width]
                for packet in stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")):
                    container.mux(packet)
            if stream is None:
                raise ValueError(f"{path}: no frames to write")
            for packet in stream.encode():
                container.mux(packet)
        finally:
            container.close()
    return path


# --------------------------------------------------------------------------- metadata
@dataclass(frozen=True)
class EpisodeMeta:
    """Root attributes the caller provides (the recorder does not know the task)."""

    task: str
    seed: int
    instruction: str
    embodiment: str
    success: bool
    object_count: int
    config: Mapping[str, Any] | BaseModel | str | None = None
    scene: Scene | None = None
    #: The scenario that made the episode, as YAML/JSON text or a mapping (stored as JSON).
    scenario: Mapping[str, Any] | str | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)

    def attrs(self, fps: float, frames: int) -> dict[str, Any]:
        """All root attributes, as HDF5-storable values."""
        if isinstance(self.config, BaseModel):
            config = self.config.model_dump_json()
        elif isinstance(self.config, str):
            config = self.config
        else:
            config = json.dumps(dict(self.config or {}), sort_keys=True)
        clash = set(self.extra) & _RESERVED_ATTRS
        if clash:
            raise ValueError(f"extra attributes may not override {sorted(clash)}")
        attrs = {
            "schema_version": np.int64(SCHEMA_VERSION),
            "task": str(self.task),
            "seed": np.int64(self.seed),
            "instruction": str(self.instruction),
            "fps": float(fps),
            "embodiment": str(self.embodiment),
            "success": np.bool_(self.success),
            "object_count": np.int64(self.object_count),
            "package_version": package_version(),
            "config": config,
            "scene": "" if self.scene is None else self.scene.model_dump_json(),
            "frame_count": np.int64(frames),
        }
        if self.scenario is not None:
            scenario = self.scenario
            attrs["scenario"] = scenario if isinstance(scenario, str) else json.dumps(scenario)
        attrs.update(self.extra)
        return attrs


_RESERVED_ATTRS = {
    "schema_version",
    "task",
    "seed",
    "instruction",
    "fps",
    "embodiment",
    "success",
    "object_count",
    "package_version",
    "config",
    "scene",
    "frame_count",
    "scenario",
}


# --------------------------------------------------------------------------- recorder
def _vec(value: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    arr = np.array(value, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"{what} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} contains NaN or inf")
    return arr


class EpisodeRecorder:
    """Accumulates one frame per control step and writes the episode file.

    Typical loop (the runner's)::

        recorder = EpisodeRecorder(fps=15, initial_action=reset_action, layout=station.layout)
        for action in expert:
            recorder.capture(sim, action)      # observation before the action, and the action
            sim.step(action)
        recorder.write(path, monitor.annotations(len(recorder)), meta)

    `layout` is the robot's action layout (default: the default embodiment's).
    """

    def __init__(
        self,
        fps: float,
        jpeg_quality: int = 90,
        initial_action: np.ndarray | None = None,
        layout: ActionLayout | None = None,
    ) -> None:
        if fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self.fps = float(fps)
        self.jpeg_quality = int(jpeg_quality)
        self.layout = layout or layout_of(default_embodiment())
        self._size = (self.layout.action_size,)
        self.initial_action = (
            None if initial_action is None else _vec(initial_action, self._size, "action")
        )
        self._rgb: dict[str, list[bytes]] = {}
        self._depth: dict[str, list[np.ndarray]] = {}
        self._intrinsic: dict[str, list[np.ndarray]] = {}
        self._extrinsic: dict[str, list[np.ndarray]] = {}
        self._action: list[np.ndarray] = []
        self._executed: list[np.ndarray] = []
        self._joint_state: list[np.ndarray] = []
        self._endpose: dict[str, list[np.ndarray]] = {s: [] for s in SIDES}
        self._objects: dict[str, list[np.ndarray]] = {}
        self._plant_state: list[np.ndarray] = []
        self._joints: dict[str, list[float]] = {}
        #: The disturbances of the episode (mappings of their fields: bicoord_drake.sim.
        #: disturbances.Disturbance) and the recovery row of each, written with the episode.
        self.disturbances: list[Mapping[str, Any]] = []
        self.recovery_rows: list[list] = []

    def __len__(self) -> int:
        return len(self._action)

    @property
    def cameras(self) -> list[str]:
        return list(self._rgb)

    @property
    def actions(self) -> np.ndarray:
        """The recorded actions, (T, A) float64 (a copy)."""
        return np.array(self._action, dtype=np.float64).reshape(len(self), self.layout.action_size)

    @property
    def executed_actions(self) -> np.ndarray | None:
        """The executed actions, (T, A) float64 (a copy), if they were recorded apart from the
        labels (``executed_action`` of :meth:`add_frame`); None otherwise."""
        if not self._executed:
            return None
        return np.array(self._executed, dtype=np.float64)

    @property
    def joint_states(self) -> np.ndarray:
        """The measured joint states, (T, A) float64 (a copy)."""
        return np.array(self._joint_state, dtype=np.float64).reshape(len(self), -1)

    def add_frame(
        self,
        *,
        action: np.ndarray,
        joint_state: np.ndarray,
        left_endpose: np.ndarray,
        right_endpose: np.ndarray,
        object_poses: Mapping[str, np.ndarray],
        images: Mapping[str, np.ndarray] | None = None,
        depth: Mapping[str, np.ndarray] | None = None,
        intrinsic_cv: Mapping[str, np.ndarray] | None = None,
        extrinsic_cv: Mapping[str, np.ndarray] | None = None,
        plant_state: np.ndarray | None = None,
        joint_positions: Mapping[str, float] | None = None,
        executed_action: np.ndarray | None = None,
    ) -> None:
        """Append one frame. Cameras, objects, joints and plant-state presence must match
        frame 0; so must that of `executed_action` (what the station executed when it is not
        `action`, the label: ``joint_action/executed``)."""
        images, depth = dict(images or {}), dict(depth or {})
        intrinsic_cv, extrinsic_cv = dict(intrinsic_cv or {}), dict(extrinsic_cv or {})
        first = len(self) == 0
        if not first:
            self._same(set(images), set(self._rgb), "cameras")
            self._same(set(depth), set(self._depth), "depth cameras")
            self._same(set(object_poses), set(self._objects), "objects")
            self._same(set(joint_positions or {}), set(self._joints), "joints")
            if (plant_state is None) != (not self._plant_state):
                raise ValueError("plant_state must be given for every frame or for none")
            if (executed_action is None) != (not self._executed):
                raise ValueError("executed_action must be given for every frame or for none")
        for cam in depth:
            if cam not in images:
                raise ValueError(f"depth for camera {cam!r} without its RGB image")
        for cam in images:
            if cam not in intrinsic_cv or cam not in extrinsic_cv:
                raise ValueError(f"camera {cam!r}: image given without intrinsic_cv/extrinsic_cv")
        frame = {
            "action": _vec(action, self._size, "action"),
            "executed": None
            if executed_action is None
            else _vec(executed_action, self._size, "executed_action"),
            "joint_state": _vec(joint_state, self._size, "joint_state"),
            "left": _vec(left_endpose, (7,), "left_endpose"),
            "right": _vec(right_endpose, (7,), "right_endpose"),
            "objects": {n: _vec(p, (7,), f"pose of {n!r}") for n, p in object_poses.items()},
            "K": {c: _vec(intrinsic_cv.get(c), (3, 3), f"{c} intrinsic_cv") for c in images},
            "E": {c: _vec(extrinsic_cv.get(c), (3, 4), f"{c} extrinsic_cv") for c in images},
            "rgb": {c: encode_jpeg(img, self.jpeg_quality) for c, img in images.items()},
            "depth": {c: self._depth_image(c, d) for c, d in depth.items()},
            "joints": {
                n: float(_vec(d, (), f"joint position of {n!r}"))
                for n, d in (joint_positions or {}).items()
            },
        }
        # all validated: commit the frame
        self._action.append(frame["action"])
        if frame["executed"] is not None:
            self._executed.append(frame["executed"])
        self._joint_state.append(frame["joint_state"])
        self._endpose["left"].append(frame["left"])
        self._endpose["right"].append(frame["right"])
        for store, key in (
            (self._objects, "objects"),
            (self._intrinsic, "K"),
            (self._extrinsic, "E"),
            (self._rgb, "rgb"),
            (self._depth, "depth"),
            (self._joints, "joints"),
        ):
            for name, value in frame[key].items():
                store.setdefault(name, []).append(value)
        if plant_state is not None:
            self._plant_state.append(np.array(plant_state, dtype=np.float64).ravel())

    def capture(
        self,
        sim: Simulation,
        action: np.ndarray,
        depth: bool = False,
        executed: np.ndarray | None = None,
    ) -> None:
        """Record the simulation's current observation (call before ``sim.step(action)``);
        `executed`: the action the station gets instead of `action` (which stays the label)."""
        if sim.station.layout.arm_joints != self.layout.arm_joints:
            raise ValueError(
                f"this recorder's layout is {self.layout.describe()}, the robot's "
                f"{sim.station.layout.describe()}: make it with layout=station.layout"
            )
        rendered = sim.images(depth=depth) if sim.station.cameras else {}
        cams = list(sim.station.cameras)
        self.add_frame(
            action=action,
            joint_state=sim.joint_state(),
            left_endpose=sim.tcp_pose("left"),
            right_endpose=sim.tcp_pose("right"),
            object_poses=sim.object_poses(),
            images={c: rendered[c] for c in cams},
            depth={c: rendered[f"{c}_depth"] for c in cams if f"{c}_depth" in rendered},
            intrinsic_cv={c: sim.intrinsic_cv(c) for c in cams},
            extrinsic_cv={c: sim.extrinsic_cv(c) for c in cams},
            plant_state=sim.station.plant.GetPositionsAndVelocities(sim.plant_context),
            joint_positions=sim.joint_positions(),
            executed_action=executed,
        )

    @property
    def plant_states(self) -> list[np.ndarray]:
        """The plant ``[q; v]`` of every frame (empty if none were recorded)."""
        return list(self._plant_state)

    def attach_images(self, frames: Iterable[CameraFrame]) -> None:
        """Add the camera frames of a recording made without cameras: one
        :class:`~bicoord_drake.sim.frame_renderer.CameraFrame` per recorded frame, in order
        (JPEG-encoded as they arrive, so a whole episode of raw images never sits in memory).

        Nothing is kept unless every frame is valid and the count matches."""
        if self._rgb:
            raise ValueError(f"this recording already has camera images: {self.cameras}")
        rgb: dict[str, list[bytes]] = {}
        depth: dict[str, list[np.ndarray]] = {}
        K: dict[str, list[np.ndarray]] = {}
        E: dict[str, list[np.ndarray]] = {}
        count = 0
        for count, frame in enumerate(frames, start=1):
            if count > len(self):
                raise ValueError(f"more camera frames than the {len(self)} recorded frames")
            cams = set(frame.images)
            if count > 1:
                self._same(cams, set(rgb), "cameras")
                self._same(set(frame.depth), set(depth), "depth cameras")
            for cam in cams:
                if cam not in frame.intrinsic_cv or cam not in frame.extrinsic_cv:
                    raise ValueError(f"camera {cam!r}: image without intrinsic_cv/extrinsic_cv")
                K.setdefault(cam, []).append(_vec(frame.intrinsic_cv[cam], (3, 3), "intrinsic"))
                E.setdefault(cam, []).append(_vec(frame.extrinsic_cv[cam], (3, 4), "extrinsic"))
                rgb.setdefault(cam, []).append(encode_jpeg(frame.images[cam], self.jpeg_quality))
            for cam, d in frame.depth.items():
                if cam not in cams:
                    raise ValueError(f"depth for camera {cam!r} without its RGB image")
                depth.setdefault(cam, []).append(self._depth_image(cam, d))
        if count != len(self):
            raise ValueError(f"{count} camera frames for {len(self)} recorded frames")
        self._rgb, self._depth, self._intrinsic, self._extrinsic = rgb, depth, K, E

    @staticmethod
    def _same(given: set, expected: set, what: str) -> None:
        if given != expected:
            raise ValueError(
                f"{what} changed between frames: {sorted(given)} != {sorted(expected)}"
            )

    @staticmethod
    def _depth_image(cam: str, depth: np.ndarray) -> np.ndarray:
        arr = np.asarray(depth)
        if arr.ndim != 2 or arr.dtype != np.uint16:
            raise ValueError(f"{cam} depth must be (H, W) uint16 mm, got {arr.shape} {arr.dtype}")
        return arr.copy()

    def frames(self, camera: str = "head_camera") -> Iterator[np.ndarray]:
        """Decoded RGB frames of one camera."""
        if camera not in self._rgb:
            raise KeyError(f"no camera {camera!r} recorded; cameras: {self.cameras}")
        return (decode_rgb(b) for b in self._rgb[camera])

    # ---------------------------------------------------------------- writing
    def write(
        self,
        path: str | Path,
        annotations: Sequence[Sequence],
        attrs: EpisodeMeta | Mapping[str, Any],
    ) -> Path:
        """Write the episode file atomically. `annotations` are the stage rows
        ``[start, end, subgoal, left, right, score]`` covering ``[0, T)``."""
        meta = attrs if isinstance(attrs, EpisodeMeta) else EpisodeMeta(**attrs)
        T = len(self)
        if T == 0:
            raise ValueError("no frames recorded")
        rows = [list(r) for r in annotations]
        check_rows(rows, T)
        root_attrs = meta.attrs(self.fps, T)
        path = Path(path)
        with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
            self._write_observation(f)
            self._write_robot(f)
            self._write_objects(f)
            self._write_stages(f, rows)
            self._write_disturbances(f, T)
            f.attrs.update(root_attrs)
        return path

    def write_video(self, path: str | Path, camera: str = "head_camera") -> Path:
        """The camera's frames as an MP4 at the recording rate (atomic; needs PyAV)."""
        return write_video(path, self.frames(camera), self.fps)

    def _write_observation(self, f: h5py.File) -> None:
        for cam, jpegs in self._rgb.items():
            g = f.create_group(f"observation/{cam}")
            g.create_dataset("rgb", data=np.array(jpegs, dtype=f"S{max(map(len, jpegs))}"))
            g.create_dataset("intrinsic_cv", data=np.stack(self._intrinsic[cam]))
            g.create_dataset("extrinsic_cv", data=np.stack(self._extrinsic[cam]))
            if cam in self._depth:
                depth = np.stack(self._depth[cam])
                g.create_dataset(
                    "depth", data=depth, chunks=(1, *depth.shape[1:]), compression="gzip"
                )

    def _write_robot(self, f: h5py.File) -> None:
        action, layout = np.stack(self._action), self.layout
        f["joint_action/vector"] = action
        if self._executed:
            f["joint_action/executed"] = np.stack(self._executed)
        for side in SIDES:
            f[f"joint_action/{side}_arm"] = action[:, layout.arm(side)]
            f[f"joint_action/{side}_gripper"] = action[:, layout.gripper(side)]
        f["joint_state/vector"] = np.stack(self._joint_state)
        for side in SIDES:
            f[f"endpose/{side}_endpose"] = np.stack(self._endpose[side])

    def _write_objects(self, f: h5py.File) -> None:
        f.create_group("objects")
        for name, poses in self._objects.items():
            f[f"objects/{name}/pose"] = np.stack(poses)
        for name, positions in self._joints.items():
            f[f"joints/{name}/position"] = np.array(positions, dtype=np.float64)

    def _write_stages(self, f: h5py.File, rows: list[list]) -> None:
        starts = np.array([int(r[0]) for r in rows], dtype=np.int64)
        f["stages/start"] = starts
        f["stages/end"] = np.array([int(r[1]) for r in rows], dtype=np.int64)
        f["stages/score"] = np.array([float(r[5]) for r in rows], dtype=np.float64)
        for k, key in ((2, "subgoal"), (3, "left"), (4, "right")):
            f.create_dataset(f"stages/{key}", data=[str(r[k]) for r in rows], dtype=_STR)
        f["stage_index"] = stage_index_from_rows(rows)
        if self._plant_state:
            f["stages/initial_state"] = np.stack(self._plant_state)[starts]
        actions = np.stack(self._executed or self._action)  # in effect: what the station ran
        before = self.initial_action if self.initial_action is not None else actions[0]
        f["stages/initial_action"] = np.stack([actions[s - 1] if s > 0 else before for s in starts])

    def _write_disturbances(self, f: h5py.File, T: int) -> None:
        if len(self.recovery_rows) != len(self.disturbances):
            raise ValueError("one recovery row per disturbance")
        if not self.disturbances:
            return
        items = [dict(d) for d in self.disturbances]
        g = f.create_group("disturbances")
        for key in ("kind", "body", "side"):
            g.create_dataset(key, data=[str(d.get(key, "")) for d in items], dtype=_STR)
        for key in ("step", "duration"):
            g[key] = np.array([int(d[key]) for d in items], dtype=np.int64)
        g["wrench"] = np.array(
            [[*d.get("torque", (0, 0, 0)), *d.get("force", (0, 0, 0))] for d in items], float
        ).reshape(-1, 6)
        g["point"] = np.array([d.get("point", (0, 0, 0)) for d in items], float).reshape(-1, 3)
        rows = [list(r) for r in self.recovery_rows]
        for j, row in enumerate(rows):
            if len(row) != 6 or not 0 <= int(row[0]) < int(row[1]) <= T:
                raise ValueError(f"recovery row {j} must be [start, end, ...] within [0, {T})")
        r = f.create_group("stages/recovery")
        r["start"] = np.array([int(x[0]) for x in rows], dtype=np.int64)
        r["end"] = np.array([int(x[1]) for x in rows], dtype=np.int64)
        r["score"] = np.array([float(x[5]) for x in rows], dtype=np.float64)
        for k, key in ((2, "subgoal"), (3, "left"), (4, "right")):
            r.create_dataset(key, data=[str(x[k]) for x in rows], dtype=_STR)


# --------------------------------------------------------------------------- reader
@dataclass(eq=False)
class Episode:
    """One episode file in memory (images stay JPEG bytes; decode with :meth:`image`)."""

    path: Path
    attrs: dict[str, Any]
    rgb: dict[str, np.ndarray]
    depth: dict[str, np.ndarray]
    intrinsic_cv: dict[str, np.ndarray]
    extrinsic_cv: dict[str, np.ndarray]
    joint_action: np.ndarray
    joint_state: np.ndarray
    left_endpose: np.ndarray
    right_endpose: np.ndarray
    objects: dict[str, np.ndarray]
    stages: list[list]
    stage_index: np.ndarray
    initial_state: np.ndarray | None = None
    initial_action: np.ndarray | None = None
    #: (T,) joint position per sliding object (empty for scenes without one, and old files).
    joints: dict[str, np.ndarray] = field(default_factory=dict)
    #: (T, A) the actions the station executed, where they differ from the labels
    #: ``joint_action`` (episodes generated with action noise); None otherwise.
    executed_action: np.ndarray | None = None
    #: The disturbances the episode was generated with (mappings of the fields of
    #: :class:`bicoord_drake.sim.disturbances.Disturbance`; empty for a clean episode).
    disturbances: list[dict[str, Any]] = field(default_factory=list)
    #: The recovery row of each disturbance, ``[start, end, subgoal, left, right, score]``.
    recovery: list[list] = field(default_factory=list)

    @property
    def replay_action(self) -> np.ndarray:
        """The actions that reproduce the episode: the executed ones where recorded, else the
        labels ``joint_action``."""
        return self.joint_action if self.executed_action is None else self.executed_action

    @property
    def action_noise(self) -> float:
        """The action-noise level (rad) the episode was generated with (0: none)."""
        return float(self.attrs.get("action_noise", 0.0))

    @property
    def length(self) -> int:
        return len(self.joint_action)

    @property
    def task(self) -> str:
        return self.attrs["task"]

    @property
    def seed(self) -> int:
        return int(self.attrs["seed"])

    @property
    def fps(self) -> float:
        return float(self.attrs["fps"])

    @property
    def success(self) -> bool:
        return bool(self.attrs["success"])

    @property
    def instruction(self) -> str:
        return self.attrs["instruction"]

    @property
    def embodiment(self) -> str:
        return self.attrs["embodiment"]

    @property
    def layout(self) -> ActionLayout:
        """The action / joint-state layout of the recording robot (a ValueError naming the
        registered embodiments if it is not one of them)."""
        return layout_of(self.embodiment)

    @property
    def config(self) -> dict[str, Any]:
        return json.loads(self.attrs.get("config") or "{}")

    @property
    def scenario_text(self) -> str | None:
        """The recorded scenario (YAML), None for files written before it was recorded; read it
        with :func:`bicoord_drake.scenario.load_scenario` (the file's path)."""
        return self.attrs.get("scenario") or None

    @property
    def scene(self) -> Scene | None:
        """The scene the episode was recorded in (exact round-trip), if stored."""
        text = self.attrs.get("scene")
        return Scene.model_validate_json(text) if text else None

    def image(self, camera: str, t: int) -> np.ndarray:
        """Frame `t` of `camera`, decoded to (H, W, 3) uint8 RGB."""
        if camera not in self.rgb:
            raise KeyError(f"no camera {camera!r}; cameras: {sorted(self.rgb)}")
        return decode_rgb(self.rgb[camera][t])


def _attr(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.generic):
        return value.item()
    return value


def check_schema(attrs: Mapping[str, Any], path: str | Path) -> None:
    """Raise ValueError saying what is wrong unless the file has our schema version."""
    if "schema_version" not in attrs:
        raise ValueError(
            f"{path}: no root attribute 'schema_version': not a bicoord-drake episode file "
            f"(expected schema_version {SCHEMA_VERSION})"
        )
    version = _attr(attrs["schema_version"])
    try:
        major = int(str(version).split(".")[0])
    except ValueError:
        major = None
    if major != SCHEMA_VERSION:
        written = _attr(attrs.get("package_version", "an unknown version"))
        raise ValueError(
            f"{path}: schema_version is {version!r} (written by bicoord-drake {written}); this "
            f"reader (bicoord-drake {package_version()}) reads schema_version {SCHEMA_VERSION}: "
            "regenerate the episode or read it with a matching bicoord-drake version"
        )


def read_episode(path: str | Path, images: bool = True) -> Episode:
    """Read an episode file; checks ``schema_version`` first. ``images=False`` skips the RGB and
    depth datasets (faster when only trajectories are needed)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise ValueError(f"{path}: cannot open HDF5 file ({exc})") from None
    with f:
        check_schema(f.attrs, path)

        def get(key: str, optional: bool = False) -> np.ndarray | None:
            if key not in f:
                if optional:
                    return None
                raise ValueError(f"{path}: missing key '{key}'")
            return f[key][()]

        cams = list(f["observation"]) if "observation" in f else []
        obs = {c: f[f"observation/{c}"] for c in cams}
        rows = [
            [int(s), int(e), str(g), str(lt), str(rt), float(sc)]
            for s, e, g, lt, rt, sc in zip(
                get("stages/start"),
                get("stages/end"),
                f["stages/subgoal"].asstr()[()],
                f["stages/left"].asstr()[()],
                f["stages/right"].asstr()[()],
                get("stages/score"),
                strict=True,
            )
        ]
        return Episode(
            path=path,
            attrs={k: _attr(v) for k, v in f.attrs.items()},
            rgb={c: g["rgb"][()] for c, g in obs.items()} if images else {},
            depth={c: g["depth"][()] for c, g in obs.items() if images and "depth" in g},
            intrinsic_cv={c: g["intrinsic_cv"][()] for c, g in obs.items()},
            extrinsic_cv={c: g["extrinsic_cv"][()] for c, g in obs.items()},
            joint_action=get("joint_action/vector"),
            joint_state=get("joint_state/vector"),
            left_endpose=get("endpose/left_endpose"),
            right_endpose=get("endpose/right_endpose"),
            objects={n: f[f"objects/{n}/pose"][()] for n in f.get("objects", {})},
            stages=rows,
            stage_index=get("stage_index"),
            initial_state=get("stages/initial_state", optional=True),
            initial_action=get("stages/initial_action", optional=True),
            joints={n: f[f"joints/{n}/position"][()] for n in f.get("joints", {})},
            executed_action=get("joint_action/executed", optional=True),
            disturbances=_read_disturbances(f),
            recovery=_read_rows(f["stages/recovery"]) if "stages/recovery" in f else [],
        )


def _read_rows(g: h5py.Group) -> list[list]:
    """Rows ``[start, end, subgoal, left, right, score]`` of a group of row datasets."""
    return [
        [int(s), int(e), str(sg), str(lt), str(rt), float(sc)]
        for s, e, sg, lt, rt, sc in zip(
            g["start"][()],
            g["end"][()],
            g["subgoal"].asstr()[()],
            g["left"].asstr()[()],
            g["right"].asstr()[()],
            g["score"][()],
            strict=True,
        )
    ]


def _read_disturbances(f: h5py.File) -> list[dict[str, Any]]:
    """The ``disturbances/`` group as mappings of the Disturbance fields (none: empty)."""
    if "disturbances" not in f:
        return []
    g = f["disturbances"]
    kinds, bodies, sides = (g[k].asstr()[()] for k in ("kind", "body", "side"))
    return [
        {
            "kind": str(kinds[j]),
            "step": int(g["step"][j]),
            "duration": int(g["duration"][j]),
            "body": str(bodies[j]),
            "side": str(sides[j]),
            "force": tuple(float(v) for v in g["wrench"][j, 3:]),
            "torque": tuple(float(v) for v in g["wrench"][j, :3]),
            "point": tuple(float(v) for v in g["point"][j]),
        }
        for j in range(len(kinds))
    ]


# --------------------------------------------------------------------------- sidecars
def write_instructions(path: str | Path, seen: Sequence[str], unseen: Sequence[str] = ()) -> Path:
    """``instructions/episode{i}.json``: ``{"seen": [...], "unseen": [...]}`` (RoboTwin style)."""
    return write_json(path, {"seen": list(seen), "unseen": list(unseen)})


def write_stage_rows(path: str | Path, rows: Sequence[Sequence]) -> Path:
    """``stages/episode{i}.json``: the rows ``[start, end, subgoal, left, right, score]``."""
    check_rows(rows)
    clean = [[int(s), int(e), str(g), str(lt), str(rt), float(sc)] for s, e, g, lt, rt, sc in rows]
    return write_json(path, clean)


@dataclass(frozen=True)
class EpisodeLayout:
    """Paths of one ``<out>/<task>/<config_name>/`` generation directory."""

    out: Path
    task: str
    config_name: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "out", Path(self.out))

    @property
    def root(self) -> Path:
        return self.out / self.task / self.config_name

    @property
    def manifest(self) -> Path:
        return self.root / "manifest.json"

    def episode(self, i: int) -> Path:
        return self.root / "data" / f"episode{i}.hdf5"

    def video(self, i: int) -> Path:
        return self.root / "video" / f"episode{i}.mp4"

    def instructions(self, i: int) -> Path:
        return self.root / "instructions" / f"episode{i}.json"

    def stages(self, i: int) -> Path:
        return self.root / "stages" / f"episode{i}.json"

    def make_dirs(self) -> Path:
        for sub in ("data", "video", "instructions", "stages"):
            (self.root / sub).mkdir(parents=True, exist_ok=True)
        return self.root


def save_episode(
    layout: EpisodeLayout,
    index: int,
    recorder: EpisodeRecorder,
    annotations: Sequence[Sequence],
    meta: EpisodeMeta,
    instructions_seen: Sequence[str] | None = None,
    instructions_unseen: Sequence[str] = (),
    video: bool = True,
) -> dict[str, Path]:
    """Write all files of episode `index`: sidecars and video first, the HDF5 file last, so an
    existing episode file means a complete episode (for resuming)."""
    layout.make_dirs()
    seen = [meta.instruction] if instructions_seen is None else list(instructions_seen)
    written = {
        "instructions": write_instructions(layout.instructions(index), seen, instructions_unseen),
        "stages": write_stage_rows(layout.stages(index), annotations),
    }
    if video:
        written["video"] = recorder.write_video(layout.video(index))
    written["episode"] = recorder.write(layout.episode(index), annotations, meta)
    return written


# --------------------------------------------------------------------------- manifest
class EpisodeEntry(BaseModel):
    """One attempted seed: an episode written (index set) or a failure with its reason."""

    model_config = ConfigDict(extra="forbid")

    seed: int
    success: bool
    index: int | None = Field(None, description="episode{index} files, None if not written")
    reason: str | None = Field(None, description="why the expert or the rollout failed")
    frames: int | None = None
    timings: dict[str, float] = Field(default_factory=dict, description="seconds per phase")
    worker: str | None = Field(None, description="host:pid of the process that ran the seed")


class Manifest(BaseModel):
    """``manifest.json`` of a generation directory."""

    model_config = ConfigDict(extra="allow")

    schema_version: int = SCHEMA_VERSION
    task: str
    config_name: str
    package_version: str = Field(default_factory=package_version)
    config: dict[str, Any] = Field(default_factory=dict)
    scenario: dict[str, Any] | None = Field(
        None,
        description="the run's full scenario (bicoord_drake.scenario); None in manifests "
        "written before it was recorded",
    )
    created: float = Field(default_factory=time.time, description="Unix time")
    episodes: list[EpisodeEntry] = Field(default_factory=list)
    timings: dict[str, float] = Field(default_factory=dict, description="total seconds")

    @property
    def successes(self) -> list[EpisodeEntry]:
        return [e for e in self.episodes if e.success]

    @property
    def failures(self) -> list[EpisodeEntry]:
        return [e for e in self.episodes if not e.success]


def write_manifest(directory: str | Path, manifest: Manifest | Mapping[str, Any]) -> Path:
    """Write ``<directory>/manifest.json`` atomically."""
    m = manifest if isinstance(manifest, Manifest) else Manifest.model_validate(manifest)
    path = Path(directory) / "manifest.json"
    with atomic_path(path) as tmp:
        tmp.write_text(m.model_dump_json(indent=2) + "\n", encoding="utf-8")
    return path


def read_manifest(directory: str | Path) -> Manifest:
    """Read ``<directory>/manifest.json`` (or a path to the file itself)."""
    path = Path(directory)
    if path.is_dir():
        path = path / "manifest.json"
    if not path.is_file():
        raise ValueError(f"{path}: no manifest")
    try:
        m = Manifest.model_validate_json(path.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise ValueError(f"{path}: invalid manifest ({exc})") from None
    if m.schema_version != SCHEMA_VERSION:
        raise ValueError(
            f"{path}: manifest schema_version is {m.schema_version}, this reader reads "
            f"{SCHEMA_VERSION}"
        )
    return m
