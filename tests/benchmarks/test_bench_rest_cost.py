"""benchmarks/bench_rest_cost.py: its arguments, the exit for a --before git cannot resolve or
check out, its worktree removed at the end, the packages taking turns, medians and ratio, the
face breakdown by body pair and its Markdown section (the measuring processes faked: no
physics)."""

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

import pytest

from tests.runner.benchmark_scripts import load_benchmark

TASK = "handover_block_with_bowls"


@pytest.fixture(scope="module")
def brc():
    return load_benchmark("bench_rest_cost")


def test_defaults_and_task_lists(brc):
    args = brc.parse_args(["--task", TASK])
    assert args.tasks == [TASK] and args.seed == 0 and args.embodiment is None
    assert (args.warmup, args.steps, args.repeats) == (5, 30, 5)
    assert args.before is None and args.out is None and not args.measure_json
    args = brc.parse_args(["--tasks", "cook, jigsaw,cook", "--seed", "3", "--before", "HEAD~1"])
    assert args.tasks == ["cook", "jigsaw"] and args.seed == 3 and args.before == "HEAD~1"


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["--task", ","],
        ["--task", TASK, "--steps", "0"],
        ["--task", TASK, "--repeats", "0"],
        ["--task", TASK, "--warmup", "-1"],
        ["--tasks", "cook,jigsaw", "--measure-json"],
    ],
)
def test_bad_arguments(brc, argv):
    with pytest.raises(SystemExit):
        brc.parse_args(argv)


def test_measure_command_is_this_file_in_json_mode(brc):
    args = brc.parse_args(["--task", TASK, "--seed", "2", "--warmup", "1", "--steps", "3"])
    command = brc.measure_command(TASK, args)
    assert command[1] == str(brc.BENCHMARKS / "bench_rest_cost.py")
    assert command[2:] == ["--measure-json", "--task", TASK, "--seed", "2", "--warmup", "1",
                           "--steps", "3"]  # fmt: skip
    args.embodiment = "franka_pair"
    assert brc.measure_command(TASK, args)[-2:] == ["--embodiment", "franka_pair"]


def _no_measurement(*args, **kwargs):
    raise AssertionError("measured despite a bad --before")


def test_an_unknown_revision_exits_2_before_measuring(brc, monkeypatch, capsys):
    monkeypatch.setattr(brc, "run", _no_measurement)
    monkeypatch.setattr(brc, "measure_in", _no_measurement)
    bad = "0123456789abcdef0123456789abcdef01234567"  # a hash this repository does not hold
    assert brc.resolve(bad) is None
    assert brc.main(["--task", TASK, "--before", bad]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and bad in err[0]


def test_a_faked_git_failure_exits_2_too(brc, monkeypatch, capsys):
    monkeypatch.setattr(brc, "resolve", lambda rev, root=brc.ROOT: None)
    monkeypatch.setattr(brc, "run", _no_measurement)
    assert brc.main(["--task", TASK, "--before", "no-such-branch"]) == 2
    assert "no-such-branch" in capsys.readouterr().err


def test_a_real_revision_resolves_to_its_short_hash(brc):
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=brc.ROOT, capture_output=True, text=True
    ).stdout.strip()
    short = brc.resolve("HEAD")
    assert short and head.startswith(short)


