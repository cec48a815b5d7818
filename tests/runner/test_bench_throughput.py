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
