"""Scenarios: the whole setup of a run as one value, read from YAML (Drake hardware_sim style).

A :class:`Scenario` holds everything that decides the data or the rollouts: the task, the seed
range (``seed``, ``episodes``), ``randomize`` and ``split``, the robot and every station setting
(control rate, cameras, physics: :class:`~bicoord_drake.config.StationConfig`). It is the one
definition of these settings: ``scripts/generate.py``, ``scripts/evaluate.py``,
:func:`~bicoord_drake.env.make_env` and the Gymnasium ids all read it; their flags and keyword
arguments (``fps``, ``resolution``, ...) are shortcuts into it (:data:`SHORTCUTS`), and every
value is checked by it, with one set of bounds.

>>> scenario = load_scenario("scenarios/aloha_50hz.yaml")               # doctest: +SKIP
>>> scenario = load_scenario("scenarios/benchmark.yaml:randomized")     # a named scenario
>>> scenario = load_scenario("data/jigsaw/default/data/episode0.hdf5")  # what made an episode
>>> scenario.with_overrides({"fps": 30, "station.time_step": 0.005}).to_yaml()

A file holds one scenario (a mapping of its fields) or named scenarios (a mapping of names to
scenarios, chosen with ``FILE.yaml:NAME``); ``base: OTHER`` starts a named scenario from
another one, merging its fields over the base's (nested mappings key by key). Every episode file
and manifest records the scenario that made it, so ``scripts/generate.py --scenario
EPISODE.hdf5`` makes that episode again. docs/scenarios.md has the details.
"""

from __future__ import annotations

import argparse
import copy
import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, get_args

import numpy as np
import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from bicoord_drake.config import (
    IMAGE_SIDE,
    Seed,
    StationConfig,
    check_seed,
    error_text,
    model_at,
    parse_resolution,
)
from bicoord_drake.models.appearance import Split
from bicoord_drake.models.layout import EmbodimentName, default_embodiment
from bicoord_drake.sim.disturbances import DISTURBANCE_KINDS, DisturbanceKind, parse_disturb

if TYPE_CHECKING:
    from bicoord_drake.episode_setup import EpisodeSetup
    from bicoord_drake.tasks.base import Task

#: First evaluation seed (PRODUCT.md: evaluation seeds are disjoint from generation seeds).
EVAL_SEED_START = 100000
#: Suffixes of episode files: ``--scenario EPISODE.hdf5`` reads the scenario recorded in one.
EPISODE_SUFFIXES = (".hdf5", ".h5")
#: The values generation and evaluation (environments too) give the scenario's None fields.
GENERATION_DEFAULTS: dict[str, Any] = {"episodes": 10, "split": "seen"}
EVALUATION_DEFAULTS: dict[str, Any] = {"episodes": 100, "split": "unseen"}
#: Shortcut names of the flags and keyword arguments -> the scenario field each one sets
#: (``resolution`` sets ``station.cameras.width`` and ``.height`` from ``"WxH"``).
SHORTCUTS: dict[str, tuple[str, ...]] = {
    "fps": ("station", "control_rate"),
    "render": ("station", "render"),
    "depth": ("station", "cameras", "depth"),
    "cameras": ("station", "cameras", "names"),
    "resolution": ("station", "cameras"),
}


#: Largest action-noise level (rad): a standard deviation of 0.2 rad (11.5 degrees) on every
#: joint target is far past what a demonstration survives.
ACTION_NOISE_MAX = 0.2
#: The level `--action-noise` without a value asks for (rad, about 1.5 mm at the ViperX's hand):
#: the largest level of the sweep (benchmarks/noise_sweep.md) at which the experts with precise
#: placements still keep at least 80 % of seeds 0-9 (jigsaw and stack_bowls 9/10, sweep_block
#: 10/10 at 0.003 rad; at 0.005 rad jigsaw keeps 1 of 5).
DEFAULT_ACTION_NOISE = 0.003
#: Mixed with an episode's seed into the seed of its action-noise generator, so the noise is
#: independent of the scene's draws (``default_rng(seed)``).
ACTION_NOISE_STREAM = 0x44415254  # "DART"

ActionNoise = float | tuple[float, float]
"""An action-noise setting: one level (rad), or a range ``(lo, hi)`` to draw each episode's
level from."""


