"""benchmarks/noise_sweep.py: success against action-noise level, resumable, one table."""

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "noise_sweep.py"


@pytest.fixture(scope="module")
def ns():
    spec = importlib.util.spec_from_file_location("noise_sweep", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def fake_runs(ns, monkeypatch, kept_by_sigma):
    """run_task replaced: kept seeds per level, the calls recorded."""
    calls = []

    def run_task(task, seeds, workers, work_dir, action_noise=0.0, **_):
        calls.append((task, action_noise))
        kept = kept_by_sigma[action_noise]
        return ns.es.TaskResult(
            task=ns.es.section_name(task, action_noise=action_noise),
            seeds=seeds,
            kept=kept,
            tried=len(seeds),
            failures=[(s, "stage_not_verified: x") for s in seeds[kept:]],
            commit="abc",
        )

    monkeypatch.setattr(ns.es, "run_task", run_task)
    monkeypatch.setattr(ns.es, "git_state", lambda root=None: ("abc", False))
    return calls


def test_table_default_level_and_sections(ns, tmp_path, monkeypatch):
    calls = fake_runs(ns, monkeypatch, {0.005: 10, 0.01: 8, 0.02: 5})
    out = tmp_path / "sweep.md"
    argv = ["--tasks", "jigsaw,cook", "--sigmas", "0.02,0.005,0.01", "--seeds", "0-9"]
    assert ns.main([*argv, "--out", str(out)]) == 0
    assert len(calls) == 6
    text = out.read_text()
    assert "| jigsaw | 10/10 (100 %) | 8/10 (80 %) | 5/10 (50 %) **<** |" in text
    assert "Default level supported: σ = 0.01 rad" in text
    assert "## cook (action noise 0.02 rad)" in text and "| 5 | stage_not_verified: x |" in text
    # resumed: nothing measured again at the same commit and seeds
    assert ns.main([*argv, "--out", str(out)]) == 0
    assert len(calls) == 6
    stored = json.loads(out.with_suffix(".json").read_text())
    assert stored["cook@0.01"]["kept"] == 8
    # other seeds are a new measurement
    assert ns.main([*argv[:-1], "0-4", "--out", str(out)]) == 0
    assert len(calls) == 12


def test_no_default_level_when_the_smallest_fails(ns):
    cells = {"a@0.005": {"kept": 7, "tried": 10}, "a@0.01": {"kept": 10, "tried": 10}}
    assert ns.default_level(cells, ["a"], [0.005, 0.01], 0.8) is None
    cells["a@0.005"]["kept"] = 8
    assert ns.default_level(cells, ["a"], [0.005, 0.01], 0.8) == 0.01
    assert ns.default_level(cells, ["a", "b"], [0.005, 0.01], 0.8) is None  # b unmeasured


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--sigmas", "0.5"], "[0, 0.2] rad"),
        (["--sigmas", "0.005-0.01"], "single levels"),
        (["--tasks", "origami"], "jigsaw"),
        (["--goal", "1.5"], "--goal"),
    ],
)
def test_bad_input_is_refused_before_running(args, words, tmp_path):
    out = tmp_path / "sweep.md"
    done = subprocess.run(
        [sys.executable, str(SCRIPT), *args, "--out", str(out)], capture_output=True, text=True
    )
    assert done.returncode == 2, done.stderr
    assert words in done.stderr and "Traceback" not in done.stderr
    assert not out.exists()
