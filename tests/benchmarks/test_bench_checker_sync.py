"""benchmarks/bench_checker_sync.py: its cases, its table, and that its *rebuild* runs really
rebuild the checker's shapes (the A/B it reports), then leave the package as it was."""

import pytest

from bicoord_drake.models.scene import demo_scene
from bicoord_drake.planning.model import PlanningModel
from tests.runner.benchmark_scripts import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_checker_sync")


def test_cases_are_task_robot_seed(bench):
    args = bench.parse_args(["--cases", "jigsaw:franka_pair:3,cook:aloha_viperx:0"])
    assert args.cases == [("jigsaw", "franka_pair", 3), ("cook", "aloha_viperx", 0)]
    with pytest.raises(SystemExit):
        bench.parse_args(["--cases", "jigsaw:franka_pair"])
    with pytest.raises(SystemExit):
        bench.parse_args(["--repeats", "0"])


def test_rebuild_mode_adds_the_shapes_again_and_is_undone(bench):
    m = PlanningModel(demo_scene("cubes"))
    m.attach("cube_0", "left", m.home.copy())
    calls = []
    real = m.checker

    class Spy:
        def __getattr__(self, name):
            return getattr(real, name)

        def AddCollisionShapeToBody(self, *args):  # noqa: N802 - Drake's name
            calls.append(args)
            return real.AddCollisionShapeToBody(*args)

    m.checker = Spy()
    m._sync_checker_held()
    assert calls == []  # kept: nothing added for an unchanged hold
    bench.forget_checker_state()
    try:
        m._sync_checker_held()
        assert len(calls) >= 1  # rebuilt, as before the change
    finally:
        bench.restore_checker_state()
    calls.clear()
    m._sync_checker_held()
    assert calls == []


def test_the_table_gives_the_ratio_and_flags_different_actions(bench):
    run = {"planning": 2.0, "wall": 10.0, "success": True}
    slow = {"planning": 3.0, "wall": 11.0, "success": True}
    rows = [
        {"task": "t", "robot": "r", "seed": 0, "repeats": 1, "keep": run, "rebuild": slow,
         "same": True},
        {"task": "u", "robot": "r", "seed": 1, "repeats": 1, "keep": run, "rebuild": slow,
         "same": False},
    ]  # fmt: skip
    text = bench.markdown(rows, "python benchmarks/bench_checker_sync.py")
    assert "| t | r | 0 | 2.00 | 3.00 | 1.50 | 10.0 | 11.0 | yes | True / True |" in text
    assert "| **no** |" in text
    assert "planning 6.0 s rebuilding against 4.0 s keeping (1.50x)" in text
