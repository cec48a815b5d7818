"""Export episode files to a LeRobot dataset (needs the ``[lerobot]`` extra).

Codebase v3.0 is written by lerobot's own ``LeRobotDataset.create`` / ``add_frame`` /
``save_episode`` / ``finalize``. Codebase v2.1 (for tools that have not moved to v3.0) is written
here directly in the v2.1 layout, with lerobot's video encoder and episode statistics; lerobot
0.4 has no writer for it, only a converter from v2.1 to v3.0, which the tests run on our v2.1
output to check it.

Features of every frame ``t`` (A numbers are ``[left n joints, left gripper, right n joints,
right gripper]``, the recording robot's layout as in the episode file: A = 14 for the ViperX
pair; the dataset's ``robot_type`` is the embodiment)::

    observation.state          (A,)   measured joint state
    action                     (A,)   commanded joint targets and gripper openings (the
                                      expert's label: of an episode generated with action
                                      noise, ``joint_action/vector``, not what was executed)
    observation.endpose        (14,)  left TCP xyz + quaternion wxyz, then right (each
                                      quaternion's sign the one nearer its arm's home
                                      orientation: no jumps between q and -q)
    stage_index                (1,)   int64, the BiCoord stage the frame belongs to
    observation.images.{head,left,right}   videos (H, W, 3) (not with ``images=False``)
    observation.environment_state  (7 K,)  with ``environment_state=True``: the poses (xyz +
                               wxyz) of the scene's K task objects, from ``objects/<name>/pose``
                               (:mod:`bicoord_drake.data.environment_state`: order and names,
                               ``<object>_<field>`` or, where the episodes' object names
                               differ (jigsaw), ``object_<i>_<field>``; in ``meta/info.json``)
    disturbed                  (1,)   int8, only in a dataset with a disturbed episode
                               (generated with ``disturb``): 1 on the frames of a disturbance
                               and the expert's recovery from it (each recovery row of
                               ``stages/recovery``: frames [start, end), from the disturbance's
                               step to the expert's next plan), else 0 (every frame of a clean
                               episode). Training code can weight or filter these frames; a
                               LeRobot policy does not take it as an input (not an
                               ``observation.*`` feature)
    task                       the episode's instruction

The dataset's fps is the episodes' recorded rate (:func:`dataset_fps`; episodes of different
rates are refused). ``meta/bicoord_episodes.jsonl`` adds per episode its source file, seed
and stage rows ``[start, end, subgoal, left, right, score]`` (and for a disturbed episode its
``disturbances`` and ``recovery`` rows). The dataset is built in a
temporary directory beside ``out`` and renamed when complete.
"""

from __future__ import annotations

import ctypes
import json
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bicoord_drake.data.environment_state import (
    ENVIRONMENT_STATE,
    environment_state,
    feature_names,
    layout_names,
    state_objects,
)
from bicoord_drake.data.episode import Episode, read_episode
from bicoord_drake.data.readers import find_episode_files
from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.layout import POSE_SIZE, layout_of

CODEBASES = ("v3.0", "v2.1")
DTYPES = ("float32", "float64")
LEROBOT_PIN = "lerobot==0.4.4"
CAMERAS = {
    "head_camera": "observation.images.head",
    "left_camera": "observation.images.left",
    "right_camera": "observation.images.right",
}
"""Our camera names and their LeRobot feature keys."""
EXTRAS_FILE = "meta/bicoord_episodes.jsonl"
#: Debian 12 packages with FFmpeg's shared libraries, which torchcodec (lerobot's video decoder)
#: loads; the same list as ``.ci/run``.
FFMPEG_DEBIAN_PACKAGES = (
    "libavcodec59",
    "libavformat59",
    "libavutil57",
    "libswscale6",
    "libswresample4",
    "libavdevice59",
    "libavfilter8",
)
_FFMPEG_LIBRARY = re.compile(r"lib(av|sw|postproc)\w*\.so")
_V21_CHUNK = 1000
_V21_DATA = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet"
_V21_VIDEO = "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4"