def parse_action_noise(value: Any) -> ActionNoise:
    """An action-noise setting from a number, ``"SIGMA"``, ``"LO-HI"`` or a pair ``[lo, hi]``:
    levels in [0, :data:`ACTION_NOISE_MAX`] rad, ``lo <= hi`` (a ValueError saying what is
    wrong otherwise); a range of one level is that level."""
    text = value
    if isinstance(value, str):
        parts = [p.strip() for p in re.split(r"(?<![eE])-", value.strip())]
        if len(parts) == 2 and all(parts):
            value = parts
        elif len(parts) == 1:
            value = parts[0]
        else:
            raise ValueError(f"write SIGMA or LO-HI in rad (e.g. 0.01 or 0.005-0.02), got {text!r}")
    pair = isinstance(value, list | tuple)
    items = list(value) if pair else [value]
    if pair and len(items) != 2:
        raise ValueError(f"a range is two levels [lo, hi], got {len(items)}: {text!r}")
    levels = []
    for item in items:
        if isinstance(item, bool):
            raise ValueError(f"a level is a number of radians, got {item!r}")
        try:
            level = float(item)
        except (TypeError, ValueError):
            raise ValueError(
                f"write SIGMA or LO-HI in rad (e.g. 0.01 or 0.005-0.02), got {text!r}"
            ) from None
        if not 0.0 <= level <= ACTION_NOISE_MAX:
            raise ValueError(
                f"a level must be in [0, {ACTION_NOISE_MAX:g}] rad (a standard deviation), "
                f"got {level:g}"
            )
        levels.append(level)
    if not pair:
        return levels[0]
    if levels[0] > levels[1]:
        raise ValueError(f"a range runs from low to high: [{levels[0]:g}, {levels[1]:g}]")
    return levels[0] if levels[0] == levels[1] else (levels[0], levels[1])


def action_noise_draw(setting: ActionNoise, seed: int) -> tuple[float, np.random.Generator]:
    """The action-noise level of episode `seed` (drawn uniformly from a range, or the one
    level given) and the generator of its noise, both from the seed. One uniform draw comes
    first either way, so the level ``lo + (hi - lo) u`` recorded in the episode's scenario
    gives the same level and the same noise again."""
    lo, hi = setting if isinstance(setting, tuple) else (setting, setting)
    rng = np.random.default_rng([ACTION_NOISE_STREAM, int(seed)])
    u = rng.random()
    return (lo if lo == hi else lo + (hi - lo) * u), rng


def evaluation_seed(seed: int) -> int:
    """The first evaluation seed of a scenario's `seed`: ``100000 * (1 + seed)``."""
    return EVAL_SEED_START * (1 + int(seed))


class ScenarioError(ValueError):
    """A scenario that cannot be read or is invalid; the message (one line) names the field, or
    the flag or keyword argument that set it."""


