"""scripts/generate.py: bad input gives one line and no traceback; one real episode end to end."""

import json
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "generate.py"


def run(*args):
    env = dict(os.environ, PYTHONPATH=str(SCRIPT.parents[1]))  # this checkout's package
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, env=env
    )


def test_unknown_task_lists_the_tasks_and_exits_2():
    result = run("--task", "origami")
    assert result.returncode == 2
    assert "jigsaw" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize(
    "args,word",
    [
        (("--episodes", "0"), "episodes"),
        (("--seed", "-3"), "seed"),
        (("--seed", str(2**70)), "[0, 2**32)"),
        (("--resolution", "320by240"), "resolution"),
    ],
)
def test_bad_settings_are_one_line_errors(args, word):
    result = run("--task", "jigsaw", *args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and word in lines[0] and "Traceback" not in result.stderr


def test_unwritable_out_is_a_one_line_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    result = run("--task", "jigsaw", "--episodes", "1", "--out", str(blocker / "data"))
    assert result.returncode == 1
    assert "Traceback" not in result.stderr and "error:" in result.stderr


def test_one_jigsaw_episode_end_to_end(tmp_path):
    result = run(
        "--task", "jigsaw", "--episodes", "1", "--out", str(tmp_path), "--resolution", "64x48"
    )
    assert result.returncode == 0, result.stderr[-2000:]
    root = tmp_path / "jigsaw" / "default"
    with h5py.File(root / "data" / "episode0.hdf5") as f:
        T = f["joint_action/vector"].shape[0]
        assert f.attrs["success"] and f.attrs["task"] == "jigsaw"
        for cam in ("head_camera", "left_camera", "right_camera"):
            assert f[f"observation/{cam}/rgb"].shape == (T,)
        starts, ends = f["stages/start"][:], f["stages/end"][:]
        assert starts[0] == 0 and ends[-1] == T and np.all(starts[1:] == ends[:-1])
        assert f["stages/score"][:].sum() == pytest.approx(1.0)
    assert (root / "video" / "episode0.mp4").stat().st_size > 0
    assert "kept 1 / tried" in result.stdout and "SMP" in result.stdout
    # the run's rate and where the time went, also per episode in the manifest
    assert "1 kept episodes" in result.stdout and "simulated s per wall s" in result.stdout
    manifest = json.loads((root / "manifest.json").read_text())
    kept = next(e for e in manifest["episodes"] if e["success"])
    assert {"build", "planning", "physics", "render", "encode", "write"} <= set(kept["timings"])
    assert manifest["timings"]["physics"] >= kept["timings"]["physics"] > 0
    # running again resumes: nothing left to do, nothing rewritten
    again = run(
        "--task", "jigsaw", "--episodes", "1", "--out", str(tmp_path), "--resolution", "64x48"
    )
    assert again.returncode == 0 and "kept 1 / tried 1" in again.stdout
