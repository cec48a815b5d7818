"""Generation on Ray with real jigsaw episodes (seed 0 and 1, no rendering): a worker killed
mid-episode is retried without loss or duplicate; a killed driver resumes from the manifest;
the Ray backend and local processes give bit-identical actions; workers stay quiet."""

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from bicoord_drake.runner.generate import GenerateConfig, generate

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "generate.py"
TASK, SEED = "jigsaw", 0
NOISE = ("Allocating", "INFO", "WARNING", "pid=", "Traceback", "ray::", "Started a local Ray")


def episode_workers() -> list[int]:
    """Pids of Ray workers, descendants of this process, running an episode job."""
    me = str(os.getpid())
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if cmd.startswith(b"ray::produce_episode") and me in ancestors(pid):
            found.append(int(pid))
    return found


def ancestors(pid: str) -> list[str]:
    chain = []
    while pid not in ("0", "1"):
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            break
        pid = stat.rsplit(")", 1)[1].split()[1]
        chain.append(pid)
    return chain


def wait_for_worker(timeout: float = 300.0) -> int:
    deadline = time.time() + timeout
    while time.time() < deadline:
        pids = episode_workers()
        if pids:
            return pids[0]
        time.sleep(0.2)
    raise AssertionError("no Ray worker started an episode")


def cli(out: Path, *extra: str) -> list[str]:
    return [
        sys.executable,
        str(SCRIPT),
        "--task",
        TASK,
        "--seed",
        str(SEED),
        "--no-render",
        "--out",
        str(out),
        *extra,
    ]


def env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT)}


def actions(path: Path) -> np.ndarray:
    with h5py.File(path) as f:
        return f["joint_action/vector"][:]


def manifest(root: Path) -> dict:
    return json.loads((root / TASK / "default" / "manifest.json").read_text())


@pytest.fixture(scope="module")
def killed_run(ray_cluster, tmp_path_factory):
    """One episode on Ray (1 worker) whose worker process is SIGKILLed 3 s into the episode."""
    out = tmp_path_factory.mktemp("ray")
    config = GenerateConfig(
        task=TASK, episodes=1, seed=SEED, out=str(out), render=False, backend="ray", workers=1
    )
    result = {}
    thread = threading.Thread(target=lambda: result.setdefault("summary", generate(config)))
    thread.start()
    victim = wait_for_worker()
    time.sleep(3.0)
    os.kill(victim, signal.SIGKILL)
    thread.join(timeout=900)
    assert not thread.is_alive() and "summary" in result
    return out, victim, result["summary"]


def test_worker_killed_mid_episode_is_retried_without_loss_or_duplicate(killed_run):
    out, victim, summary = killed_run
    assert summary.kept == 1 and summary.tried == 1 and not summary.failures
    entries = manifest(out)["episodes"]
    assert [(e["seed"], e["success"], e["index"]) for e in entries] == [(SEED, True, 0)]
    assert int(entries[0]["worker"].rsplit(":", 1)[1]) != victim  # a retry made it
    files = sorted(p.name for p in (out / TASK / "default" / "data").iterdir())
    assert files == ["episode0.hdf5"]
    assert not (out / TASK / "default" / ".staging").exists()
    dataset = json.loads((out / "dataset_default.json").read_text())
    assert dataset["tasks"][TASK]["kept"] == 1 and dataset["settings"]["render"] is False


def test_same_seed_same_actions_with_local_processes_and_ray(killed_run, tmp_path):
    out, _, _ = killed_run
    local = subprocess.run(
        cli(tmp_path, "--episodes", "1", "--workers", "2"),
        capture_output=True,
        text=True,
        env=env(),
        timeout=900,
    )
    assert local.returncode == 0, local.stderr[-2000:]
    for word in NOISE:  # process-pool workers keep Drake's log off the terminal
        assert word not in local.stderr, local.stderr[-2000:]
    ray_actions = actions(out / TASK / "default" / "data" / "episode0.hdf5")
    local_actions = actions(tmp_path / TASK / "default" / "data" / "episode0.hdf5")
    assert ray_actions.shape == local_actions.shape
    assert ray_actions.tobytes() == local_actions.tobytes()


def test_killed_driver_resumes_from_the_manifest(killed_run, ray_cluster, tmp_path):
    source, _, _ = killed_run
    out = tmp_path / "data"
    shutil.copytree(source, out)
    first = out / TASK / "default" / "data" / "episode0.hdf5"
    digest = hashlib.sha256(first.read_bytes()).hexdigest()
    command = cli(
        out, "--episodes", "2", "--workers", "1", "--backend", "ray", "--ray-address", ray_cluster
    )
    driver = subprocess.Popen(
        command, env=env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        wait_for_worker()  # seed 1 is running
        time.sleep(2.0)
    finally:
        driver.send_signal(signal.SIGKILL)
        driver.wait()
    assert [e["seed"] for e in manifest(out)["episodes"]] == [SEED]
    again = subprocess.run(command, capture_output=True, text=True, env=env(), timeout=900)
    assert again.returncode == 0, again.stderr[-2000:]
    assert "kept 2 / tried 2" in again.stdout
    for word in NOISE:  # no Ray or Drake log lines from the workers on the terminal
        assert word not in again.stderr, again.stderr[-2000:]
    entries = manifest(out)["episodes"]
    assert [(e["seed"], e["index"]) for e in entries] == [(SEED, 0), (SEED + 1, 1)]
    assert hashlib.sha256(first.read_bytes()).hexdigest() == digest
    data = sorted(p.name for p in first.parent.iterdir())
    assert data == ["episode0.hdf5", "episode1.hdf5"]
