"""load_policy("openpi:HOST:PORT"): openpi's websocket protocol against an in-process
openpi-compatible server (tests/policies/openpi_server.py) on loopback: the request layout,
chunk consumption, reset, errors naming the server (down, silent, failing) and both action
sizes, the whole scripts/evaluate.py path, and the round-trip latency."""

import json
import os
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("openpi_client")
pytest.importorskip("websockets")

from bicoord_drake.policies import (  # noqa: E402
    PolicyLoadError,
    close_policy,
    load_policy,
    load_policy_for,
)
from bicoord_drake.policies.openpi_policy import (  # noqa: E402
    INSTALL_HINT,
    OpenPIPolicy,
    RemotePolicyError,
    parse_spec,
)
from tests.policies.openpi_server import (  # noqa: E402
    PolicyServer,
    hold_chunk,
    numbered_chunk,
    playback_chunk,
)

ROOT = Path(__file__).resolve().parents[2]
HEAD = "observation.images.head"


def _obs(task="Fill the grid.", state=None, image=(48, 64)):
    """An observation keyed like the Gymnasium environment's."""
    obs = {
        "observation.state": np.arange(14, dtype=np.float32) if state is None else state,
        "observation.endpose": np.zeros(14, np.float32),
        "task": task,
    }
    if image:
        obs[HEAD] = np.full((*image, 3), 200, np.uint8)
    return obs


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ------------------------------------------------------------------ spec
@pytest.mark.parametrize(
    "spec,uri,address,options",
    [
        ("openpi:localhost:8000", "ws://localhost:8000", "localhost:8000", {}),
        ("openpi:10.1.2.3:8000", "ws://10.1.2.3:8000", "10.1.2.3:8000", {}),
        ("openpi:[::1]:9000", "ws://[::1]:9000", "[::1]:9000", {}),
        ("openpi:ws://gpu-box:8000/policy", "ws://gpu-box:8000/policy", "gpu-box:8000", {}),
        (
            "openpi:localhost:8000?action_horizon=10&image_size=0&timeout=2.5",
            "ws://localhost:8000",
            "localhost:8000",
            {"action_horizon": 10, "image_size": 0, "timeout": 2.5},
        ),
    ],
)
def test_spec_parsing(spec, uri, address, options):
    assert parse_spec(spec) == (uri, address, options)


@pytest.mark.parametrize(
    "spec,words",
    [
        ("openpi:", ["expected openpi:HOST:PORT"]),
        ("openpi:localhost", ["expected openpi:HOST:PORT"]),
        ("openpi:localhost:99999", ["port 99999"]),
        ("openpi:localhost:8000?horizon=3", ["unknown option 'horizon'", "action_horizon"]),
        ("openpi:localhost:8000?action_horizon=x", ["action_horizon='x'", "int"]),
    ],
)
def test_bad_specs_name_the_problem(spec, words):
    with pytest.raises(PolicyLoadError) as err:
        load_policy(spec)
    for word in words:
        assert word in str(err.value)


def test_missing_openpi_client_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "openpi_client", None)  # import -> ImportError
    with pytest.raises(PolicyLoadError) as err:
        load_policy("openpi:localhost:8000")
    assert INSTALL_HINT in str(err.value)


# ------------------------------------------------------------------ round trip
def test_round_trip_request_layout_and_chunk_consumption():
    server = PolicyServer(numbered_chunk(horizon=4), metadata={"action_horizon": 4})
    with server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}")
        assert isinstance(policy, OpenPIPolicy) and policy.metadata == {"action_horizon": 4}
        policy.reset("Fill the grid.")
        actions = [policy.act(_obs()) for _ in range(6)]
        # one request per chunk of 4: rows 0-3 of chunk 0, then rows 0-1 of chunk 1
        assert [a[0] for a in actions] == [0, 1, 2, 3, 100, 101]
        assert all(a.shape == (14,) and a.dtype == np.float64 for a in actions)
        assert len(server.requests) == 2
        request = server.requests[0]
        assert set(request) == {"state", "images", "prompt"}
        assert request["state"].dtype == np.float32 and np.array_equal(
            request["state"], np.arange(14)
        )
        assert request["prompt"] == "Fill the grid."
        image = request["images"]["cam_high"]  # 64x48 resized with padding to 224x224, CHW
        assert image.shape == (3, 224, 224) and image.dtype == np.uint8
        assert image[:, 112, 112].tolist() == [200, 200, 200] and image[:, 0, 112].max() == 0
        close_policy(policy)
    assert server.closed == server.connections == 1