# --------------------------------------------------------------------------- the value
class SceneSettings(BaseModel):
    """The settings a scenario and one episode (:class:`~bicoord_drake.episode_setup.
    EpisodeSetup`) share. The robot is ``embodiment`` and ``station.embodiment`` at once: give
    it either way (both, if they agree)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    randomize: bool = Field(
        False,
        description="the seed's randomized look: textures of the split, lights, table height, "
        "head-camera pose, 2-8 distractor objects",
    )
    embodiment: EmbodimentName = Field(
        default_factory=default_embodiment, description="the robot (a wrong name lists them)"
    )
    station: StationConfig = Field(
        default_factory=StationConfig,
        description="how the cell is built and driven: control rate, cameras, physics",
    )

    @model_validator(mode="before")
    @classmethod
    def _one_embodiment(cls, data: Any) -> Any:
        """``embodiment`` and ``station.embodiment`` name one robot: whichever of them is not
        the default (both, if they agree)."""
        if not isinstance(data, dict):
            return data
        station = data.get("station", StationConfig())
        if isinstance(station, dict):
            try:
                station = StationConfig(**station)
            except (ValidationError, TypeError):
                return data  # the field's own validation reports it, with its location
        if not isinstance(station, StationConfig):
            return data
        default = default_embodiment()
        given = data.get("embodiment", default)
        name = given
        if station.embodiment != given:
            if given != default and station.embodiment != default:
                raise ValueError(
                    f"embodiment {given!r} and station.embodiment {station.embodiment!r} "
                    "differ: give the robot once"
                )
            name = given if given != default else station.embodiment
        if station.embodiment != name:
            station = station.model_copy(update={"embodiment": name})
        return {**data, "embodiment": name, "station": station}

    @model_validator(mode="after")
    def _task_supports_the_robot(self) -> SceneSettings:
        """The task (a :class:`Scenario`'s or an episode's) runs on the robot: it lists it in
        ``Task.supported_robots`` (each task of a comma list; ``all`` means the tasks that do).
        Every entry point's settings are one of these two values, so an unsupported pair
        fails here, before anything is built."""
        task = getattr(self, "task", None)
        if task is None or (isinstance(task, str) and self.embodiment == default_embodiment()):
            return self  # every registered task supports the default robot (check_task_class)
        from bicoord_drake.tasks.registry import check_supported  # imports the tasks

        check_supported(task, self.embodiment)
        return self


#: The order of a scenario's fields in files (``action_noise`` and ``disturb`` only when they
#: are on: the records of runs without them are those of before they existed).
FIELD_ORDER = (
    "task",
    "seed",
    "episodes",
    "randomize",
    "split",
    "embodiment",
    "station",
    "action_noise",
    "disturb",
)


class Scenario(SceneSettings):
    """The whole setup of a run (see the module docstring). ``None`` fields take the entry
    point's default: ``episodes`` 10 for generation, 100 for evaluation; ``split`` seen for
    generation, unseen for evaluation and environments."""

    task: str | None = Field(
        None,
        description="the task (generation: also a comma list, or all: every task that supports "
        "the robot)",
    )
    seed: Seed = Field(
        0,
        description="generation tries seeds from this one up; evaluation and environments "
        "start at 100000 * (1 + seed), disjoint from them",
    )
    episodes: int | None = Field(
        None,
        ge=1,
        description="episodes to keep (generation; default 10) or rollouts (evaluation; "
        "default 100)",
    )
    split: Split | None = Field(
        None,
        description="instructions and (with randomize) textures of this split (default: seen "
        "for generation, unseen for evaluation and environments)",
    )
    action_noise: ActionNoise = Field(
        0.0,
        description="DART noise of the expert's demonstrations (generation): the standard "
        "deviation, rad, of a zero-mean Gaussian added to each arm joint target the station "
        "executes (grippers untouched; joint_action/vector stays the expert's label, "
        "joint_action/executed holds what ran), or a range LO-HI from which each episode draws "
        f"its level; levels in [0, {ACTION_NOISE_MAX:g}]; 0: off",
    )

    disturb: tuple[DisturbanceKind, ...] = Field(
        (),
        description="disturbances of the expert's demonstrations (generation), a comma list of "
        f"kinds ({', '.join(DISTURBANCE_KINDS)}; none: off): each fires once per episode, at a "
        "step drawn from the seed where it applies (push: a force on a free task object before "
        "the expert's next plan; drop: a holding gripper forced open; knock: a force on a "
        "placed object), recorded in the episode file (disturbances/) and re-applied by its "
        "replay; in an evaluation, the same disturbances in a second, disturbed rollout of "
        "each seed",
    )

    @field_validator("action_noise", mode="before")
    @classmethod
    def _action_noise(cls, value: Any) -> ActionNoise:
        return parse_action_noise(value)

    @field_validator("disturb", mode="before")
    @classmethod
    def _disturb(cls, value: Any) -> tuple[str, ...]:
        return parse_disturb(value)

    # ---------------------------------------------------------------- derived values
    @property
    def resolution(self) -> str:
        """The cameras' image size as ``"WxH"``."""
        cameras = self.station.cameras
        return f"{cameras.width}x{cameras.height}"

    @property
    def fps(self) -> float:
        """The control and recording rate, Hz (``station.control_rate``)."""
        return self.station.control_rate

    def episode_setup(self, seed: int, task: str | Task | None = None) -> EpisodeSetup:
        """The episode of `seed` in this scenario (of `task`, default the scenario's; the
        split must be set, e.g. by :meth:`with_defaults`)."""
        from bicoord_drake.episode_setup import EpisodeSetup

        task = task if task is not None else self.task
        if task is None:
            raise ScenarioError("no task: give one (task=..., --task, or task: in the scenario)")
        if self.split is None:
            raise ScenarioError("the split is not set (seen or unseen)")
        try:
            return EpisodeSetup(
                task=task,
                seed=seed,
                randomize=self.randomize,
                split=self.split,
                embodiment=self.embodiment,
                station=self.station,
            )
        except ValidationError as err:  # e.g. a task (object) that does not support the robot
            raise ScenarioError(_describe(err, {}, None)) from None

    # ---------------------------------------------------------------- copies
    def with_overrides(
        self, overrides: Mapping[str, Any], labels: Mapping[str, str] | None = None
    ) -> Scenario:
        """A copy with `overrides` (field paths such as ``station.time_step``, or shortcut
        names such as ``fps``; None values are left out), validated again. A ScenarioError
        names the key of a bad value as `labels` call it (e.g. ``--fps``)."""
        return resolve(self.to_dict(), overrides, labels)

    def with_defaults(self, **defaults: Any) -> Scenario:
        """A copy whose None fields take `defaults` (an entry point's episodes and split)."""
        missing = {k: v for k, v in defaults.items() if getattr(self, k) is None}
        return self.with_overrides(missing) if missing else self

    @property
    def noisy(self) -> bool:
        """Whether the expert's executed actions get noise (``action_noise`` is not 0)."""
        return self.action_noise != 0.0

    @property
    def disturbed(self) -> bool:
        """Whether the expert's demonstrations get disturbances (``disturb`` is not empty)."""
        return bool(self.disturb)

    def action_noise_level(self, seed: int) -> float:
        """The action-noise level (rad) of the episode of `seed` (:func:`action_noise_draw`)."""
        return action_noise_draw(self.action_noise, seed)[0]

    def for_episode(self, task: str, seed: int) -> Scenario:
        """The scenario of one episode of this run: its task and seed, one episode (and the
        action-noise level it drew from a range)."""
        overrides: dict[str, Any] = {"task": task, "seed": seed, "episodes": 1}
        if self.noisy:
            overrides["action_noise"] = self.action_noise_level(seed)
        return self.with_overrides(overrides)

    # ---------------------------------------------------------------- files
    def to_dict(self) -> dict[str, Any]:
        """The fields as plain JSON values, in file order (the robot once, at the top)."""
        data = self.model_dump(mode="json")
        data["station"].pop("embodiment", None)
        if not self.noisy:
            data.pop("action_noise")
        if not self.disturbed:
            data.pop("disturb")
        return {name: data[name] for name in FIELD_ORDER if name in data}

    def to_yaml(self) -> str:
        """The scenario as a YAML document (floats written exactly)."""
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


