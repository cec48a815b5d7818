"""Shared fixtures of the policy tests: one freshly generated balance_roller demonstration
(state only) and its LeRobot export, for the dataset-playback tests (here and over openpi)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Exported:
    """Episode files (`data`), their LeRobot export (`lerobot`) and the episodes' seeds."""

    task: str
    data: Path
    lerobot: Path
    seeds: tuple[int, ...]


def script_env(tmp: Path) -> dict[str, str]:
    """The environment of a scripts/*.py subprocess: this checkout importable, the expert-check
    cache in `tmp`, no network."""
    return {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
        "BICOORD_CACHE": str(tmp / "cache"),
        "HF_HUB_OFFLINE": "1",
    }


def run_script(name: str, args: list[str], tmp: Path, timeout: int = 1800):
    """``python scripts/<name>.py ARGS`` from the checkout; fails the test on a non-zero exit."""
    out = subprocess.run(
        [sys.executable, f"scripts/{name}.py", *args],
        capture_output=True,
        text=True,
        env=script_env(tmp),
        cwd=ROOT,
        timeout=timeout,
    )
    assert out.returncode == 0, f"scripts/{name}.py {args} failed:\n{out.stderr[-3000:]}"
    return out


def generate_and_export(
    tmp: Path,
    task: str,
    episodes: int,
    *,
    render: bool = False,
    resolution: str = "64x48",
    environment_state: bool = False,
) -> Exported:
    """Generate `episodes` demonstrations of `task` (seeds from 0, one process) and export them
    to LeRobot v3.0 (without images unless `render`; with the objects' poses if
    `environment_state`)."""
    data, lerobot = tmp / "data", tmp / "lerobot"
    cameras = ["--resolution", resolution] if render else ["--no-render"]
    run_script(
        "generate",
        ["--task", task, "--episodes", str(episodes), "--out", str(data), "--workers", "1"]
        + ["--no-video", *cameras],
        tmp,
    )
    run_script(
        "export",
        [str(data), "--to", "lerobot", "--out", str(lerobot)]
        + ([] if render else ["--no-images"])
        + (["--environment-state"] if environment_state else []),
        tmp,
    )
    lines = (lerobot / "meta" / "bicoord_episodes.jsonl").read_text().splitlines()
    seeds = tuple(json.loads(line)["seed"] for line in lines)
    assert len(seeds) == episodes
    return Exported(task, data, lerobot, seeds)


@pytest.fixture(scope="session")
def balance_roller_export(tmp_path_factory) -> Exported:
    """One balance_roller demonstration without cameras (about 10 s) and its state-only LeRobot
    export (about 20 s, mostly lerobot's imports)."""
    pytest.importorskip("lerobot.datasets.lerobot_dataset")
    return generate_and_export(
        tmp_path_factory.mktemp("playback"), "balance_roller", 1, environment_state=True
    )
