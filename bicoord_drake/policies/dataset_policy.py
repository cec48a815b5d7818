"""A LeRobot dataset played back as a policy: ``load_policy("lerobot-dataset:DIR")``,
``--policy lerobot-dataset:DIR``.

``DIR`` is a dataset written by this project's LeRobot export (``scripts/export.py --to
lerobot``, codebase v3.0; a v2.1 export is converted first with lerobot's converter,
:func:`bicoord_drake.data.export.convert_v21_to_v30`). Its frames and actions are read with
lerobot's own ``LeRobotDataset(repo_id, root=DIR)``. After each reset (``bind(env)``) the policy
finds the dataset's episode of the rollout's task and seed and then returns that episode's
``action`` column one frame per control step, from the rollout's first frame (its stage's start
in a stage rollout, up to that stage's end), holding the last action when the episode runs out.
It is the proof that the export, the rate and the control loop line up: played back through
``scripts/evaluate.py`` on the demonstrations' own seeds (``--data`` with the episode files the
dataset was exported from), every episode must succeed again.

Where the seed is: LeRobot's own metadata (``meta/info.json``, ``meta/episodes/``) has no field
for it, so the exporter writes ``meta/bicoord_episodes.jsonl``, one line per episode with its
``episode_index``, ``task_name``, ``seed``, ``source`` (the episode file), ``instruction`` and
stage rows. That file maps (task, seed) to the dataset's episode index; a seed the dataset lacks
fails ``bind`` naming the seeds of that task it has (and the tasks, if it has none of that one).
Two episodes of the same task and seed (e.g. a plain and a randomized scene) are told apart by
the source file of the environment's demonstration.

Checked at ``bind``: the environment commands joint targets (``qpos``: the export's ``action``),
its action size is the dataset's, and its control rate is the dataset's ``fps``. Every step the
observed joint state is compared with the dataset's ``observation.state`` of the same frame
(frame ``t`` is the observation *before* action ``t``), and with the frames one before and one
after, so that a one-step shift between observations and actions shows as a better match at a
neighbour; so are the end poses and the environment state (the task objects' poses) where the
dataset has them, the other inputs of a state-based policy; with ``images=1`` the rendered
cameras are compared the same way with the dataset's decoded video frames (mean |error| in
0..255 levels; cameras of another size are skipped).
:attr:`DatasetPlaybackPolicy.alignments` has the figures of every rollout, ``close()`` prints
their summary on stderr, and ``state_tolerance`` turns a state error above it into a failure of
the step, naming the frame, the error and the best-matching neighbour.

The export's ``action`` is the expert's label (``joint_action/vector``): an episode generated
with action noise executed other actions, so its playback need not reproduce it (the ``replay``
built-in replays the executed ones from the episode file).

Spec options, after a ``?``: ``lerobot-dataset:DIR?state_tolerance=1e-3&images=1``; in Python
also keyword arguments (``repo_id``, ``action_size``). Needs lerobot (the ``[lerobot]`` extra;
decoding videos for ``images=1`` needs FFmpeg's shared libraries, see the README).
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bicoord_drake.data.environment_state import ENVIRONMENT_STATE
from bicoord_drake.policies import PolicyLoadError, env_action_size, spec_options
from bicoord_drake.policies.lerobot_policy import ENDPOSE, observation_vector

PREFIX = "lerobot-dataset:"
#: The exporter's per-episode metadata (source file, task, seed, stage rows).
EXTRAS_FILE = "meta/bicoord_episodes.jsonl"
STATE = "observation.state"
ACTION = "action"
#: Our camera names and the dataset's video features (as in the export).
CAMERAS = {
    "head_camera": "observation.images.head",
    "left_camera": "observation.images.left",
    "right_camera": "observation.images.right",
}
#: Frames compared around the played one: one before, the same, one after.
SHIFTS = (-1, 0, 1)
#: The other observation vectors compared when the dataset has them (what a state-based policy
#: takes besides the joints): their names in the alignment and their dataset features.
VECTORS = {"end poses": ENDPOSE, "environment state": ENVIRONMENT_STATE}


def _flag(value: str) -> bool:
    text = value.strip().lower()
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off", ""):
        return False
    raise ValueError(value)


#: Spec options (after ``?``) and their types.
OPTIONS = {"state_tolerance": float, "images": _flag, "repo_id": str}


def parse_spec(spec: str) -> tuple[Path, dict[str, Any]]:
    """``"lerobot-dataset:DIR?k=v"`` -> (DIR, options); PolicyLoadError for anything else."""
    body = spec[len(PREFIX) :].strip() if spec.startswith(PREFIX) else spec.strip()
    body, _, query = body.partition("?")
    if not body:
        raise PolicyLoadError(
            f"policy {spec!r}: give a LeRobot dataset directory after {PREFIX!r} "
            "(a scripts/export.py --to lerobot output)"
        )
    options = spec_options(spec, query, OPTIONS)
    return Path(body).expanduser(), options


@dataclass
class EpisodeRecord:
    """One line of :data:`EXTRAS_FILE`: a dataset episode and where it came from."""

    index: int
    task: str
    seed: int
    source: str
    stages: list[list[Any]]


@dataclass
class Alignment:
    """How one rollout's observations compared with the played episode's frames.

    ``state_error[s]``: the largest |observed joint state - the dataset's ``observation.state``
    of frame t + s| over the played frames ``t`` (rad or opening units), for s = -1, 0, +1
    (s = 0: the frame whose action is played; a neighbour matching better means a shift).
    ``image_error[s]``: the mean |rendered - decoded| of the compared camera images, 0..255
    levels (None: not compared). ``vector_error[name][s]``: as ``state_error`` for the other
    observation vectors of :data:`VECTORS` the dataset and the observation both have (end
    poses: m and quaternion units; environment state: the objects' poses, as a state-based
    policy gets them)."""

    task: str
    seed: int
    episode_index: int
    start_frame: int
    frames: int = 0
    state_error: dict[int, float] = field(default_factory=lambda: dict.fromkeys(SHIFTS, 0.0))
    image_error: dict[int, float] | None = None
    images_compared: int = 0
    vector_error: dict[str, dict[int, float]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["state_error"] = {str(k): v for k, v in self.state_error.items()}
        out["vector_error"] = {
            name: {str(k): v for k, v in errors.items()}
            for name, errors in self.vector_error.items()
        }
        if self.image_error is not None:
            out["image_error"] = {str(k): v for k, v in self.image_error.items()}
        return out

    def text(self) -> str:
        s = self.state_error
        line = (
            f"{self.task} seed {self.seed} (dataset episode {self.episode_index}): "
            f"{self.frames} frames, max |joint state - frame t| {s[0]:.2e} "
            f"(frame t-1: {s[-1]:.2e}, t+1: {s[1]:.2e})"
        )
        if self.image_error is not None:
            i = self.image_error
            line += (
                f"; images mean |error| {i[0]:.2f} levels (t-1: {i[-1]:.2f}, t+1: {i[1]:.2f}) "
                f"over {self.images_compared} frames"
            )
        for name, e in self.vector_error.items():
            line += f"; max |{name} - frame t| {e[0]:.2e} (t-1: {e[-1]:.2e}, t+1: {e[1]:.2e})"
        return line


def _require_lerobot() -> None:
    from bicoord_drake.policies.lerobot_policy import preload_triton

    preload_triton()  # before lerobot imports torch, in a process that may have rendered
    try:
        import lerobot.datasets.lerobot_dataset  # noqa: F401
    except ImportError as exc:
        raise PolicyLoadError(
            f"the lerobot-dataset policy reads the dataset with lerobot ({exc}); install it with "
            "pip install -e '.[lerobot]' && pip install --no-deps lerobot==0.4.4"
        ) from None


def read_records(root: Path) -> list[EpisodeRecord]:
    """The episodes of :data:`EXTRAS_FILE` (PolicyLoadError when it is missing or unreadable:
    LeRobot's own metadata does not record seeds)."""
    path = root / EXTRAS_FILE
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError:
        raise PolicyLoadError(
            f"lerobot-dataset policy: {path} is missing: the dataset was not written by "
            "scripts/export.py (LeRobot's own metadata records no seed; the exporter keeps each "
            "episode's task and seed there)"
        ) from None
    records = []
    try:
        for line in lines:
            if not line.strip():
                continue
            row = json.loads(line)
            records.append(
                EpisodeRecord(
                    index=int(row["episode_index"]),
                    task=str(row["task_name"]),
                    seed=int(row["seed"]),
                    source=str(row.get("source", "")),
                    stages=list(row.get("stages") or []),
                )
            )
    except (ValueError, KeyError, TypeError) as exc:
        raise PolicyLoadError(
            f"lerobot-dataset policy: {path} is not the exporter's episode list "
            f"({type(exc).__name__}: {exc})"
        ) from None
    return records


def _seed_list(seeds: list[int]) -> str:
    """``0, 1, 2`` (the first 20, then how many more)."""
    seeds = sorted(set(seeds))
    shown = ", ".join(map(str, seeds[:20]))
    return shown + (f" and {len(seeds) - 20} more" if len(seeds) > 20 else "")


def _bicoord_env(env: Any) -> Any:
    """The :class:`bicoord_drake.env.Env` of `env` (itself, or a Gymnasium environment's)."""
    unwrapped = getattr(env, "unwrapped", env)
    return getattr(unwrapped, "bicoord_env", env)


class DatasetPlaybackPolicy:
    """The actions of a LeRobot export, played back on the episodes' own seeds (see the module
    docstring).

    `root`: the dataset directory; `repo_id`: the name lerobot gives it (default
    ``bicoord_drake/<task>``, as the exporter's; only a label for a local root);
    `state_tolerance`: fail a step whose observed joint state departs from the dataset's frame by
    more (None: only measured); `images`: also compare camera images with the decoded video
    frames; `action_size`: the environment's, checked at load.
    """

    def __init__(
        self,
        root: str | Path,
        *,
        repo_id: str | None = None,
        state_tolerance: float | None = None,
        images: bool = False,
        action_size: int | None = None,
    ) -> None:
        self.root = Path(root).expanduser()
        where = f"lerobot-dataset policy {self.root}"
        try:
            info = json.loads((self.root / "meta" / "info.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            raise PolicyLoadError(
                f"{where}: not a LeRobot dataset (no readable meta/info.json)"
            ) from None
        version = str(info.get("codebase_version", ""))
        if version != "v3.0":
            raise PolicyLoadError(
                f"{where}: codebase {version or 'unknown'}; lerobot 0.4 reads v3.0 (convert a "
                "v2.1 export with bicoord_drake.data.export.convert_v21_to_v30, or export again "
                "with --codebase v3.0)"
            )
        if state_tolerance is not None and not state_tolerance > 0:
            raise PolicyLoadError(f"{where}: state_tolerance must be > 0, not {state_tolerance}")
        self.records = read_records(self.root)
        if not self.records:
            raise PolicyLoadError(f"{where}: {EXTRAS_FILE} lists no episode")
        _require_lerobot()
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        tasks = sorted({r.task for r in self.records})
        self.repo_id = repo_id or f"bicoord_drake/{tasks[0] if len(tasks) == 1 else 'mixed'}"
        try:
            self.dataset = LeRobotDataset(self.repo_id, root=self.root)
        except Exception as exc:
            raise PolicyLoadError(
                f"{where}: lerobot cannot load it ({type(exc).__name__}: {exc})"
            ) from None
        features = self.dataset.meta.features
        for key in (ACTION, STATE):
            if key not in features:
                raise PolicyLoadError(f"{where}: it has no {key!r} feature")
        self.fps = float(self.dataset.meta.fps)
        self.action_size = int(np.prod(features[ACTION]["shape"]))
        if action_size is not None and int(action_size) != self.action_size:
            raise PolicyLoadError(
                f"{where}: its actions have {self.action_size} numbers, the environment's have "
                f"{int(action_size)}"
            )
        self._columns = self._read_columns()
        known = set(self._columns)
        missing = sorted({r.index for r in self.records} - known)
        if missing:
            raise PolicyLoadError(
                f"{where}: {EXTRAS_FILE} lists episodes {missing} the dataset does not have"
            )
        self.state_tolerance = state_tolerance
        self.images = bool(images)
        self.video_keys = list(self.dataset.meta.video_keys)
        if self.images:
            from bicoord_drake.data.export import require_video_decoder

            require_video_decoder()
        self._by_seed: dict[tuple[str, int], list[EpisodeRecord]] = defaultdict(list)
        for record in self.records:
            self._by_seed[(record.task, record.seed)].append(record)
        #: The figures of every rollout played so far (:class:`Alignment`), in order.
        self.alignments: list[Alignment] = []
        self._played: EpisodeRecord | None = None
        self._actions = np.zeros((0, self.action_size))
        self._hold: np.ndarray | None = None
        self._t = 0
        self._end = 0
        self._image_counts = dict.fromkeys(SHIFTS, 0)
        self._decoded: dict[int, dict[str, Any]] = {}  # the frames around the played one

    def __repr__(self) -> str:
        return f"DatasetPlaybackPolicy({str(self.root)!r})"

    # ---------------------------------------------------------------- dataset
    def _read_columns(self) -> dict[int, dict[str, Any]]:
        """Per episode index: its ``action`` and ``observation.state`` in frame order and the
        dataset's row index of each frame."""
        table = self.dataset.hf_dataset.data  # the arrow table (no per-item decoding)

        def column(name: str, dtype: Any = float) -> np.ndarray:
            return np.asarray(table.column(name).to_pylist(), dtype=dtype)

        episodes = column("episode_index", np.int64).reshape(-1)
        frames = column("frame_index", np.int64).reshape(-1)
        rows = column("index", np.int64).reshape(-1)
        actions = column(ACTION).reshape(len(episodes), -1)
        states = column(STATE).reshape(len(episodes), -1)
        vectors = {
            name: column(key).reshape(len(episodes), -1)
            for name, key in VECTORS.items()
            if key in table.column_names
        }
        out = {}
        for index in np.unique(episodes):
            mine = np.flatnonzero(episodes == index)
            order = mine[np.argsort(frames[mine])]
            if not np.array_equal(frames[order], np.arange(len(order))):
                raise PolicyLoadError(
                    f"lerobot-dataset policy {self.root}: episode {int(index)} has frames "
                    f"missing or repeated (frame_index is not 0..{len(order) - 1})"
                )
            out[int(index)] = {
                "action": actions[order],
                "state": states[order],
                "rows": rows[order],
                "vectors": {name: values[order] for name, values in vectors.items()},
            }
        return out

    @property
    def seeds(self) -> dict[str, list[int]]:
        """The seeds the dataset has, per task."""
        out: dict[str, list[int]] = defaultdict(list)
        for record in self.records:
            out[record.task].append(record.seed)
        return {task: sorted(set(seeds)) for task, seeds in sorted(out.items())}

    def missing_seeds(self, task: str, seeds: list[int]) -> str | None:
        """Why some of `seeds` of `task` cannot be played back (None when all can)."""
        have = self.seeds.get(task)
        if not have:
            return (
                f"the dataset {self.root} has no episode of {task} (it has "
                + "; ".join(f"{t}: seeds {_seed_list(s)}" for t, s in self.seeds.items())
                + ")"
            )
        lacking = sorted(set(int(s) for s in seeds) - set(have))
        if not lacking:
            return None
        return (
            f"the dataset {self.root} has no {task} episode of seed{'s' * (len(lacking) > 1)} "
            f"{_seed_list(lacking)}; its {task} seeds are {_seed_list(have)}"
        )

    def find(self, task: str, seed: int, source: str | Path | None = None) -> EpisodeRecord:
        """The dataset's episode of `task` and `seed` (of `source`, the environment's episode
        file, where the dataset has several); ValueError naming the seeds it has."""
        problem = self.missing_seeds(task, [seed])
        if problem:
            raise ValueError(f"lerobot-dataset policy: {problem} ({EXTRAS_FILE})")
        found = self._by_seed[(task, int(seed))]
        if len(found) > 1 and source is not None:
            name = Path(source)
            same = [r for r in found if Path(r.source) == name]
            same = same or [r for r in found if Path(r.source).resolve() == name.resolve()]
            if len(same) == 1:
                return same[0]
        if len(found) > 1:
            raise ValueError(
                f"lerobot-dataset policy: the dataset {self.root} has {len(found)} episodes of "
                f"{task} seed {seed} (episodes {[r.index for r in found]}, from "
                f"{[r.source for r in found]}); evaluate with --data on one of those files"
            )
        return found[0]

    def frames(
        self, task: str, seed: int, source: str | Path | None = None
    ) -> dict[str, np.ndarray]:
        """The dataset's episode of `task` and `seed` (:meth:`find`) in frame order: its
        ``action`` (T, A), ``state`` (``observation.state``, T x A) and the :data:`VECTORS` it
        has, under their names, as float64."""
        columns = self._columns[self.find(task, seed, source).index]
        return {
            "action": np.asarray(columns["action"], dtype=float),
            "state": np.asarray(columns["state"], dtype=float),
            **{k: np.asarray(v, dtype=float) for k, v in columns["vectors"].items()},
        }

    # ---------------------------------------------------------------- policy interface
    def bind(self, env: Any) -> None:
        """Find the episode of the rollout's task and seed; check the action mode, size and
        rate (the evaluation calls this after every reset)."""
        inner = _bicoord_env(env)
        mode = getattr(inner, "action_mode", "qpos")
        if mode != "qpos":
            raise ValueError(
                "the lerobot-dataset policy plays the export's joint targets: use "
                f"action_mode='qpos', not {mode!r}"
            )
        size = env_action_size(env)
        if size is not None and size != self.action_size:
            raise ValueError(
                f"lerobot-dataset policy {self.root}: its actions have {self.action_size} "
                f"numbers, the environment's have {size}"
            )
        rate = float(inner.config.control_rate)
        if abs(rate - self.fps) > 1e-9:
            raise ValueError(
                f"lerobot-dataset policy {self.root}: the dataset was recorded at "
                f"{self.fps:g} fps, the environment steps at {rate:g} Hz"
            )
        episode = getattr(inner, "episode", None)
        source = getattr(episode, "path", None)
        record = self.find(inner.task.name, int(inner.seed), source)
        columns = self._columns[record.index]
        start = int(getattr(inner, "start_frame", 0) or 0)
        end = len(columns["action"])
        stage = getattr(inner, "stage", None)
        if stage is not None and stage < len(record.stages):
            end = min(end, int(record.stages[stage][1]))
        self._played = record
        self._actions = np.asarray(columns["action"], dtype=float)
        self._t, self._end = start, end
        self._hold = np.asarray(inner.action, dtype=float).copy()
        self.alignments.append(Alignment(record.task, record.seed, record.index, start))
        self._image_counts = dict.fromkeys(SHIFTS, 0)
        self._decoded = {}

    def reset(self, instruction: str) -> None:
        if self._played is None:
            raise RuntimeError(
                "the lerobot-dataset policy must be bound to an environment (bind(env)) to know "
                "the rollout's seed"
            )

    def act(self, obs: dict[str, Any]) -> np.ndarray:
        """The dataset's action of the current frame (then the next one); the last action once
        the episode (or the stage) has run out."""
        if self._played is None:
            raise RuntimeError("the lerobot-dataset policy must be bound first (bind(env))")
        if self._t < self._end:
            self._compare(obs, self._t)
            self._hold = self._actions[self._t].copy()
            self._t += 1
        return self._hold.copy()

    def close(self) -> None:
        """Print the rollouts' alignment summary on stderr (if any were played)."""
        if self.alignments:
            worst = max(a.state_error[0] for a in self.alignments)
            print(
                f"lerobot-dataset playback of {self.root}: {len(self.alignments)} rollouts, "
                f"largest |observed joint state - the dataset's frame| {worst:.2e}",
                file=sys.stderr,
            )
            for alignment in self.alignments:
                print(f"  {alignment.text()}", file=sys.stderr)
        self.alignments = []

    # ---------------------------------------------------------------- alignment
    def _compare(self, obs: dict[str, Any], t: int) -> None:
        """Compare the observation before action `t` with frames t-1, t, t+1."""
        alignment = self.alignments[-1]
        columns = self._columns[self._played.index]
        states = columns["state"]
        live = obs.get("joint_state", obs.get(STATE))
        if live is not None:
            live = np.asarray(live, dtype=float).reshape(-1)
            errors = {}
            for shift in SHIFTS:
                k = t + shift
                if 0 <= k < len(states) and len(states[k]) == len(live):
                    errors[shift] = float(np.max(np.abs(live - states[k])))
                    alignment.state_error[shift] = max(alignment.state_error[shift], errors[shift])
            alignment.frames += 1
            if (
                self.state_tolerance is not None
                and 0 in errors
                and errors[0] > self.state_tolerance
            ):
                best = min(errors, key=errors.get)
                hint = (
                    f"; frame {t + best} matches better ({errors[best]:.3g}): the observations "
                    f"and actions are shifted by {best:+d} frame"
                    if best != 0
                    else ""
                )
                raise ValueError(
                    f"lerobot-dataset policy: the observed joint state before action {t} "
                    f"departs from the dataset's frame {t} ({self._played.task} seed "
                    f"{self._played.seed}) by {errors[0]:.3g} > state_tolerance "
                    f"{self.state_tolerance:g}{hint}"
                )
        for name, frames in columns["vectors"].items():
            live = observation_vector(obs, VECTORS[name])
            if live is not None:
                live = np.asarray(live, dtype=float).reshape(-1)
            self._compare_vector(name, live, frames, t, alignment)
        if self.images:
            self._compare_images(obs, t, alignment)

    @staticmethod
    def _compare_vector(
        name: str, live: np.ndarray | None, frames: np.ndarray, t: int, alignment: Alignment
    ) -> None:
        """Record the largest |live - frame t + s| of one observation vector (not compared
        when the observation lacks it or its size differs)."""
        if live is None:
            return
        errors = alignment.vector_error.setdefault(name, dict.fromkeys(SHIFTS, 0.0))
        for shift in SHIFTS:
            k = t + shift
            if 0 <= k < len(frames) and len(frames[k]) == len(live):
                errors[shift] = max(errors[shift], float(np.max(np.abs(live - frames[k]))))

    def _compare_images(self, obs: dict[str, Any], t: int, alignment: Alignment) -> None:
        cameras = [
            (camera, key)
            for camera, key in CAMERAS.items()
            if key in self.video_keys and (camera in obs or key in obs)
        ]
        if not cameras:
            return
        rows = self._columns[self._played.index]["rows"]
        window = {int(rows[t + s]) for s in SHIFTS if 0 <= t + s < len(rows)}
        self._decoded = {row: item for row, item in self._decoded.items() if row in window}
        sums: dict[int, float] = {}
        for shift in SHIFTS:
            k = t + shift
            if not 0 <= k < len(rows):
                continue
            row = int(rows[k])
            if row not in self._decoded:  # each frame is decoded once (three steps use it)
                self._decoded[row] = self.dataset[row]
            item = self._decoded[row]
            errors = []
            for camera, key in cameras:
                live = np.asarray(obs.get(camera, obs.get(key)), dtype=float)
                decoded = np.asarray(item[key]).transpose(1, 2, 0) * 255.0
                if decoded.shape != live.shape:
                    continue  # rendered at another size than the dataset's
                errors.append(float(np.mean(np.abs(decoded - live))))
            if errors:
                sums[shift] = float(np.mean(errors))
        if 0 not in sums:
            return
        if alignment.image_error is None:
            alignment.image_error = dict.fromkeys(SHIFTS, 0.0)
        for shift, error in sums.items():  # running means
            n = self._image_counts[shift] + 1
            mean = alignment.image_error[shift]
            alignment.image_error[shift] = mean + (error - mean) / n
            self._image_counts[shift] = n
        alignment.images_compared += 1


def load_dataset_policy(spec: str, **kwargs: Any) -> DatasetPlaybackPolicy:
    """``"lerobot-dataset:DIR[?options]"`` -> :class:`DatasetPlaybackPolicy` (keyword
    arguments: those of the class; they override the spec's options)."""
    root, options = parse_spec(spec)
    known = {*OPTIONS, "action_size"}
    unknown = sorted(set(kwargs) - known)
    if unknown:
        raise PolicyLoadError(
            f"policy {spec!r}: unknown arguments {unknown} (known: {', '.join(sorted(known))})"
        )
    if not root.is_dir():
        raise PolicyLoadError(f"policy {spec!r}: {root} is not a directory")
    return DatasetPlaybackPolicy(root, **{**options, **kwargs})