def test_reset_drops_the_rest_of_the_chunk_and_the_horizon_option():
    server = PolicyServer(numbered_chunk(horizon=8))
    with server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}?action_horizon=3&image_size=0")
        policy.reset("first")
        first = [policy.act(_obs(task="first"))[0] for _ in range(4)]
        assert first == [0, 1, 2, 100]  # 3 of each 8-action chunk
        policy.reset("second")  # a new rollout: the rest of chunk 1 is dropped
        assert policy.act({"joint_state": np.zeros(14), "instruction": "second"})[0] == 200
        assert [r["prompt"] for r in server.requests] == ["first", "first", "second"]
        assert server.requests[0]["images"]["cam_high"].shape == (3, 48, 64)  # as rendered
        assert server.requests[2]["images"] == {}  # an Env observation without cameras
        policy.close()


def test_gymnasium_environment_round_trip():
    """A real environment observation (head camera) out, the server's chunk stepped in."""
    import gymnasium

    import bicoord_drake  # noqa: F401  (registers the ids)

    env = gymnasium.make(
        "bicoord_drake/balance_roller-v0", resolution="64x48", cameras=["head_camera"]
    )
    server = PolicyServer(hold_chunk(horizon=4))
    with server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}")
        obs, _ = env.reset(seed=100000)
        policy.bind(env)
        assert policy.action_size == 14
        policy.reset(obs["task"])
        for _ in range(5):
            obs, _, terminated, truncated, _ = env.step(policy.act(obs))
            assert not (terminated or truncated)
        assert len(server.requests) == 2
        assert server.requests[0]["prompt"] == env.unwrapped.task_description
        assert server.requests[0]["images"]["cam_high"].shape == (3, 224, 224)
        policy.close()
    env.close()


# ------------------------------------------------------------------ errors
def test_a_server_that_is_down_is_named_without_waiting():
    port = _free_port()  # nothing listens there
    start = time.perf_counter()
    with pytest.raises(PolicyLoadError) as err:
        load_policy(f"openpi:127.0.0.1:{port}")
    assert f"127.0.0.1:{port}" in str(err.value) and "is it running" in str(err.value)
    assert time.perf_counter() - start < 5


def test_a_server_that_does_not_answer_times_out():
    """Something listens but never speaks websocket: the connection timeout, not a hang."""
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        port = silent.getsockname()[1]
        start = time.perf_counter()
        with pytest.raises(PolicyLoadError) as err:
            load_policy(f"openpi:127.0.0.1:{port}?timeout=0.5")
        elapsed = time.perf_counter() - start
    assert f"127.0.0.1:{port}" in str(err.value) and "within 0.5 s" in str(err.value)
    assert elapsed < 5


def test_an_action_size_other_than_the_environment_s_names_both():
    server = PolicyServer(numbered_chunk(horizon=4, size=7))
    with server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}")
        policy.bind(SimpleNamespace(action_size=14))
        policy.reset("x")
        with pytest.raises(ValueError, match=r"actions of 7 numbers; the environment takes 14"):
            policy.act(_obs())
        sized = load_policy_for(f"openpi:127.0.0.1:{server.port}", action_size=16)
        sized.reset("x")
        with pytest.raises(ValueError, match=r"7 numbers; the environment takes 16"):
            sized.act(_obs())


def test_a_failing_server_is_named_and_the_next_rollout_reconnects():
    calls = {"n": 0}

    def flaky(obs):
        calls["n"] += 1
        if calls["n"] == 1:
            raise RuntimeError("model exploded")
        return {"actions": np.zeros((2, 14), np.float32)}

    server = PolicyServer(flaky)
    with server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}")
        policy.reset("x")
        with pytest.raises(RemotePolicyError) as err:
            policy.act(_obs())
        message = str(err.value)
        assert f"127.0.0.1:{server.port} failed" in message and "model exploded" in message
        policy.reset("x")  # a new rollout connects again
        assert np.array_equal(policy.act(_obs()), np.zeros(14))
        assert server.connections == 2
        policy.close()


def test_no_answer_in_time_is_named():
    def slow(obs):
        time.sleep(1.0)
        return {"actions": np.zeros((1, 14))}

    with PolicyServer(slow) as server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}?infer_timeout=0.2")
        policy.reset("x")
        with pytest.raises(RemotePolicyError, match=r"sent no answer within 0.2 s"):
            policy.act(_obs())


def test_an_answer_without_actions_is_named():
    with PolicyServer(lambda obs: {"action": np.zeros(14)}) as server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}")
        policy.reset("x")
        with pytest.raises(RemotePolicyError, match=r"no 'actions' \(it has action\)"):
            policy.act(_obs())