def require_lerobot() -> None:
    """Raise ImportError saying how to install lerobot unless its dataset API imports."""
    try:
        import lerobot.datasets.lerobot_dataset  # noqa: F401
    except ImportError as exc:
        raise ImportError(
            f"the LeRobot export needs lerobot ({exc}); install it with "
            f"pip install -e '.[lerobot]' && pip install --no-deps {LEROBOT_PIN}"
        ) from None


class MissingFFmpegError(RuntimeError):
    """torchcodec, which decodes the dataset's videos, cannot load FFmpeg's shared libraries."""


def ffmpeg_install_command() -> str:
    """The apt command that installs the FFmpeg libraries torchcodec needs (Debian 12)."""
    return "sudo apt-get install -y " + " ".join(FFMPEG_DEBIAN_PACKAGES)


def ffmpeg_installed() -> bool:
    """Whether the dynamic loader finds FFmpeg's libavutil of a version torchcodec supports
    (FFmpeg 4 to 8: libavutil.so.56 to .60)."""
    for major in range(56, 61):
        try:
            ctypes.CDLL(f"libavutil.so.{major}")
        except OSError:
            continue
        return True
    return False


def require_video_decoder() -> None:
    """Raise :class:`MissingFFmpegError`, with the apt command that fixes it, if torchcodec
    cannot load FFmpeg's shared libraries (a fresh machine without them). Writing an export does
    not need them (lerobot encodes with PyAV, which bundles FFmpeg); loading it does."""
    try:
        import torchcodec.decoders  # noqa: F401
    except (OSError, RuntimeError) as exc:
        if not _FFMPEG_LIBRARY.search(str(exc)) or ffmpeg_installed():
            raise  # another cause (e.g. a torch/torchcodec mismatch): torchcodec's own message
        raise MissingFFmpegError(
            "decoding the LeRobot dataset's videos needs FFmpeg's shared libraries, which "
            "torchcodec (lerobot's video decoder) failed to load (the error above); install "
            f"them with\n\n    {ffmpeg_install_command()}\n\n(Debian 12 package names; "
            "torchcodec takes any FFmpeg 4 to 8 built with shared libraries)"
        ) from exc


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_lerobot` wrote."""

    root: Path
    repo_id: str
    codebase: str
    episodes: int
    frames: int
    sources: tuple[Path, ...]


# --------------------------------------------------------------------------- features
NUMERIC = ("observation.state", "action", "observation.endpose", "stage_index")
"""The numeric features every export has (``observation.environment_state`` and
``disturbed`` are optional: :data:`OPTIONAL`)."""
DISTURBED = "disturbed"
"""The per-frame marker of disturbed and recovery frames (only in a dataset with a disturbed
episode)."""
OPTIONAL = (ENVIRONMENT_STATE, DISTURBED)


def disturbed_frames(episode: Episode) -> np.ndarray:
    """(T,) int8: 1 on the frames of each recovery row of `episode` (``[start, end)``: from a
    disturbance's step to the end of the expert's recovery from it), 0 elsewhere; all 0 for a
    clean episode."""
    marker = np.zeros(episode.length, dtype=np.int8)
    for start, end, *_ in episode.recovery:
        marker[int(start) : int(end)] = 1
    return marker


def is_disturbed(episode: Episode) -> bool:
    """Whether `episode` was generated with disturbances (it records some)."""
    return bool(getattr(episode, "disturbances", None) or getattr(episode, "recovery", None))


def episode_state_objects(episode: Episode) -> tuple[str, ...]:
    """The objects of the episode's environment state (from its recorded scene), checked
    against the poses it recorded; ValueError saying what is missing."""
    scene = episode.scene
    if scene is None:
        raise ValueError(f"{episode.path}: no scene recorded; the environment state needs it")
    objects = state_objects(scene)
    missing = [n for n in objects if n not in episode.objects]
    if missing:
        raise ValueError(f"{episode.path}: no objects/<name>/pose recorded for {missing}")
    return objects


def lerobot_features(
    episode: Episode,
    dtype: str = "float32",
    *,
    images: bool = True,
    environment_state: bool = False,
    disturbed: bool = False,
) -> dict[str, dict[str, Any]]:
    """The LeRobot feature dictionary for episodes shaped like ``episode`` (its robot's action
    layout, its cameras and image size; its task objects with `environment_state`; the
    ``disturbed`` marker with `disturbed`)."""
    if dtype not in DTYPES:
        raise ValueError(f"unknown dtype {dtype!r}; choose one of {', '.join(DTYPES)}")
    layout = layout_of(episode.attrs["embodiment"])  # as Episode.layout

    def joints() -> dict[str, Any]:
        return {"dtype": dtype, "shape": (layout.action_size,), "names": layout.feature_names()}

    pose = ["x", "y", "z", "qw", "qx", "qy", "qz"]
    features: dict[str, dict[str, Any]] = {
        "observation.state": joints(),
        "action": joints(),
        "observation.endpose": {
            "dtype": dtype,
            "shape": (len(SIDES) * POSE_SIZE,),
            "names": [f"{side}_{p}" for side in SIDES for p in pose],
        },
        "stage_index": {"dtype": "int64", "shape": (1,), "names": None},
    }
    if environment_state:
        names = feature_names(episode_state_objects(episode))
        features[ENVIRONMENT_STATE] = {"dtype": dtype, "shape": (len(names),), "names": names}
    if disturbed:
        features[DISTURBED] = {"dtype": "int8", "shape": (1,), "names": None}
    for cam in sorted(episode.rgb) if images else ():
        if cam not in CAMERAS:
            raise ValueError(f"{episode.path}: unknown camera {cam!r}; known: {sorted(CAMERAS)}")
        h, w = episode.image(cam, 0).shape[:2]
        features[CAMERAS[cam]] = {
            "dtype": "video",
            "shape": (h, w, 3),
            "names": ["height", "width", "channels"],
        }
    return features


def frame_values(
    episode: Episode,
    t: int,
    dtype: str = "float32",
    objects: tuple[str, ...] | None = None,
    disturbed: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """The non-image feature values of frame ``t`` (with the environment state of `objects`
    if given, and the ``disturbed`` marker of frame t from `disturbed`, the episode's
    :func:`disturbed_frames`, if given)."""
    values = {
        "observation.state": episode.joint_state[t].astype(dtype),
        "action": episode.joint_action[t].astype(dtype),
        "observation.endpose": np.concatenate(
            [episode.left_endpose[t], episode.right_endpose[t]]
        ).astype(dtype),
        "stage_index": np.array([episode.stage_index[t]], dtype=np.int64),
    }
    if objects is not None:
        poses = {name: episode.objects[name][t] for name in objects}
        values[ENVIRONMENT_STATE] = environment_state(poses, objects, dtype)
    if disturbed is not None:
        values[DISTURBED] = np.array([disturbed[t]], dtype=np.int8)
    return values


def _objects(episode: Episode, features: dict[str, Any]) -> tuple[str, ...] | None:
    """The environment state's objects if `features` has it."""
    return episode_state_objects(episode) if ENVIRONMENT_STATE in features else None


def _marker(episode: Episode, features: Mapping[str, Any]) -> np.ndarray | None:
    """The episode's disturbed-frame marker if `features` has it."""
    return disturbed_frames(episode) if DISTURBED in features else None


def _frames(episode: Episode, features: dict[str, Any]) -> Iterator[dict[str, Any]]:
    dtype = features["action"]["dtype"]
    objects = _objects(episode, features)
    marker = _marker(episode, features)
    cams = [c for c in sorted(episode.rgb) if CAMERAS[c] in features]
    for t in range(episode.length):
        frame: dict[str, Any] = frame_values(episode, t, dtype, objects, marker)
        for cam in cams:
            frame[CAMERAS[cam]] = episode.image(cam, t)
        yield frame


def _episode_extras(index: int, episode: Episode) -> dict[str, Any]:
    extras = {
        "episode_index": index,
        "source": str(episode.path),
        "task_name": episode.task,
        "seed": episode.seed,
        "instruction": episode.instruction,
        "stages": episode.stages,
    }
    if is_disturbed(episode):  # a clean episode's line stays as it was
        extras["disturbances"] = [dict(d) for d in episode.disturbances]
        extras["recovery"] = episode.recovery
    return extras


# --------------------------------------------------------------------------- inputs
def _integer_fps(episode: Episode) -> int:
    fps = episode.fps
    if fps != int(fps):
        raise ValueError(f"{episode.path}: LeRobot needs an integer fps, the episode has {fps}")
    return int(fps)


def dataset_fps(episodes: Sequence[Episode]) -> int:
    """The dataset's fps: the rate the episodes were recorded at (their ``fps`` attribute),
    the same for all; a ValueError naming two episodes of different rates otherwise."""
    first = episodes[0]
    for episode in episodes:
        if _integer_fps(episode) != _integer_fps(first):
            raise ValueError(
                f"the episodes were recorded at different rates: {episode.path} at "
                f"{episode.fps:g} Hz, {first.path} at {first.fps:g} Hz; a LeRobot dataset has "
                "one fps: export each rate to its own dataset"
            )
    return _integer_fps(first)


def load_episodes(
    paths: Iterable[str | Path],
    *,
    images: bool = True,
    environment_state: bool = False,
    max_episodes: int | None = None,
) -> list[Episode]:
    """Read every episode file under ``paths`` (only the first `max_episodes` in natural order,
    if given) and check they can share one dataset (with `images`, the export's cameras; with
    `environment_state`, its task objects)."""
    files, errors = find_episode_files(paths)
    if errors:
        raise ValueError("; ".join(errors))
    if max_episodes is not None:
        if max_episodes < 1:
            raise ValueError(f"max_episodes must be at least 1, got {max_episodes}")
        if len(files) < max_episodes:
            raise ValueError(f"{max_episodes} episodes asked for, {len(files)} found")
        files = files[:max_episodes]
    episodes = [read_episode(f, images=images) for f in files]
    if not episodes:
        raise ValueError("no episode files to export")
    first = episodes[0]
    options = {"images": images, "environment_state": environment_state}

    def features(episode: Episode) -> dict[str, Any]:  # the state's names may vary (jigsaw)
        out = lerobot_features(episode, **options)
        if ENVIRONMENT_STATE in out:
            out[ENVIRONMENT_STATE] = {**out[ENVIRONMENT_STATE], "names": None}
        return out

    dataset_fps(episodes)
    reference = features(first)
    for episode in episodes:
        if images and not episode.rgb:
            raise ValueError(
                f"{episode.path}: no camera images (generated with --no-render?); "
                "export without them with images=False (--no-images)"
            )
        if features(episode) != reference:
            raise ValueError(
                f"{episode.path}: cameras, image sizes, embodiment or task objects differ from "
                f"{first.path}"
            )
    return episodes


def default_repo_id(episodes: Sequence[Episode]) -> str:
    """``bicoord_drake/<task>`` for one task, ``bicoord_drake/mixed`` for several."""
    tasks = sorted({e.task for e in episodes})
    return f"bicoord_drake/{tasks[0] if len(tasks) == 1 else 'mixed'}"


# --------------------------------------------------------------------------- export
def export_lerobot(
    paths: Iterable[str | Path],
    out: str | Path,
    *,
    repo_id: str | None = None,
    codebase: str = "v3.0",
    dtype: str = "float32",
    vcodec: str = "libsvtav1",
    images: bool = True,
    environment_state: bool = False,
    max_episodes: int | None = None,
) -> ExportResult:
    """Export the episodes under ``paths`` into a new LeRobot dataset directory ``out``.

    ``dtype`` float64 keeps the stored states, actions and poses bit-exact; lerobot hands
    items out as float32 either way (what policies read). ``images=False`` leaves the cameras
    out (a state-only dataset; episodes generated without rendering need it);
    ``environment_state`` adds ``observation.environment_state``, the task objects' poses;
    ``max_episodes`` exports only the first that many episode files (natural order: the first
    seeds of a generated directory). When an episode was generated with disturbances, every
    frame gets the ``disturbed`` marker (:func:`disturbed_frames`; 0 throughout a clean
    episode); without one the dataset is what it was before the marker existed. Raises
    ``FileExistsError`` if ``out`` exists, ``ValueError`` on bad input.
    """
    if codebase not in CODEBASES:
        raise ValueError(f"unknown codebase {codebase!r}; choose one of {', '.join(CODEBASES)}")
    if dtype not in DTYPES:
        raise ValueError(f"unknown dtype {dtype!r}; choose one of {', '.join(DTYPES)}")
    out = Path(out)
    if out.exists():
        raise FileExistsError(f"{out} exists; remove it or choose another output directory")
    require_lerobot()
    episodes = load_episodes(
        paths, images=images, environment_state=environment_state, max_episodes=max_episodes
    )
    features = lerobot_features(
        episodes[0],
        dtype,
        images=images,
        environment_state=environment_state,
        disturbed=any(is_disturbed(e) for e in episodes),
    )
    if environment_state:
        names = layout_names([episode_state_objects(e) for e in episodes])
        features[ENVIRONMENT_STATE] = {**features[ENVIRONMENT_STATE], "names": names}
    repo_id = repo_id or default_repo_id(episodes)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.", suffix=".tmp"))
    root = staging / "dataset"
    try:
        writer = _write_v30 if codebase == "v3.0" else _write_v21
        writer(episodes, root, repo_id, features, vcodec)
        _write_jsonl(root / EXTRAS_FILE, [_episode_extras(i, e) for i, e in enumerate(episodes)])
        root.rename(out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return ExportResult(
        root=out,
        repo_id=repo_id,
        codebase=codebase,
        episodes=len(episodes),
        frames=sum(e.length for e in episodes),
        sources=tuple(e.path for e in episodes),
    )


def _write_jsonl(path: Path, rows: Iterable[dict[str, Any]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        for row in rows:
            fh.write(json.dumps(row, ensure_ascii=False) + "\n")


def _write_v30(
    episodes: Sequence[Episode],
    root: Path,
    repo_id: str,
    features: dict[str, dict[str, Any]],
    vcodec: str,
) -> None:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    dataset = LeRobotDataset.create(
        repo_id=repo_id,
        fps=dataset_fps(episodes),
        features=features,
        root=root,
        robot_type=episodes[0].attrs["embodiment"],
        use_videos=True,
        vcodec=vcodec,
    )
    try:
        for episode in episodes:
            for frame in _frames(episode, features):
                dataset.add_frame({**frame, "task": episode.instruction})
            # lerobot stores a (1,)-shaped feature as a scalar column and hands each (1,) array
            # to int(), which numpy >= 2.3 refuses: give it the scalars it stores.
            buffer = dataset.episode_buffer
            for key in ("stage_index", DISTURBED):
                if key in buffer:
                    buffer[key] = [int(v[0]) for v in buffer[key]]
            dataset.save_episode(parallel_encoding=False)
    finally:
        dataset.finalize()


def _write_v21(
    episodes: Sequence[Episode],
    root: Path,
    repo_id: str,
    features: dict[str, dict[str, Any]],
    vcodec: str,
) -> None:
    """The v2.1 layout: one parquet file and one MP4 per camera per episode, JSON-lines meta."""
    import datasets
    from lerobot.datasets.compute_stats import compute_episode_stats
    from lerobot.datasets.utils import DEFAULT_FEATURES, get_hf_features_from_features
    from lerobot.datasets.video_utils import encode_video_frames, get_video_info
    from PIL import Image

    fps = dataset_fps(episodes)
    dtype = features["action"]["dtype"]
    features = {**features, **DEFAULT_FEATURES}
    numeric = [k for k in (*NUMERIC, *OPTIONAL) if k in features]
    video_keys = [k for k, f in features.items() if f["dtype"] == "video"]
    table_features = {k: f for k, f in features.items() if f["dtype"] != "video"}
    hf_features = get_hf_features_from_features(table_features)
    tasks: dict[str, int] = {}
    episode_rows, stats_rows = [], []
    total = 0
    for index, episode in enumerate(episodes):
        task_index = tasks.setdefault(episode.instruction, len(tasks))
        T = episode.length
        objects, marker = _objects(episode, features), _marker(episode, features)
        values = [frame_values(episode, t, dtype, objects, marker) for t in range(T)]
        columns: dict[str, Any] = {k: np.stack([v[k] for v in values]) for k in numeric}
        columns["timestamp"] = (np.arange(T) / fps).astype(np.float32).reshape(T, 1)
        columns["frame_index"] = np.arange(T, dtype=np.int64).reshape(T, 1)
        columns["episode_index"] = np.full((T, 1), index, dtype=np.int64)
        columns["index"] = np.arange(total, total + T, dtype=np.int64).reshape(T, 1)
        columns["task_index"] = np.full((T, 1), task_index, dtype=np.int64)
        chunk = index // _V21_CHUNK
        data_path = root / _V21_DATA.format(episode_chunk=chunk, episode_index=index)
        data_path.parent.mkdir(parents=True, exist_ok=True)
        table = {
            k: columns[k][:, 0] if features[k]["shape"] == (1,) else list(columns[k])
            for k in table_features
        }
        datasets.Dataset.from_dict(table, features=hf_features).to_parquet(str(data_path))

        frame_paths: dict[str, list[str]] = {}
        with tempfile.TemporaryDirectory(dir=root) as frames_dir:
            for cam in sorted(episode.rgb):
                key = CAMERAS[cam]
                if key not in features:
                    continue
                cam_dir = Path(frames_dir) / key
                cam_dir.mkdir()
                frame_paths[key] = []
                for t in range(T):
                    png = cam_dir / f"frame-{t:06d}.png"
                    Image.fromarray(episode.image(cam, t)).save(png, compress_level=1)
                    frame_paths[key].append(str(png))
                video = root / _V21_VIDEO.format(
                    episode_chunk=chunk, video_key=key, episode_index=index
                )
                encode_video_frames(cam_dir, video, fps, vcodec=vcodec)
            stats = compute_episode_stats({**columns, **frame_paths}, features)
        stats_rows.append({"episode_index": index, "stats": _jsonable(stats)})
        episode_rows.append({"episode_index": index, "tasks": [episode.instruction], "length": T})
        total += T

    for key in video_keys:
        video = root / _V21_VIDEO.format(episode_chunk=0, video_key=key, episode_index=0)
        features[key]["info"] = get_video_info(video)
    info = {
        "codebase_version": "v2.1",
        "robot_type": episodes[0].attrs["embodiment"],
        "total_episodes": len(episodes),
        "total_frames": total,
        "total_tasks": len(tasks),
        "total_videos": len(episodes) * len(video_keys),
        "total_chunks": (len(episodes) - 1) // _V21_CHUNK + 1,
        "chunks_size": _V21_CHUNK,
        "fps": fps,
        "splits": {"train": f"0:{len(episodes)}"},
        "data_path": _V21_DATA,
        "video_path": _V21_VIDEO,
        "features": _jsonable(features),
    }
    (root / "meta").mkdir(parents=True, exist_ok=True)
    (root / "meta/info.json").write_text(json.dumps(info, indent=4) + "\n", encoding="utf-8")
    _write_jsonl(root / "meta/episodes.jsonl", episode_rows)
    _write_jsonl(root / "meta/episodes_stats.jsonl", stats_rows)
    _write_jsonl(
        root / "meta/tasks.jsonl", [{"task_index": i, "task": t} for t, i in tasks.items()]
    )


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


# --------------------------------------------------------------------------- checking
@dataclass(frozen=True)
class ExportCheck:
    """How a LeRobot dataset loaded with lerobot compares with its source episodes."""

    episodes: int
    frame_counts: tuple[tuple[int, int], ...]
    """(exported, source) frames per episode"""
    numeric_exact: dict[str, bool]
    """per numeric feature: equal to the source cast to the dataset's dtype, bit for bit"""
    image_mean_abs_error: float
    """mean |exported - source| over the compared images, in 0..255 levels"""
    image_max_mean_abs_error: float
    """the worst compared frame's mean |error|"""
    images_compared: int

    @property
    def ok(self) -> bool:
        """Counts match and every numeric feature is exact (images are judged by the caller)."""
        return all(a == b for a, b in self.frame_counts) and all(self.numeric_exact.values())


def load_lerobot(root: str | Path, repo_id: str) -> Any:
    """``LeRobotDataset(repo_id, root=root)`` decoding videos with torchcodec, offline.
    Raises :class:`MissingFFmpegError` if torchcodec cannot load FFmpeg's libraries."""
    require_lerobot()
    require_video_decoder()
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    return LeRobotDataset(repo_id, root=root, video_backend="torchcodec")


def check_export(
    dataset: Any, episodes: Sequence[Episode], images_per_episode: int | None = 3
) -> ExportCheck:
    """Compare a loaded LeRobot dataset with its source episodes (in export order).

    Numeric features are compared in full; images on ``images_per_episode`` evenly spaced frames
    per episode (all frames if None).
    """
    numeric = tuple(k for k in (*NUMERIC, *OPTIONAL) if k in dataset.meta.features)
    dtype = dataset.meta.features["action"]["dtype"]
    # read the arrow columns (datasets' numpy formatter imports a torchvision API gone in 0.25+)
    table = dataset.hf_dataset.data
    columns = {
        k: np.array(table.column(k).to_pylist(), dtype=dataset.meta.features[k]["dtype"])
        for k in (*numeric, "episode_index", "frame_index")
    }
    if dataset.meta.total_episodes != len(episodes):
        raise ValueError(
            f"the dataset has {dataset.meta.total_episodes} episodes, the source {len(episodes)}"
        )
    counts, exact = [], dict.fromkeys(numeric, True)
    errors: list[float] = []
    for index, episode in enumerate(episodes):
        rows = np.flatnonzero(columns["episode_index"].reshape(-1) == index)
        counts.append((len(rows), episode.length))
        if len(rows) != episode.length:
            for key in numeric:
                exact[key] = False
            continue
        order = rows[np.argsort(columns["frame_index"].reshape(-1)[rows])]
        state_of = episode_state_objects(episode) if ENVIRONMENT_STATE in numeric else None
        marker = disturbed_frames(episode) if DISTURBED in numeric else None
        source = [frame_values(episode, t, dtype, state_of, marker) for t in range(episode.length)]
        for key in numeric:
            want = np.stack([s[key] for s in source])
            got = columns[key][order].reshape(want.shape)
            exact[key] &= got.dtype == want.dtype and np.array_equal(got, want)
        last = episode.length - 1
        picks = (
            range(last + 1)
            if images_per_episode is None
            else np.linspace(0, last, images_per_episode)
        )
        for t in sorted({int(round(p)) for p in picks}):
            item = dataset[int(order[t])]
            for cam in sorted(episode.rgb):
                if CAMERAS[cam] not in dataset.meta.features:
                    continue
                got = np.asarray(item[CAMERAS[cam]]).transpose(1, 2, 0) * 255.0
                errors.append(float(np.mean(np.abs(got - episode.image(cam, t)))))
    return ExportCheck(
        episodes=len(episodes),
        frame_counts=tuple(counts),
        numeric_exact=exact,
        image_mean_abs_error=float(np.mean(errors)) if errors else float("nan"),
        image_max_mean_abs_error=float(np.max(errors)) if errors else float("nan"),
        images_compared=len(errors),
    )


def convert_v21_to_v30(root: str | Path, repo_id: str, work_dir: str | Path) -> Path:
    """Convert a v2.1 export with lerobot's own converter (offline) into ``work_dir``; returns
    the converted dataset's root. The v2.1 directory itself is left untouched."""
    require_lerobot()
    from lerobot.datasets.v30.convert_dataset_v21_to_v30 import convert_dataset

    target = Path(work_dir) / repo_id
    if target.exists():
        raise FileExistsError(f"{target} exists")
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copytree(root, target)
    convert_dataset(repo_id, root=work_dir, push_to_hub=False)
    return target
