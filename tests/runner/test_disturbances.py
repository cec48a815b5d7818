"""Disturbances and recovery (issue #54, item 2): the ``disturb`` setting, the disturbance
record, the schedule drawn from the seed, a push through the plant, the episode file and the
replay of a disturbed episode.

The schedule tests run the planners on a synthetic clean run over a real jigsaw station (no
physics); one physics test pushes a cube for a few control steps; one runs balance_roller's
expert twice (traced and plain). The slow test generates a pushed balance_roller episode and
replays it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.data.episode import EpisodeRecorder, read_episode
from bicoord_drake.episode_setup import EpisodeSetup, assemble
from bicoord_drake.runner import generate as gen
from bicoord_drake.runner.stopwatch import Stopwatch
from bicoord_drake.scenario import Scenario, ScenarioError, load_scenario, resolve
from bicoord_drake.sim import disturbances as dist
from bicoord_drake.sim.disturbances import (
    DISTURBANCE_KINDS,
    Disturbance,
    DisturbanceDriver,
    ExpertTrace,
    FrameFacts,
    NoDisturbanceWindow,
    parse_disturb,
    plan_disturbances,
    slide_push,
)

STATION = StationConfig(render=False)


def script_main():
    path = Path(__file__).resolve().parents[2] / "scripts" / "generate.py"
    spec = importlib.util.spec_from_file_location("script_generate_disturb", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


# --------------------------------------------------------------------------- the setting
@pytest.mark.parametrize(
    ("given", "expected"),
    [
        (None, ()),
        ("", ()),
        ("none", ()),
        ([], ()),
        ("push", ("push",)),
        ("knock, push", ("push", "knock")),  # each once, in DISTURBANCE_KINDS order
        (["drop", "push", "drop"], ("push", "drop")),
    ],
)
def test_the_kinds_are_read_once_each(given, expected):
    assert parse_disturb(given) == expected
    assert resolve({}, {"disturb": given}).disturb == expected


def test_an_unknown_kind_names_itself_and_the_valid_ones(capsys):
    valid = ", ".join(DISTURBANCE_KINDS)
    assert valid == "push, drop, knock"
    with pytest.raises(ValueError, match=f"unknown disturbance kind 'shove'; kinds: {valid}"):
        parse_disturb("push,shove")
    with pytest.raises(ScenarioError, match=f"^--disturb: unknown disturbance kind 'x'.*{valid}"):
        resolve({}, {"disturb": "x"}, {"disturb": "--disturb"})
    with pytest.raises(ScenarioError, match="^disturb: write KIND or KIND,KIND"):
        resolve({}, {"disturb": 3})
    main = script_main()
    assert main(["--task", "jigsaw", "--disturb", "shove", "--print-scenario"]) == 2
    assert f"--disturb: unknown disturbance kind 'shove'; kinds: {valid}" in capsys.readouterr().err
    assert main(["--task", "jigsaw", "--disturb", "push,knock", "--print-scenario"]) == 0
    assert capsys.readouterr().out.endswith("disturb:\n- push\n- knock\n")


def test_a_disturbance_record_is_checked():
    with pytest.raises(ValueError, match="'push', 'drop' or 'knock'"):
        Disturbance(kind="shove", step=3, duration=2, body="cube")
    with pytest.raises(ValueError, match="a drop needs side"):
        Disturbance(kind="drop", step=3, duration=2, body="cube")
    with pytest.raises(ValueError, match="a push has no side"):
        Disturbance(kind="push", step=3, duration=2, body="cube", side="left")
    with pytest.raises(ValueError, match="greater than or equal to 1"):
        Disturbance(kind="push", step=3, duration=0, body="cube")
    push = Disturbance(kind="push", step=3, duration=2, body="cube", force=(0.0, 0.5, 0.0))
    assert [push.active(t) for t in (2, 3, 4, 5)] == [False, True, True, False]
    assert np.array_equal(push.wrench, [0, 0, 0, 0, 0.5, 0])
    assert dist.from_records(dist.disturbance_records([push])) == [push]
    row = dist.recovery_row(push, 20)
    assert row[:2] == [3, 20] and row[2] == "recover from the push on 'cube' (0.5 N)"


def test_off_by_default_and_then_absent_from_the_records():
    scenario = Scenario(task="jigsaw")
    assert scenario.disturb == () and not scenario.disturbed
    assert "disturb" not in scenario.to_dict()  # records as before the setting existed
    config = gen.GenerateConfig(task="jigsaw")
    assert "disturb" not in config.data_settings() and config.config_name == "default"


def test_a_disturbed_run_records_its_setting_and_gets_its_own_directory():
    config = gen.GenerateConfig(task="jigsaw", disturb="push")
    assert config.data_settings()["disturb"] == ["push"]
    assert config.config_name == "default_disturbed"
    both = gen.GenerateConfig(task="jigsaw", disturb="push", action_noise=0.01)
    assert both.config_name == "default_noisy_disturbed"
    assert gen.default_config_name(True, "franka_pair", disturbed=True) == (
        "franka_pair_randomized_disturbed"
    )
    assert Scenario.model_validate(config.scenario.to_dict()) == config.scenario
    assert config.scenario.for_episode("jigsaw", 4).disturb == ("push",)


def test_the_runner_passes_the_kinds_only_when_on(monkeypatch, tmp_path):
    calls = []

    def fake(setup, depth=False, action_noise=0.0, **kwargs):
        calls.append(kwargs)
        return gen.EpisodeResult(setup.seed, False, "planning: stand-in")

    monkeypatch.setattr(gen, "run_expert", fake)
    for disturb in (None, "push,drop"):
        config = gen.GenerateConfig(task="jigsaw", disturb=disturb, render=False, out=str(tmp_path))
        gen.produce_episode(config, 0, None)
    assert calls == [{}, {"disturb": ("push", "drop")}]


# --------------------------------------------------------------------------- the schedule
@pytest.fixture(scope="module")
def jigsaw():
    """jigsaw seed 0 assembled (no cameras): spares at (+-0.2, -0.2) and (+-0.2, 0)."""
    return assemble(EpisodeSetup(task="jigsaw", seed=0, split="seen", station=STATION))


def synthetic_trace(assembly) -> ExpertTrace:
    """A made-up clean run of 200 frames: every object rests on the table until the robot takes
    it. spare_left_1 is picked at frame 20 and held up over 40-80 (left), placed at 90 and
    released; spare_left_0 is first touched at 120, spare_right_0 at 150, spare_right_1 at 25;
    the expert re-plans at frames 60, 100, 140 and 170."""
    trace = ExpertTrace(assembly.sim)
    poses = assembly.sim.object_poses()
    names = list(poses)
    first = {"spare_left_1": 20, "spare_right_1": 25, "spare_left_0": 120, "spare_right_0": 150}
    for t in range(200):
        robot = {n: frozenset({"left"} if n.startswith("spare_left") else {"right"}) for n in names}
        robot = {n: s if first.get(n, 10**6) <= t < first.get(n, 0) + 70 else frozenset()
                 for n, s in robot.items()}  # fmt: skip
        fingers = dict(robot)
        touching = {n: frozenset({dist.SUPPORT}) for n in names}
        if 40 <= t < 80:
            touching["spare_left_1"] = frozenset()  # in the air
        trace.frames.append(
            FrameFacts(
                robot=robot,
                fingers=fingers,
                touching=touching,
                poses=poses,
                speeds={n: 0.0 for n in names},
            )
        )
    trace.reads = {0, 60, 100, 140, 170}
    return trace


def test_the_schedule_is_drawn_from_the_seed(jigsaw):
    trace = synthetic_trace(jigsaw)
    kinds = ("push", "drop", "knock")
    plans = {seed: plan_disturbances(kinds, seed, trace, jigsaw.station) for seed in range(12)}
    again = {seed: plan_disturbances(kinds, seed, trace, jigsaw.station) for seed in range(12)}
    assert plans == again  # the same seed, the same disturbances
    for kind in range(3):
        assert len({plans[s][kind] for s in plans}) > 6, kind  # other seeds, others
    assert [d.kind for d in plans[0]] == list(kinds)
    # one kind's draws do not depend on which other kinds are asked for
    assert plan_disturbances(("knock",), 5, trace, jigsaw.station)[0] == plans[5][2]


def test_the_windows(jigsaw):
    """A push: between 0.5 s and the first re-plan (60) minus its 2 steps and 0.6 s to settle,
    on an object the robot takes only after that re-plan; a drop: while a gripper holds its
    object in the air, before the last re-plan; a knock: on a released object, at rest, with a
    re-plan after it."""
    trace, station = synthetic_trace(jigsaw), jigsaw.station
    for seed in range(20):
        push, drop, knock = plan_disturbances(("push", "drop", "knock"), seed, trace, station)
        assert push.body in {"spare_left_0", "spare_right_0"}  # not those of the first plan
        assert 8 <= push.step and push.end + 9 <= 60 and push.duration == 2
        assert 1.0 < np.linalg.norm(push.force) / (0.05 * 9.81) < 4 and push.force[2] == 0
        assert -0.02 < push.point[2] < -0.01  # below the centre, above the table (cube: 2 cm)
        assert (drop.body, drop.side) == ("spare_left_1", "left") and drop.duration == 15
        assert 40 <= drop.step and drop.end <= 80
        assert knock.body in {"spare_left_1", "spare_right_1"}  # placed, then left alone
        released = {"spare_left_1": 90, "spare_right_1": 95}[knock.body]
        assert knock.step >= released + 9 and knock.end + 9 <= 170
    trace.reads = {0, 15}  # the only re-plan comes before a push could settle
    with pytest.raises(NoDisturbanceWindow, match="no time for a push"):
        plan_disturbances(("push",), 0, trace, station)


def test_a_drop_starts_only_just_above_where_the_object_lay(jigsaw):
    """A drop starts where its object is at most DROP_HEIGHT above its place at the start:
    lifted higher at every step of its window, it has none."""
    trace, station = synthetic_trace(jigsaw), jigsaw.station
    low = plan_disturbances(("drop",), 0, trace, station)[0]
    assert low.body == "spare_left_1"
    for t in range(40, 80):
        f = trace.frames[t]
        raised = f.poses["spare_left_1"].copy()
        raised[2] += dist.DROP_HEIGHT + 0.01
        f.poses = {**f.poses, "spare_left_1": raised}
    with pytest.raises(NoDisturbanceWindow, match="drop: no gripper"):
        plan_disturbances(("drop",), 0, trace, station)


def test_a_knock_falls_on_a_placed_object_resting_alone(jigsaw):
    """A knock needs its placed object alone on its support: one set down on another object
    (or in a drawer) is never knocked; with none left, the seed has no knock window."""
    trace, station = synthetic_trace(jigsaw), jigsaw.station
    for f in trace.frames[95:]:
        f.touching["spare_right_1"] = frozenset({dist.SUPPORT, "spare_left_1"})
    bodies = {plan_disturbances(("knock",), s, trace, station)[0].body for s in range(10)}
    assert bodies == {"spare_left_1"}
    for f in trace.frames[90:]:
        f.touching["spare_left_1"] = frozenset({"spare_right_1"})
    with pytest.raises(NoDisturbanceWindow, match="knock: no object"):
        plan_disturbances(("knock",), 0, trace, station)


def test_a_knock_leaves_out_what_stands_above_the_table_top(jigsaw):
    """An object set down on a shelf (here: its rest 5 cm above where it stood) is not knocked:
    the expert puts back only what it set on the table top."""
    trace, station = synthetic_trace(jigsaw), jigsaw.station
    placed = {"spare_left_1", "spare_right_1"}
    assert plan_disturbances(("knock",), 0, trace, station)[0].body in placed
    for f in trace.frames[90:]:
        poses = dict(f.poses)
        for name in placed:
            poses[name] = poses[name] + np.array([0, 0, 0.05, 0, 0, 0, 0])
        f.poses = poses
    with pytest.raises(NoDisturbanceWindow, match="knock: no object"):
        plan_disturbances(("knock",), 0, trace, station)


def test_a_knock_leaves_out_what_would_tip_over_as_it_slides(jigsaw, monkeypatch):
    """A 4 cm cube sliding on the table (combined friction 0.85) stops on its face: friction's
    moment (0.85 x 2 cm) stays inside its leading edge (2 cm, 2.8 cm along a diagonal); at a
    friction of 1.5 it would tip (3 cm), whichever way it slides."""
    pose = np.asarray(jigsaw.sim.object_poses()["spare_left_0"])
    directions = [(1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.7, 0.7, 0.0)]
    assert dist.combined_friction(jigsaw.station, "spare_left_0") == pytest.approx(0.847, abs=1e-3)
    assert not any(
        dist.topples_when_slid(jigsaw.station, "spare_left_0", pose, u) for u in directions
    )
    monkeypatch.setattr(dist, "combined_friction", lambda station, name: 1.5)
    assert all(dist.topples_when_slid(jigsaw.station, "spare_left_0", pose, u) for u in directions)


def test_a_push_keeps_clear_of_the_table_edge_and_the_other_objects(jigsaw):
    """spare_left_0 stands at (-0.2, -0.2), 15 cm from the table's near edge and 10 cm from the
    grid's cells (4 cm squares): whatever the drawn angle, its predicted path (1.5 x 5 cm)
    keeps 8 cm inside the edge and 3 cm off every other object; boxed in, it is not pushed."""
    poses = jigsaw.sim.object_poses()
    cube = np.array(poses["spare_left_0"])
    for angle in np.linspace(0, 2 * np.pi, 16, endpoint=False):
        force, _ = slide_push(jigsaw.station, "spare_left_0", poses, 0.05, angle)
        end = cube[:2] + 0.075 * np.asarray(force[:2]) / np.linalg.norm(force[:2])
        assert abs(end[1]) <= 0.35 - 0.08 - 0.02 + 1e-9  # never over the near edge
        for name, pose in poses.items():
            if name != "spare_left_0":
                assert np.linalg.norm(end - pose[:2]) >= 0.02 + 0.02 + 0.03 - 1e-9, name
    neighbours = [
        "spare_right_0",
        "spare_right_1",
        "spare_left_1",
        min(n for n in poses if n[:5] == "cube_"),
    ]
    boxed = dict(poses)
    for name, offset in zip(
        neighbours, ([0.07, 0], [-0.07, 0], [0, 0.07], [0, -0.07]), strict=True
    ):
        boxed[name] = np.concatenate([cube[:2] + offset, cube[2:]])
    assert slide_push(jigsaw.station, "spare_left_0", boxed, 0.05, 0.0) is None


# --------------------------------------------------------------------------- physics
def test_a_push_moves_a_free_object_through_the_plant(jigsaw):
    """A force on the plant's applied-spatial-force input for two control steps slides a spare
    cube a few cm (4 asked); the driver sets no state (the plant's positions are untouched by
    it), and the same steps without the force leave the cube where it was."""
    sim = jigsaw.sim
    home = sim.station.embodiment.home_action()
    poses = sim.object_poses()
    force, point = slide_push(sim.station, "spare_left_0", poses, 0.04, np.pi / 2)
    push = Disturbance(
        kind="push", step=8, duration=2, body="spare_left_0", force=force, point=point
    )
    port = sim.station.plant.get_applied_spatial_force_input_port()
    moved = {}
    for name, schedule in (("pushed", [push]), ("still", [])):
        sim.reset(home)
        driver = DisturbanceDriver(sim, schedule)
        for t in range(30):
            if t == 8:
                start = sim.object_poses()["spare_left_0"][:3]
            q = sim.station.plant.GetPositionsAndVelocities(sim.plant_context).copy()
            executed = driver.before_step(t, home)
            assert executed is home  # a push leaves the action alone
            assert np.array_equal(q, sim.station.plant.GetPositionsAndVelocities(sim.plant_context))
            if schedule:
                ctx = sim.plant_context
                applied = port.Eval(ctx) if port.HasValue(ctx) else []
                assert len(applied) == (1 if push.active(t) else 0)
            sim.step(executed)
        moved[name] = np.linalg.norm(sim.object_poses()["spare_left_0"][:3] - start)
        driver.clear()
    assert 0.015 < moved["pushed"] < 0.07, moved  # 4 cm asked: 2.9 cm measured
    assert moved["still"] < 1e-3, moved


def test_a_drop_opens_the_executed_gripper_evenly_only_while_it_acts(jigsaw):
    sim = jigsaw.sim
    layout = sim.station.layout
    drop = Disturbance(kind="drop", step=2, duration=3, body="spare_left_1", side="left")
    driver = DisturbanceDriver(sim, [drop])
    action = layout.compose(
        {s: sim.station.embodiment.home_of(s) for s in ("left", "right")},
        {"left": 0.0, "right": 0.0},
    )
    out = [driver.before_step(t, action) for t in range(6)]
    opened = [float(a[layout.gripper("left")]) for a in out]
    n = dist.steps_of(dist.DROP_OPEN_SECONDS, sim.station.config.control_period)
    assert opened == pytest.approx([0.0, 0.0, 1 / n, 2 / n, 3 / n, 0.0])  # a loosening grip
    again = [driver.before_step(t, a) for t, a in enumerate(out)]  # a replay of what ran
    assert all(np.array_equal(a, b) for a, b in zip(again, out, strict=True))
    assert all(a[layout.gripper("right")] == 0.0 for a in out)
    assert action[layout.gripper("left")] == 0.0  # the label is not touched
    with pytest.raises(ValueError, match="no such object"):
        DisturbanceDriver(sim, [drop.model_copy(update={"body": "ghost"})])


def test_without_disturbances_the_expert_runs_as_before():
    """The plain run (what generation does without ``disturb``) and the traced clean run a
    disturbed episode starts from (the expert's reads watched, every frame's contacts read)
    send the same actions bit for bit: watching changes nothing, so a disturbance's window
    holds in the disturbed run up to its step."""
    setup = EpisodeSetup(task="balance_roller", seed=0, split="seen", station=STATION)
    plain = gen._simulate(setup, 0.0, Stopwatch())
    traced = gen._simulate(setup, 0.0, Stopwatch(), schedule=[], trace=True)
    assert plain.failure is None and traced.failure is None
    assert np.array_equal(plain.recorder.actions, traced.recorder.actions)
    assert plain.recorder.executed_actions is None and traced.recorder.executed_actions is None
    assert len(traced.trace.frames) == len(plain.recorder) and traced.trace.boundaries
    assert not plain.reads  # the plain run does not even watch


# --------------------------------------------------------------------------- the file
def recorded(disturbances) -> EpisodeRecorder:
    recorder = EpisodeRecorder(fps=15.0, initial_action=np.zeros(14))
    for _ in range(6):
        recorder.add_frame(
            action=np.zeros(14),
            joint_state=np.zeros(14),
            left_endpose=[0, 0, 1, 1, 0, 0, 0],
            right_endpose=[0.5, 0, 1, 1, 0, 0, 0],
            object_poses={},
        )
    recorder.disturbances = dist.disturbance_records(disturbances)
    recorder.recovery_rows = [dist.recovery_row(d, 5) for d in disturbances]
    return recorder


def test_the_file_records_the_disturbance_and_its_recovery_row(tmp_path):
    import h5py

    meta = dict(
        task="jigsaw", seed=0, instruction="x", embodiment="aloha_viperx", success=True,
        object_count=1,
    )  # fmt: skip
    rows = [[0, 2, "a", "l", "r", 0.5], [2, 6, "b", "l", "r", 0.5]]
    push = Disturbance(
        kind="push", step=1, duration=2, body="cube", force=(0.1, 0.5, 0.0), point=(0, 0, -0.01)
    )
    drop = Disturbance(kind="drop", step=3, duration=2, body="cube", side="right")
    path = recorded([push, drop]).write(
        tmp_path / "e.hdf5", rows, {**meta, "extra": {"disturb": "push,drop"}}
    )
    episode = read_episode(path)
    assert dist.from_records(episode.disturbances) == [push, drop]
    assert episode.recovery == [dist.recovery_row(push, 5), dist.recovery_row(drop, 5)]
    assert episode.stages == rows  # the task's stage rows stay as they are
    with h5py.File(path) as f:
        assert np.allclose(f["disturbances/wrench"][0], [0, 0, 0, 0.1, 0.5, 0])
        assert list(f["disturbances/side"].asstr()[()]) == ["", "right"]
        assert f.attrs["disturb"] == "push,drop"
    clean = read_episode(recorded([]).write(tmp_path / "c.hdf5", rows, meta))
    assert clean.disturbances == [] and clean.recovery == []
    with h5py.File(clean.path) as f:
        assert "disturbances" not in f and "stages/recovery" not in f and "disturb" not in f.attrs
    bad = recorded([push])
    bad.recovery_rows = [[4, 9, "x", "l", "r", 0.0]]
    with pytest.raises(ValueError, match="recovery row 0"):
        bad.write(tmp_path / "b.hdf5", rows, meta)


# --------------------------------------------------------------------------- an episode
def test_a_pushed_episode_is_kept_recorded_and_replayed(tmp_path):
    """balance_roller seed 0 with ``disturb=push``: the cube is pushed a few cm before the
    hands lift the roller, the expert carries the roller over the cube where it now stands and
    the episode is kept; the file records the push and its recovery row, the replay (the
    recorded actions, the push applied again) reproduces every frame and stage, and the
    episode's scenario makes it again bit for bit."""
    from bicoord_drake.env import make_env
    from bicoord_drake.policies.builtin import ReplayPolicy

    config = gen.GenerateConfig(
        task="balance_roller", seed=0, episodes=1, max_tries=1, render=False,
        disturb="push", out=str(tmp_path / "a"), workers=1,
    )  # fmt: skip
    assert config.config_name == "default_disturbed"
    summary = gen.generate(config)
    assert summary.kept == 1, [f.reason for f in summary.failures]
    episode = read_episode(summary.root / "data" / "episode0.hdf5", images=False)
    (push,) = dist.from_records(episode.disturbances)
    assert push.kind == "push" and push.body == "block" and episode.attrs["disturb"] == "push"
    ((start, end, subgoal, *_),) = episode.recovery
    assert start == push.step < push.end <= end <= episode.length
    assert subgoal.startswith("recover from the push on 'block'")
    block = episode.objects["block"]
    moved = np.linalg.norm(block[end - 1, :2] - block[push.step, :2])
    assert 0.015 < moved < 0.07, moved
    assert episode.executed_action is None  # a push leaves the actions alone
    assert load_scenario(episode.path).disturb == ("push",)

    env = make_env("balance_roller", render=False, split="seen")
    obs = env.reset(episode=episode)
    assert env.disturbances == (push,)
    policy = ReplayPolicy()
    policy.bind(env)
    policy.reset(env.instruction)
    t, info = 0, {"done": False}
    while not info["done"] and t + 1 < episode.length:
        obs, info = env.step(policy.act(obs))
        t += 1
        assert np.array_equal(obs["joint_state"], episode.joint_state[t]), t
        assert np.array_equal(obs["object_poses"]["block"], block[t]), t
    assert info["success"] and all(info["completed"])
    env.reset(seed=episode.seed)  # a plain reset applies nothing
    assert env.disturbances == ()
    env.close()

    again = gen.GenerateConfig(
        scenario=load_scenario(episode.path), out=str(tmp_path / "b"), max_tries=1, workers=1
    )
    root = gen.generate(again).root
    assert "bit for bit" in gen.compare_regenerated(episode.path, root, 0)
    made = read_episode(root / "data" / "episode0.hdf5", images=False)
    assert made.disturbances == episode.disturbances


@pytest.mark.parametrize(
    ("kind", "end"),
    [("push", 30), ("drop", 80), ("knock", 80)],
)
def test_a_recovery_row_ends_where_the_expert_put_things_back(kind, end):
    """A push's recovery ends at the expert's next read of the world (step 30); a drop's and a
    knock's where the expert noted that it had picked up and placed again what fell or was
    knocked away (step 80), not at an earlier note or read; never past the episode."""
    force = (1.0, 0.0, 0.0) if kind != "drop" else (0.0, 0.0, 0.0)
    side = {"side": "left"} if kind == "drop" else {}
    d = Disturbance(kind=kind, step=20, duration=3, body="cube", force=force, **side)
    assert gen.recovery_end(d, reads={10, 30, 60}, recovered={15, 80}, frames=200) == end
    assert gen.recovery_end(d, reads={10, 30, 60}, recovered={15, 80}, frames=50) == min(end, 50)
