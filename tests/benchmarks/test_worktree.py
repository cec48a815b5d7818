"""expert_success.worktree, the one checkout of a revision the benchmark scripts use for
``--before`` (bench_early_stop, bench_rest_cost, bench_throughput): git for real, in this
repository at HEAD; bench_throughput's measurements faked (no physics)."""

import subprocess
import sys
import tempfile
from contextlib import nullcontext
from pathlib import Path

import pytest

from tests.runner.benchmark_scripts import load_benchmark


@pytest.fixture(scope="module")
def es():
    return load_benchmark("expert_success")


@pytest.fixture
def tmp(tmp_path, monkeypatch):
    """tempfile's directory for the test: the worktrees' temporary directories go there."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    return tmp_path


def git(root: Path, *args: str) -> str:
    return subprocess.run(
        ["git", *args], cwd=root, check=True, capture_output=True, text=True
    ).stdout.strip()


def worktrees(root: Path) -> set[Path]:
    """The worktrees git knows of `root`'s repository (resolved paths)."""
    lines = git(root, "worktree", "list", "--porcelain").splitlines()
    return {Path(line.split(" ", 1)[1]).resolve() for line in lines if line.startswith("worktree ")}


def test_no_revision_is_no_tree(es, tmp):
    with es.worktree(None, "test-worktree-") as tree:
        assert tree is None
    assert list(tmp.iterdir()) == []


@pytest.mark.parametrize("error", [False, True])
def test_a_worktree_of_head_is_removed_on_the_way_out(es, tmp, error):
    head = git(es.ROOT, "rev-parse", "HEAD")
    seen = []
    with pytest.raises(ValueError) if error else nullcontext():
        with es.worktree("HEAD", "test-worktree-") as tree:
            seen.append(tree)
            assert tree.name == "tree" and tree.parent.parent == tmp
            assert tree.parent.name.startswith("test-worktree-")
            assert git(tree, "rev-parse", "HEAD") == head  # detached at the revision
            assert (tree / "benchmarks" / "expert_success.py").is_file()
            assert tree.resolve() in worktrees(es.ROOT)
            if error:
                raise ValueError("the body failed")
    assert seen and not seen[0].parent.exists()
    assert seen[0].resolve() not in worktrees(es.ROOT)
    assert list(tmp.iterdir()) == []


def test_a_revision_git_cannot_check_out_is_named_with_gits_message(es, tmp):
    before = worktrees(es.ROOT)
    with pytest.raises(RuntimeError) as err:
        with es.worktree("no-such-revision", "test-worktree-"):
            pytest.fail("the body ran")
    message = str(err.value)
    assert message.startswith("git worktree add no-such-revision failed: ")
    assert "fatal:" in message and "no-such-revision" in message.split("failed: ", 1)[1]
    assert list(tmp.iterdir()) == [] and worktrees(es.ROOT) == before


# --------------------------------------------------------------------------- bench_throughput
@pytest.fixture
def bench():
    return load_benchmark("bench_throughput")


def fake_measure(calls: list, fail_in: Path | None = None):
    """bench_throughput.measure without generate.py: records the tree (and that it exists)."""

    def measure(tree, task, episodes, seed, workers, render, embodiment="aloha_viperx", sets=()):
        calls.append((tree, tree.is_dir()) + ((tuple(sets),) if sets else ()))
        if tree == fail_in:
            raise RuntimeError("generate.py failed")
        return {
            "wall": 10.0,
            "simulated": 5.0,
            "rate": 0.5,
            "kept": episodes,
            "tried": episodes,
            "split": {"physics": 2.0},
            "load": 0.0,
        }

    return measure


def argv(out: Path, *extra: str) -> list[str]:
    return ["bench_throughput.py", "--tasks", "jigsaw", "--workers", "1", "--out", str(out), *extra]


def test_throughput_before_measures_a_worktree_then_removes_it(bench, tmp, monkeypatch):
    calls = []
    monkeypatch.setattr(bench, "measure", fake_measure(calls))
    monkeypatch.setattr(sys, "argv", argv(tmp / "out.md", "--before", "HEAD"))
    bench.main()
    (tree, present), (here, _) = calls
    assert present and tree.name == "tree" and tree.parent.parent == tmp and here == bench.ROOT
    assert not tree.parent.exists() and tree.resolve() not in worktrees(bench.ROOT)
    head = git(bench.ROOT, "rev-parse", "--short", "HEAD")
    assert f"/ before (`{head}`)" in (tmp / "out.md").read_text()
    assert [p.name for p in tmp.iterdir()] == ["out.md"]


def test_throughput_before_removes_the_worktree_when_a_run_fails(bench, tmp, monkeypatch):
    calls = []

    def measure(tree, *args):
        return fake_measure(calls, fail_in=tree if tree != bench.ROOT else None)(tree, *args)

    monkeypatch.setattr(bench, "measure", measure)
    monkeypatch.setattr(sys, "argv", argv(tmp / "out.md", "--before", "HEAD"))
    with pytest.raises(RuntimeError, match="generate.py failed"):
        bench.main()
    [(tree, present)] = calls
    assert present and not tree.parent.exists() and tree.resolve() not in worktrees(bench.ROOT)
    assert list(tmp.iterdir()) == []


def test_throughput_without_before_measures_this_checkout_only(bench, tmp, monkeypatch):
    calls = []
    monkeypatch.setattr(bench, "measure", fake_measure(calls))
    monkeypatch.setattr(sys, "argv", argv(tmp / "out.md"))
    bench.main()
    assert calls == [(bench.ROOT, True)]
    assert "/ before" not in (tmp / "out.md").read_text()


def test_throughput_before_git_cannot_check_out_is_named(bench, tmp, monkeypatch):
    monkeypatch.setattr(bench, "measure", lambda *a: pytest.fail("measured"))
    monkeypatch.setattr(sys, "argv", argv(tmp / "out.md", "--before", "no-such-revision"))
    with pytest.raises(RuntimeError, match="git worktree add no-such-revision failed: fatal"):
        bench.main()
    assert list(tmp.iterdir()) == []


def test_throughput_versus_measures_this_checkout_without_then_with_the_settings(
    bench, tmp, monkeypatch
):
    calls = []
    monkeypatch.setattr(bench, "measure", fake_measure(calls))
    gl = "station.cameras.renderer=gl"
    monkeypatch.setattr(
        sys, "argv", argv(tmp / "out.md", "--set", "station.time_step=0.004", "--versus", gl)
    )
    bench.main()
    base = ("station.time_step=0.004",)
    assert calls == [(bench.ROOT, True, base), (bench.ROOT, True, (*base, gl))]
    text = (tmp / "out.md").read_text()
    head = git(bench.ROOT, "rev-parse", "--short", "HEAD")
    assert f"After (`{head}` + {gl}) / before (`{head}`)" in text
    assert "--set station.time_step=0.004" in text
    assert "| jigsaw | yes | 1 | 1.00x | 1.00x |" in text


def test_throughput_refuses_before_and_versus_together(bench, tmp, monkeypatch):
    monkeypatch.setattr(bench, "measure", fake_measure([]))
    monkeypatch.setattr(sys, "argv", argv(tmp / "out.md", "--before", "HEAD", "--versus", "a=1"))
    with pytest.raises(SystemExit):
        bench.main()
