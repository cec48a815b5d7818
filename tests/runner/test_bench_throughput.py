"""The throughput benchmark's before/after table: ratios of the run rate and the physics phase."""

import pytest

from tests.runner.benchmark_scripts import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_throughput")


def _row(commit, task, wall, physics, simulated=20.0):
    return {
        "commit": commit,
        "before": commit == "old",
        "task": task,
        "render": False,
        "workers": 1,
        "kept": 1,
        "tried": 1,
        "simulated": simulated,
        "wall": wall,
        "rate": simulated / wall,
        "split": {"physics": physics, "planning": 2.0},
        "load": 1.0,
    }


def test_ratio_table_gives_run_and_physics_ratios_and_their_medians(bench):
    rows = [
        _row("old", "a", wall=40.0, physics=30.0),
        _row("new", "a", wall=20.0, physics=10.0),
        _row("old", "b", wall=30.0, physics=20.0),
        _row("new", "b", wall=30.0, physics=20.0),
        _row("new", "c", wall=10.0, physics=5.0),  # no 'before' row: left out
    ]
    text = bench.ratio_table(rows)
    assert "After (`new`) / before (`old`)" in text
    assert "| a | no | 1 | 2.00x | 3.00x |" in text
    assert "| b | no | 1 | 1.00x | 1.00x |" in text
    assert "| c |" not in text
    assert "**1.50x** | **2.00x**" in text


def test_physics_rate_needs_a_physics_phase(bench):
    assert bench.physics_rate(_row("x", "a", wall=10.0, physics=4.0)) == pytest.approx(5.0)
    assert bench.physics_rate({**_row("x", "a", 10.0, 0.0), "split": {}}) is None


def test_ratio_table_pairs_by_checkout_when_head_moves_during_the_run(bench):
    """A commit landing mid-run gives this checkout's rows two commits; they still pair with
    the --before rows (before, no ratio table came out at all)."""
    rows = [
        _row("old", "a", wall=40.0, physics=30.0),
        _row("new1", "a", wall=20.0, physics=10.0),
        _row("old", "b", wall=30.0, physics=20.0),
        _row("new2", "b", wall=15.0, physics=10.0),
    ]
    text = bench.ratio_table(rows)
    assert "After (`new1`, `new2`) / before (`old`)" in text
    assert "| a | no | 1 | 2.00x | 3.00x |" in text
    assert "| b | no | 1 | 2.00x | 2.00x |" in text


def test_no_ratio_table_without_a_before_run(bench):
    assert bench.ratio_table([_row("new", "a", wall=20.0, physics=10.0)]) == ""


def _fake_generate(manifest_dir: str, calls: list):
    """A stand-in for subprocess.run of generate.py: records the command, writes one kept
    30-frame episode's manifest under <out>/<task>/<manifest_dir>/."""
    import json
    from pathlib import Path
    from types import SimpleNamespace

    def run(cmd, **kwargs):
        calls.append(cmd)
        opts = dict(a[2:].split("=", 1) for a in cmd if a.startswith("--") and "=" in a)
        where = Path(opts["out"]) / opts["task"] / manifest_dir
        where.mkdir(parents=True)
        episode = {"success": True, "frames": 30, "timings": {"physics": 1.5, "planning": 0.5}}
        manifest = {"config": {"fps": 15.0}, "episodes": [episode]}
        (where / "manifest.json").write_text(json.dumps(manifest))
        return SimpleNamespace(returncode=0, stderr="")

    return run


def test_measure_passes_another_robot_and_reads_its_settings_directory(bench, monkeypatch):
    calls: list = []
    monkeypatch.setattr(bench.subprocess, "run", _fake_generate("franka_pair", calls))
    gl = "station.cameras.renderer=gl"
    row = bench.measure(bench.ROOT, "jigsaw", 1, 0, 2, False, "franka_pair", (gl,))
    assert "--embodiment=franka_pair" in calls[0] and "--no-render" in calls[0]
    assert calls[0][-2:] == ["--set", gl]
    assert (row["kept"], row["tried"], row["simulated"]) == (1, 1, 2.0)
    assert row["split"] == {"physics": 1.5, "planning": 0.5}


def test_measure_leaves_the_default_robot_to_generate(bench, monkeypatch):
    calls: list = []
    monkeypatch.setattr(bench.subprocess, "run", _fake_generate("default", calls))
    bench.measure(bench.ROOT, "jigsaw", 1, 0, 1, True)
    assert not any(a.startswith("--embodiment") for a in calls[0])
    assert "--no-render" not in calls[0]


def test_totals_sum_the_runs_of_each_side(bench):
    rows = [
        _row("old", "a", wall=40.0, physics=30.0),
        _row("old", "b", wall=60.0, physics=6.0),
        _row("new", "a", wall=20.0, physics=6.0),
    ]
    lines = bench.totals(rows).splitlines()
    assert lines[0].startswith("- `old`, 2 runs: 40.0 simulated s of kept episodes in 100.0 wall s")
    assert "**0.40 simulated s per wall s**" in lines[0]
    assert "worker time 40.0 s: planning 10 %, physics 90 %" in lines[0]
    assert (
        "**1.00 simulated s per wall s**" in lines[1] and "planning 25 %, physics 75 %" in lines[1]
    )
