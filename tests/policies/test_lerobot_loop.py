"""The whole loop, as a user runs it: generate two demonstrations, export them with the
environment state, train a tiny ACT with ``lerobot-train`` and evaluate the checkpoint with
``scripts/evaluate.py --policy lerobot:PATH`` (slow: 80-110 s on a shared 2-core machine)."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TASK = "balance_roller"
#: A tiny state-based ACT: a few thousand parameters, a few dozen CPU steps.
TINY_ACT = (
    "--policy.type=act",
    "--policy.device=cpu",
    "--policy.push_to_hub=false",
    "--policy.pretrained_backbone_weights=null",
    "--policy.dim_model=16",
    "--policy.n_heads=2",
    "--policy.dim_feedforward=32",
    "--policy.n_encoder_layers=1",
    "--policy.n_decoder_layers=1",
    "--policy.use_vae=false",
    "--policy.chunk_size=4",
    "--policy.n_action_steps=4",
    "--batch_size=4",
    "--steps=30",
    "--save_freq=30",
    "--log_freq=10",
    "--eval_freq=0",
    "--num_workers=0",
    "--wandb.enable=false",
)


def _run(args: list[str], env: dict[str, str], timeout: int = 900) -> subprocess.CompletedProcess:
    out = subprocess.run(args, capture_output=True, text=True, env=env, timeout=timeout, cwd=ROOT)
    assert out.returncode == 0, f"{args[:3]} failed:\n{out.stderr[-3000:]}"
    return out


@pytest.mark.slow
def test_export_train_with_lerobot_and_evaluate(tmp_path):
    pytest.importorskip("lerobot.policies.act.modeling_act")
    train = shutil.which("lerobot-train")
    if train is None:
        pytest.skip("lerobot-train is not on PATH (pip install --no-deps lerobot==0.4.4)")
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
        "BICOORD_CACHE": str(tmp_path / "cache"),
        "HF_HUB_OFFLINE": "1",
        "WANDB_MODE": "disabled",
    }
    python = sys.executable
    data, dataset, outputs = tmp_path / "data", tmp_path / "lerobot", tmp_path / "act"
    _run(
        [python, "scripts/generate.py", "--task", TASK, "--episodes", "2", "--out", str(data)]
        + ["--no-render", "--workers", "1"],
        env,
    )
    printed = _run(
        [python, "scripts/export.py", str(data), "--to", "lerobot", "--out", str(dataset)]
        + ["--environment-state", "--no-images"],
        env,
    ).stdout
    assert "2 episodes" in printed
    info = json.loads((dataset / "meta" / "info.json").read_text())
    assert info["features"]["observation.environment_state"]["names"][::7] == [
        "roller_x",
        "block_x",
    ]
    _run(
        [train, f"--dataset.repo_id=bicoord_drake/{TASK}", f"--dataset.root={dataset}"]
        + [*TINY_ACT, f"--output_dir={outputs}"],
        env,
    )
    model = outputs / "checkpoints" / "last" / "pretrained_model"
    config = json.loads((model / "config.json").read_text())
    assert set(config["input_features"]) >= {
        "observation.state",
        "observation.environment_state",
    }
    evaluated = _run(
        [python, "scripts/evaluate.py", "--task", TASK, "--policy", f"lerobot:{outputs}"]
        + ["--episodes", "1", "--no-render", "--workers", "1", "--json"]
        + ["--out", str(tmp_path / "eval")],
        env,
    )
    assert "cannot be checked" not in evaluated.stderr  # the object order was checked
    report = json.loads(evaluated.stdout)
    assert report["n"] == 1 and report["policy"] == f"lerobot:{outputs}"
    (rollout,) = report["rollouts"]
    assert rollout["error"] is None, rollout.get("traceback")
    assert 0 < rollout["steps"] <= 300 and 0.0 <= report["SSR"] <= 1.0
    assert [s["subgoal"] for s in report["stages"]] == [
        "lift the roller together",
        "balance it on the block",
    ]
    assert Path(report["report"]).is_file()