# --------------------------------------------------------------------------- overrides
def _assignments(key: str, value: Any, label: str) -> list[tuple[tuple[str, ...], Any]]:
    """The field paths and values one override sets."""
    if key == "resolution":
        try:
            if isinstance(value, str):
                width, height = parse_resolution(value)
            else:
                width, height = (int(v) for v in value)
        except (TypeError, ValueError) as exc:
            raise ScenarioError(f"{label}: {exc}") from None
        cameras = SHORTCUTS["resolution"]
        return [((*cameras, "width"), width), ((*cameras, "height"), height)]
    if key in SHORTCUTS:
        return [(SHORTCUTS[key], value)]
    return [(tuple(key.split(".")), value)]


def _set(data: dict[str, Any], path: tuple[str, ...], value: Any, label: str) -> None:
    node = data
    for depth, part in enumerate(path[:-1]):
        child = node.get(part)
        if isinstance(child, BaseModel):
            child = child.model_dump()
        elif child is None:
            child = {}
        elif isinstance(child, Mapping):
            child = dict(child)
        else:
            where = ".".join(path[: depth + 1])
            raise ScenarioError(f"{label}: {where} is {child!r}, not a mapping of fields")
        node[part] = child
        node = child
    node[path[-1]] = value


def resolve(
    data: Mapping[str, Any],
    overrides: Mapping[str, Any] | None = None,
    labels: Mapping[str, str] | None = None,
    source: str | None = None,
    defaults: Mapping[str, Any] | None = None,
) -> Scenario:
    """The scenario of the fields in `data` (read from `source`, a file) with `overrides` set
    over them and `defaults` filling fields still None, validated once. A ScenarioError names
    the first bad value by who set it: its override's label (default: the override's key) or
    its path in `source`."""
    data = copy.deepcopy(dict(data))
    set_by: dict[tuple[str, ...], str] = {}
    for key, value in (overrides or {}).items():
        if value is None:
            continue
        label = (labels or {}).get(key, key)
        for path, v in _assignments(key, value, label):
            _set(data, path, v, label)
            set_by[path] = label
    for key, value in (defaults or {}).items():
        if data.get(key) is None:
            data[key] = value
    try:
        return Scenario.model_validate(data)
    except ValidationError as err:
        raise ScenarioError(_describe(err, set_by, source)) from None