def test_a_revision_git_cannot_check_out_exits_1_naming_it(brc, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the worktree's temporary directory
    monkeypatch.setattr(brc, "resolve", lambda rev, root=brc.ROOT: "no-such-revision")
    monkeypatch.setattr(brc, "run", _no_measurement)
    assert brc.main(["--task", TASK, "--before", "no-such-revision"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("error: git worktree add no-such-revision failed: fatal:")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("fails", [False, True])
def test_the_worktree_of_before_is_removed_at_the_end(brc, tmp_path, monkeypatch, capsys, fails):
    """expert_success.worktree for real, of HEAD; the measurements faked."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the worktree's temporary directory
    seen = []

    def run(args, packages, command):
        seen.extend((p.label, p.tree, p.tree.is_dir()) for p in packages)
        if fails:
            raise RuntimeError("a measurement failed")
        return [], False

    monkeypatch.setattr(brc, "run", run)
    assert brc.main(["--task", TASK, "--before", "HEAD"]) == (1 if fails else 0)
    (before, tree, present), (after, here, _) = seen
    assert (before, after, here) == ("before", "after", brc.ROOT) and present
    assert tree.parent.parent == tmp_path and not tree.parent.exists()
    listed = subprocess.run(
        ["git", "worktree", "list", "--porcelain"], cwd=brc.ROOT, capture_output=True, text=True
    ).stdout
    assert f"worktree {tree.resolve()}\n" not in listed
    assert list(tmp_path.iterdir()) == []
    err = capsys.readouterr().err
    assert ("[bench_rest_cost] error: a measurement failed" in err) == fails


def result(package: Path, cpu: float, faces: int = 10, drift: float = 0.0) -> dict:
    return {
        "task": TASK,
        "seed": 0,
        "embodiment": "aloha_viperx",
        "package": str(package / "bicoord_drake"),
        "cpu_ms": cpu,
        "wall_ms": 2 * cpu,
        "drift_mm": drift,
        "surfaces": 2,
        "faces": faces,
        "points": 0,
        "pairs": [["bowl_0", "table", faces, 0]],
    }


class FakeRunner:
    """subprocess.run for the measuring processes: records where each ran and answers a JSON
    line whose package is under that directory, the CPU ms the next of `cpus`."""

    def __init__(self, cpus: list[float]):
        self.cpus = list(cpus)
        self.calls: list[tuple[Path, str]] = []

    def __call__(self, command, *, cwd, env, capture_output, text):
        assert "--measure-json" in command and capture_output and text
        self.calls.append((Path(cwd), env["PYTHONPATH"].split(":")[0]))
        line = json.dumps(result(Path(cwd), self.cpus.pop(0)))
        return subprocess.CompletedProcess(command, 0, f"drake says hello\n{line}\n", "")


def packages(brc, tree: Path) -> list:
    return [brc.Package("before", tree, "aaaaaaa"), brc.Package("after", brc.ROOT, "bbbbbbb")]


def test_the_packages_take_turns_and_the_table_gives_medians_and_ratio(brc, tmp_path):
    tree = tmp_path / "tree"
    args = brc.parse_args(["--task", TASK, "--repeats", "3", "--before", "HEAD"])
    runner = FakeRunner([30, 10, 40, 12, 35, 11])
    rows, moved = brc.run(args, packages(brc, tree), "python benchmarks/bench_rest_cost.py", runner)
    assert [cwd for cwd, _ in runner.calls] == [tree, brc.ROOT] * 3
    assert [path for _, path in runner.calls] == [str(tree), str(brc.ROOT)] * 3
    assert not moved
    assert rows[0].startswith(f"| {TASK} | before | `aaaaaaa` | 35.0 | 70.0 | 2 | 10 | 0 |")
    assert rows[1].startswith(f"| {TASK} | after | `bbbbbbb` | 11.0 | 22.0 |")
    assert "**3.18x**" in rows[2]


def test_alternate_orders_the_labels_per_repeat(brc):
    order = []
    runs = brc.alternate(["before", "after"], 3, lambda label: order.append(label) or len(order))
    assert order == ["before", "after"] * 3
    assert runs == {"before": [1, 3, 5], "after": [2, 4, 6]}


def test_a_failed_or_misplaced_measurement_is_an_error(brc, tmp_path):
    args = brc.parse_args(["--task", TASK])
    package = brc.Package("before", tmp_path, "aaaaaaa")

    def failing(command, **kwargs):
        return subprocess.CompletedProcess(command, 1, "", "Traceback: boom")

    with pytest.raises(RuntimeError, match="boom"):
        brc.measure_in(package, TASK, args, failing)

    def elsewhere(command, **kwargs):  # imported this checkout's package, not the tree's
        return subprocess.CompletedProcess(command, 0, json.dumps(result(brc.ROOT, 1.0)), "")

    with pytest.raises(RuntimeError, match="imported bicoord_drake from"):
        brc.measure_in(package, TASK, args, elsewhere)


def test_summary_medians_largest_drift_and_ratio(brc, tmp_path):
    runs = [result(tmp_path, c, f, d) for c, f, d in [(3.0, 10, 0.1), (1.0, 12, 0.4), (2.0, 11, 0)]]
    s = brc.summary(runs)
    assert (s["cpu_ms"], s["wall_ms"], s["faces"], s["surfaces"]) == (2.0, 4.0, 11, 2)
    assert s["drift_mm"] == 0.4 and s["runs"] == 3 and s["pairs"] == runs[-1]["pairs"]
    assert brc.ratio({"before": {"cpu_ms": 118.0}, "after": {"cpu_ms": 31.0}}) == pytest.approx(
        118 / 31
    )
    assert brc.ratio({"this checkout": s}) is None


def test_a_drifting_scene_is_flagged(brc, tmp_path):
    args = brc.parse_args(["--task", TASK, "--repeats", "1"])
    here = [brc.Package("this checkout", brc.ROOT, "bbbbbbb", dirty=True)]

    def drifting(command, *, cwd, **kwargs):
        line = json.dumps(result(Path(cwd), 5.0, drift=3.5))
        return subprocess.CompletedProcess(command, 0, line, "")

    rows, moved = brc.run(args, here, "cmd", drifting)
    assert moved and "**3.500** (moved)" in rows[0] and "`bbbbbbb` (dirty)" in rows[0]


def test_the_breakdown_sums_faces_and_points_by_body_pair(brc):
    surfaces = [
        ("bowl_0", "table", 100),
        ("table", "bowl_0", 40),  # the same pair, the other way round
        ("block", "bowl_0", 7),
        ("bowl_1", "table", 140),
    ]
    points = [("left/finger", "block"), ("block", "left/finger"), ("bowl_1", "table")]
    assert brc.breakdown(surfaces, points) == [
        ["bowl_1", "table", 140, 1],  # as many faces: more point contacts first
        ["bowl_0", "table", 140, 0],
        ["block", "bowl_0", 7, 0],
        ["block", "left/finger", 0, 2],
    ]
    assert brc.breakdown([]) == []


def test_body_labels_prefix_names_used_twice(brc):
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import SpatialInertia

    plant = MultibodyPlant(0.0)
    left, right = plant.AddModelInstance("left"), plant.AddModelInstance("right")
    inertia = SpatialInertia.SolidSphereWithMass(1.0, 0.1)
    for instance in (left, right):
        plant.AddRigidBody("finger", instance, inertia)
    plant.AddRigidBody("bowl_0", plant.AddModelInstance("bowls"), inertia)
    plant.Finalize()
    labels = set(brc.body_labels(plant).values())
    assert {"left::finger", "right::finger", "bowl_0", "world"} <= labels


def _section(brc, tmp_path, cpu_after: float) -> str:
    args = argparse.Namespace(seed=0, embodiment=None, steps=30, warmup=5, repeats=5)
    pkgs = packages(brc, tmp_path)
    stats = {
        "before": brc.summary([result(tmp_path, 118.0, faces=1784)]),
        "after": brc.summary([result(brc.ROOT, cpu_after, faces=242)]),
    }
    command = "python benchmarks/bench_rest_cost.py --task T --before 512374c"
    return brc.format_section(TASK, args, pkgs, stats, command, "512374c")


def test_the_section_and_the_writer_keep_other_sections(brc, tmp_path):
    section = _section(brc, tmp_path, 31.0)
    assert section.startswith(f"## {TASK} (seed 0, aloha_viperx)\n")
    for text in [
        "python benchmarks/bench_rest_cost.py --task T --before 512374c",
        "| machine | ",
        "| date (UTC) | ",
        "before `aaaaaaa` (`--before 512374c`); after `bbbbbbb`",
        f"| {TASK} | before | `aaaaaaa` | 118.0 | 236.0 | 2 | 1784 | 0 | 0.000 |",
        f"| {TASK} | after | `bbbbbbb` | 31.0 | 62.0 | 2 | 242 | 0 | 0.000 |",
        "before / after: **3.81x**",
        "### Faces by body pair, before (`aaaaaaa`)",
        "| bowl_0 | table | 1784 | 0 |",
        "1 of 1 body pairs in contact.",
    ]:
        assert text in section, text

    out = tmp_path / "rest.md"
    other = "## cook (seed 0, aloha_viperx)\n\nkept as it was\n"
    out.write_text(f"# Title\n\nintro\n\n{other}\n## {TASK} (seed 0, aloha_viperx)\n\nold\n")
    name = f"{TASK} (seed 0, aloha_viperx)"
    brc.write_sections(out, {name: section})
    text = out.read_text()
    assert text.startswith("# Title\n\nintro\n") and "kept as it was" in text
    assert "old" not in text and text.count(f"## {name}") == 1 and "3.81x" in text
    brc.write_sections(out, {name: _section(brc, tmp_path, 59.0)})
    text = out.read_text()
    assert "2.00x" in text and "3.81x" not in text and "kept as it was" in text
    assert not list(tmp_path.glob("*.tmp"))

    fresh = tmp_path / "new.md"
    brc.write_sections(fresh, {name: section})
    assert fresh.read_text().startswith(brc.TITLE)