# ------------------------------------------------------------------ the evaluation CLI
def test_scripts_evaluate_with_an_openpi_server(tmp_path):
    server = PolicyServer(hold_chunk(horizon=4))
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
        "BICOORD_CACHE": str(tmp_path / "cache"),
    }
    with server:
        spec = f"openpi:127.0.0.1:{server.port}"
        args = [sys.executable, "scripts/evaluate.py", "--task", "balance_roller"]
        args += ["--policy", spec, "--episodes", "1", "--step-limit", "6", "--no-render"]
        args += ["--no-expert-check", "--workers", "1", "--json", "--out", str(tmp_path)]
        out = subprocess.run(args, capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    report = json.loads(out.stdout)
    (rollout,) = report["rollouts"]
    assert rollout["error"] is None, rollout.get("traceback")
    assert rollout["steps"] == 6
    assert len(server.requests) == 2  # 6 steps from chunks of 4
    assert server.requests[0]["images"] == {} and server.requests[0]["state"].shape == (14,)

    down = f"openpi:127.0.0.1:{_free_port()}"
    args[args.index(spec)] = down
    out = subprocess.run(args, capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert out.returncode == 2 and down.removeprefix("openpi:") in out.stderr


def test_scripts_evaluate_scores_a_server_playing_the_export_back(balance_roller_export, tmp_path):
    """Issue 53, goal 3: an in-process openpi server answering with the LeRobot export's own
    actions (read with lerobot by the dataset-playback policy) in chunks of 10, evaluated by
    ``scripts/evaluate.py --policy openpi:HOST:PORT`` on the demonstration's seed: 100 %, and
    each request's state is the dataset's frame of the chunk's first action."""
    pytest.importorskip("lerobot.datasets.lerobot_dataset")
    ex = balance_roller_export
    (seed,) = ex.seeds
    frames = load_policy(f"lerobot-dataset:{ex.lerobot}").frames(ex.task, seed)
    infer = playback_chunk(frames["action"], frames["state"], horizon=10)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
        "BICOORD_CACHE": str(tmp_path / "cache"),
    }
    with PolicyServer(infer) as server:
        args = [sys.executable, "scripts/evaluate.py", "--task", ex.task, "--data", str(ex.data)]
        args += ["--policy", f"openpi:127.0.0.1:{server.port}", "--no-render", "--workers", "1"]
        args += ["--json", "--out", str(tmp_path)]
        out = subprocess.run(args, capture_output=True, text=True, env=env, cwd=ROOT, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    report = json.loads(out.stdout)
    (rollout,) = report["rollouts"]
    assert rollout["seed"] == seed and rollout["error"] is None, rollout.get("traceback")
    assert report["SR"] == 1.0 and rollout["success"]
    assert len(server.requests) == -(-rollout["steps"] // 10)  # one request per chunk of 10
    assert max(infer.state_errors) < 1e-4, infer.state_errors  # float32 rounding only


# ------------------------------------------------------------------ latency
def test_round_trip_latency_on_loopback(capsys):
    """The median time of one request (three 224x224 images, the state, a prompt) and its
    answer (a 50 x 14 chunk) over 100 calls on loopback; docs/remote_policies.md records it."""

    def chunk(obs):
        return {"actions": np.zeros((50, 14), np.float32)}

    obs = {
        "observation.state": np.zeros(14, np.float32),
        "observation.images.head": np.zeros((240, 320, 3), np.uint8),
        "observation.images.left": np.zeros((240, 320, 3), np.uint8),
        "observation.images.right": np.zeros((240, 320, 3), np.uint8),
        "task": "Fill the grid.",
    }
    with PolicyServer(chunk) as server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}")
        request = policy.request(obs)
        policy.client.infer(request)  # warm up
        wire, full = [], []
        for _ in range(100):
            t0 = time.perf_counter()
            policy.client.infer(request)
            t1 = time.perf_counter()
            policy.reset("x")
            policy.act(obs)  # the request built from the images too
            wire.append(t1 - t0)
            full.append(time.perf_counter() - t1)
        policy.close()
    wire_ms, full_ms = 1e3 * statistics.median(wire), 1e3 * statistics.median(full)
    with capsys.disabled():
        print(
            f"\nopenpi loopback round trip per chunk, median of 100: {wire_ms:.2f} ms on the "
            f"wire, {full_ms:.2f} ms with the request built from 320x240 images"
        )
    assert wire_ms < 1000 and full_ms < 1000