def _describe(
    err: ValidationError, set_by: Mapping[tuple[str, ...], str], source: str | None
) -> str:
    first = err.errors()[0]
    loc = tuple(str(p) for p in first["loc"])
    message = error_text(first, Scenario)
    if first["type"] == "extra_forbidden" and len(loc) == 1:
        message = f"unknown field; valid fields: {', '.join(FIELD_ORDER)}"
        if loc[0] in SHORTCUTS:
            target = ".".join(SHORTCUTS[loc[0]])
            target += ".width and .height" if loc[0] == "resolution" else ""
            message += f" ({loc[0]} is {target})"
    who = next((set_by[loc[:n]] for n in range(len(loc), 0, -1) if loc[:n] in set_by), None)
    if who is not None:
        if first["type"] == "extra_forbidden" and len(loc) == 1:
            message += f", or a shortcut: {', '.join(SHORTCUTS)}"
        return f"{who}: {message}"
    where = ".".join(loc)
    text = f"{where}: {message}" if where else message
    return f"{source}: {text}" if source else text


def fold_shortcuts(data: Any, shortcuts: Sequence[str], defaults: Mapping[str, Any]) -> Any:
    """For a front door's settings model (GenerateConfig, EvaluateConfig): `data` with its
    `shortcuts` keys (``task``, ``fps``, ``resolution``, ...) moved into ``data["scenario"]``
    (a Scenario or a mapping of its fields), and `defaults` filling the scenario's None
    fields. A bad shortcut value is reported by the scenario's validation, at its field."""
    if not isinstance(data, dict):
        return data
    data = dict(data)
    base = data.pop("scenario", None)
    given = {key: data.pop(key) for key in shortcuts if key in data}
    raw = base.to_dict() if isinstance(base, Scenario) else dict(base or {})
    for key, value in given.items():
        if value is None:
            continue
        for path, v in _assignments(key, value, key):
            _set(raw, path, v, key)
    for key, value in defaults.items():
        if raw.get(key) is None:
            raw[key] = value
    data["scenario"] = raw
    return data


#: The keys a front door's settings accept besides its own: the scenario's fields (but its
#: station) and the shortcuts.
SCENARIO_KEYS = (*(name for name in FIELD_ORDER if name != "station"), *SHORTCUTS)


class RunConfig(BaseModel):
    """A front door's settings (:class:`~bicoord_drake.runner.generate.GenerateConfig`,
    :class:`~bicoord_drake.runner.evaluate.EvaluateConfig`): a :class:`Scenario` and how the run
    executes. The scenario's fields are also taken and read under their names and shortcuts
    (``task``, ``seed``, ``fps``, ``resolution``, ...: :data:`SCENARIO_KEYS`), so they are
    declared and checked once, in the scenario; its None fields take :attr:`DEFAULTS`."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    #: The entry point's values of the scenario's None fields (episodes, split).
    DEFAULTS: ClassVar[dict[str, Any]] = {}
    #: Keys taken besides the fields (named with them when a key is unknown).
    ALSO_ACCEPTS: ClassVar[tuple[str, ...]] = SCENARIO_KEYS

    scenario: Scenario = Field(description="what is simulated: task, seeds, robot, station")

    @model_validator(mode="before")
    @classmethod
    def _fold(cls, data: Any) -> Any:
        return fold_shortcuts(data, SCENARIO_KEYS, cls.DEFAULTS)

    @classmethod
    def key_of(cls, loc: tuple[str, ...]) -> str:
        """The key a user gives for the field at `loc` (an error's location): a shortcut's or
        the scenario field's name (``("scenario", "station", "control_rate")``: ``fps``)."""
        if loc[:1] != ("scenario",) or len(loc) < 2:
            return ".".join(loc)
        path = loc[1:]
        if path[:3] in {(*SHORTCUTS["resolution"], side) for side in ("width", "height")}:
            return "resolution"
        for name, target in SHORTCUTS.items():
            if name != "resolution" and path[: len(target)] == target:
                return name
        return ".".join(path)

    # ---------------------------------------------------------------- the scenario's fields
    @property
    def task(self) -> str:
        return self.scenario.task  # type: ignore[return-value]  # checked by the subclasses

    @property
    def seed(self) -> int:
        return self.scenario.seed

    @property
    def episodes(self) -> int:
        return self.scenario.episodes  # type: ignore[return-value]  # a default fills it

    @property
    def randomize(self) -> bool:
        return self.scenario.randomize

    @property
    def split(self) -> Split:
        return self.scenario.split  # type: ignore[return-value]  # a default fills it

    @property
    def embodiment(self) -> str:
        return self.scenario.embodiment

    @property
    def action_noise(self) -> ActionNoise:
        return self.scenario.action_noise

    @property
    def station(self) -> StationConfig:
        return self.scenario.station

    @property
    def fps(self) -> float:
        return self.scenario.station.control_rate

    @property
    def resolution(self) -> str:
        return self.scenario.resolution

    @property
    def depth(self) -> bool:
        return self.scenario.station.cameras.depth

    @property
    def render(self) -> bool:
        return self.scenario.station.render

    # ---------------------------------------------------------------- copies
    def replace(self, **changes: Any) -> RunConfig:
        """A copy with `changes` (fields, or the scenario's fields and shortcuts), validated
        again."""
        current = {name: getattr(self, name) for name in type(self).model_fields}
        return type(self)(**{**current, **changes})

    def model_copy(
        self, *, update: Mapping[str, Any] | None = None, deep: bool = False
    ) -> RunConfig:
        """As pydantic's, but `update` goes through :meth:`replace`: validated, and a
        scenario field (``episodes``, ``fps``, ...) reaches the scenario."""
        if update:
            return self.replace(**update)
        return super().model_copy(deep=deep)

    def _check_task(self) -> None:
        if not self.scenario.task:
            raise ValueError("no task: give task (--task, or task: in the scenario)")


# --------------------------------------------------------------------------- files
def read_source(source: str | Path) -> tuple[dict[str, Any], str | None]:
    """The fields a scenario source holds (not yet validated) and the scenario's name.

    `source`: ``FILE.yaml`` (one scenario; named after the file), ``FILE.yaml:NAME`` (a named
    scenario of the file) or an episode file (the scenario recorded in it; no name)."""
    path, name = _split_source(str(source))
    if is_episode_file(path):
        if name is not None:
            raise ScenarioError(f"{source}: an episode file holds one scenario, not named ones")
        return episode_scenario_data(path), None
    try:
        document = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{path}: not valid YAML ({_one_line(exc)})") from None
    document = {} if document is None else document
    if not isinstance(document, dict):
        raise ScenarioError(f"{path}: a scenario file is a mapping, got {type(document).__name__}")
    if not _is_named(document):
        if name is not None:
            raise ScenarioError(
                f"{source}: {path} holds one scenario (its top level has scenario fields), "
                "not named ones: drop :NAME"
            )
        return document, path.stem
    names = list(document)
    if name is None:
        raise ScenarioError(
            f"{path} holds named scenarios ({', '.join(names)}): choose one with "
            f"{path}:NAME (a file of one scenario has fields such as task or station at its "
            "top level)"
        )
    return _named(document, name, path, ()), name


def is_episode_file(source: str | Path | None) -> bool:
    """Whether a scenario source names an episode file (by its suffix)."""
    return source is not None and Path(str(source)).suffix.lower() in EPISODE_SUFFIXES


def _split_source(source: str) -> tuple[Path, str | None]:
    if Path(source).exists():
        return Path(source), None
    head, sep, tail = source.rpartition(":")
    if sep and head and "/" not in tail and Path(head).exists():
        return Path(head), tail
    raise ScenarioError(f"{source}: no such file")


def _is_named(document: Mapping[str, Any]) -> bool:
    """Named scenarios: no scenario field at the top level, and every value a mapping."""
    fields = set(Scenario.model_fields) | set(SHORTCUTS)
    return (
        bool(document)
        and not fields & set(document)
        and all(isinstance(v, dict) or v is None for v in document.values())
    )


def _named(
    document: Mapping[str, Any], name: str, path: Path, chain: tuple[str, ...]
) -> dict[str, Any]:
    """The fields of named scenario `name`, merged over those of its base."""
    if name not in document:
        raise ScenarioError(
            f"{path}: no scenario named {name!r}; it has {', '.join(map(str, document))}"
        )
    if name in chain:
        raise ScenarioError(
            f"{path}: the bases of {chain[0]!r} run in a circle: " + " -> ".join([*chain, name])
        )
    fields = dict(document[name] or {})
    base = fields.pop("base", None)
    if base is None:
        return fields
    return _merged(_named(document, str(base), path, (*chain, name)), fields)


def _merged(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """`over` merged into `base`: nested mappings key by key, anything else replaced."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merged(out[key], value)
        else:
            out[key] = value
    return out


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())


def load_scenario(
    source: str | Path,
    overrides: Mapping[str, Any] | None = None,
    labels: Mapping[str, str] | None = None,
) -> Scenario:
    """The scenario of `source` (``FILE.yaml``, ``FILE.yaml:NAME`` or an episode file) with
    `overrides` (see :meth:`Scenario.with_overrides`); ScenarioError on anything wrong."""
    data, _ = read_source(source)
    return resolve(data, overrides, labels, str(source))


def recorded_scenario(episode: Any) -> Scenario | None:
    """The scenario an :class:`~bicoord_drake.data.episode.Episode` records (None for files
    written before it was recorded)."""
    text = episode.scenario_text
    if not text:
        return None
    return resolve(_recorded_data(text, episode.path), source=str(episode.path))


def _recorded_data(text: str, path: str | Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{path}: its scenario is not valid YAML ({_one_line(exc)})") from None
    if not isinstance(data, dict):
        raise ScenarioError(f"{path}: its scenario attribute is not a mapping")
    return data


def episode_scenario_data(path: str | Path) -> dict[str, Any]:
    """The scenario fields recorded in an episode file: its ``scenario`` attribute; for a file
    written before that was recorded, those of its ``config`` attribute, seed and rate (the
    station's physics then are today's defaults, which may differ from the ones it had)."""
    import h5py

    from bicoord_drake.data.episode import check_schema

    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            check_schema(f.attrs, path)
            attrs = {k: v.decode() if isinstance(v, bytes) else v for k, v in f.attrs.items()}
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot open the episode file ({exc})") from None
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    if attrs.get("scenario"):
        return _recorded_data(attrs["scenario"], path)
    config = json.loads(attrs.get("config") or "{}")
    width, height = parse_resolution(config.get("resolution", "320x240"))
    return {
        "task": str(attrs["task"]),
        "seed": int(attrs["seed"]),
        "episodes": 1,
        "randomize": bool(config.get("randomize", False)),
        "split": "seen",
        "embodiment": str(attrs.get("embodiment", default_embodiment())),
        "station": {
            "control_rate": float(attrs["fps"]),
            "render": bool(config.get("render", True)),
            "cameras": {"width": width, "height": height, "depth": bool(config.get("depth"))},
        },
    }


# --------------------------------------------------------------------------- command lines
#: The scenario flags of the scripts: name -> the field it sets, whose description is its help
#: (``resolution`` sets the cameras' width and height).
FLAGS: dict[str, tuple[str, ...]] = {
    "task": ("task",),
    "seed": ("seed",),
    "episodes": ("episodes",),
    "fps": SHORTCUTS["fps"],
    "resolution": SHORTCUTS["resolution"],
    "depth": SHORTCUTS["depth"],
    "render": SHORTCUTS["render"],
    "randomize": ("randomize",),
    "split": ("split",),
    "embodiment": ("embodiment",),
    "action_noise": ("action_noise",),
    "disturb": ("disturb",),
}


def field_help(path: tuple[str, ...]) -> str:
    """A field's description with its bounds, default and path, for ``--help``."""
    owner = model_at(Scenario, path[:-1])
    info = owner.model_fields[path[-1]]
    text = info.description or path[-1].replace("_", " ")
    bounds = _bounds(info.metadata)
    if bounds:
        text += f"; {'in ' if ',' in bounds else ''}{bounds}"
    default = info.get_default(call_default_factory=True)
    if default is not None and not isinstance(default, BaseModel | tuple):
        text += f"; default {default:g}" if isinstance(default, float) else f"; default {default}"
    return f"{text} [{'.'.join(path)}]"


def _bounds(metadata: Sequence[Any]) -> str:
    """A field's bounds as text: ``(0, 1000]``, ``>= 1``; empty without bounds."""
    found = {a: getattr(m, a) for m in metadata for a in ("gt", "ge", "lt", "le") if hasattr(m, a)}
    low = ("(", found["gt"]) if "gt" in found else ("[", found["ge"]) if "ge" in found else None
    high = (")", found["lt"]) if "lt" in found else ("]", found["le"]) if "le" in found else None
    if low and high:
        return f"{low[0]}{low[1]:g}, {high[1]:g}{high[0]}"
    if low:
        return f"{'>' if low[0] == '(' else '>='} {low[1]:g}"
    if high:
        return f"{'<' if high[0] == ')' else '<='} {high[1]:g}"
    return ""


def add_scenario_arguments(
    parser: argparse.ArgumentParser, notes: Mapping[str, str] | None = None
) -> None:
    """Add ``--scenario``, ``--set``, ``--print-scenario`` and the shortcut flags (help from the
    scenario's field descriptions; `notes` adds a script's words to a flag's help). Every flag
    defaults to None: only the flags given override the scenario."""
    notes = dict(notes or {})
    group = parser.add_argument_group(
        "scenario (a file's values, then --set, then these flags; docs/scenarios.md)"
    )
    group.add_argument(
        "--scenario",
        metavar="SOURCE",
        help="the scenario: FILE.yaml, FILE.yaml:NAME (a named scenario of the file) or an "
        "episode file EPISODE.hdf5 (the scenario that made it: generating from it makes that "
        "episode again); the flags given override it",
    )
    group.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        help="set any scenario field, e.g. station.time_step=0.005 or "
        "station.cameras.names=[head_camera] (VALUE is YAML); repeatable",
    )
    group.add_argument(
        "--print-scenario",
        action="store_true",
        help="print the resolved scenario as YAML and exit",
    )
    for name, path in FLAGS.items():
        kwargs: dict[str, Any] = {"default": None}
        if name == "action_noise":
            kwargs["metavar"] = "SIGMA|LO-HI"
            kwargs["nargs"] = "?"
            kwargs["const"] = f"{DEFAULT_ACTION_NOISE:g}"
            help_text = f"{field_help(path)}; without a value {DEFAULT_ACTION_NOISE:g}"
        elif name == "disturb":
            kwargs["metavar"] = "KIND[,KIND]"
            help_text = field_help(path)
        elif name == "resolution":
            kwargs["metavar"] = "WxH"
            help_text = (
                f"camera image size WIDTHxHEIGHT, each side in [{IMAGE_SIDE[0]}, "
                f"{IMAGE_SIDE[1]}]; default {Scenario().resolution} [station.cameras.width, "
                ".height]"
            )
        else:
            info = model_at(Scenario, path[:-1]).model_fields[path[-1]]
            help_text = field_help(path)
            if info.annotation is bool:
                kwargs["action"] = argparse.BooleanOptionalAction
            elif name == "split":
                kwargs["choices"] = get_args(Split)
            elif info.annotation in (int, float) or name in ("seed", "episodes"):
                kwargs["type"] = float if info.annotation is float else int
        if name in notes:
            help_text = f"{help_text}; {notes[name]}"
        group.add_argument("--" + name.replace("_", "-"), help=help_text, **kwargs)


def scenario_from_args(
    args: argparse.Namespace,
    defaults: Mapping[str, Any] | None = None,
    hints: Mapping[str, str] | None = None,
) -> tuple[Scenario, str | None]:
    """The scenario of parsed arguments (see :func:`add_scenario_arguments`) and its name (a
    named scenario's or the file's; None without a file or for an episode file). `hints`
    (flag -> words) are added to the error of a bad value a flag gave."""
    try:
        return _scenario_from_args(args, defaults)
    except ScenarioError as err:
        for flag, hint in (hints or {}).items():
            if str(err).startswith(f"--{flag}: "):
                raise ScenarioError(f"{err}; {hint}") from None
        raise


def _scenario_from_args(
    args: argparse.Namespace, defaults: Mapping[str, Any] | None
) -> tuple[Scenario, str | None]:
    data, name = read_source(args.scenario) if args.scenario else ({}, None)
    overrides: dict[str, Any] = {}
    labels: dict[str, str] = {}
    for item in args.set or ():
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ScenarioError(f"--set {item}: write FIELD=VALUE, e.g. station.time_step=0.005")
        try:
            overrides[key] = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise ScenarioError(f"--set {item}: VALUE is not YAML ({_one_line(exc)})") from None
        labels[key] = f"--set {key}"
    for flag in FLAGS:
        value = getattr(args, flag)
        if value is not None:
            overrides.pop(flag, None)  # a flag is applied after --set: keep the order
            overrides[flag] = value
            labels[flag] = "--" + flag.replace("_", "-")
    source = str(args.scenario) if args.scenario else None
    return resolve(data, overrides, labels, source, defaults), name


def check_evaluation_seed(scenario: Scenario, label: str = "seed") -> int:
    """The first evaluation seed of `scenario` (a ScenarioError naming `label` past 2**32)."""
    try:
        return check_seed(evaluation_seed(scenario.seed), "evaluation seed")
    except ValueError as exc:
        raise ScenarioError(f"{label} {scenario.seed}: {exc}") from None
