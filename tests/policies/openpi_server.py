"""A tiny openpi-compatible policy server for the tests: the protocol of openpi's
``WebsocketPolicyServer`` (metadata first, then msgpack-numpy observation -> action dict; a text
frame with the traceback when the policy raises, then close), on loopback, in a thread.

    with PolicyServer(hold_chunk(4)) as server:
        policy = load_policy(f"openpi:127.0.0.1:{server.port}")
"""

from __future__ import annotations

import asyncio
import threading
import traceback
from collections.abc import Callable
from typing import Any

import numpy as np
import websockets.asyncio.server
import websockets.frames
from openpi_client import msgpack_numpy
from websockets.exceptions import ConnectionClosed

Infer = Callable[[dict[str, Any]], dict[str, Any]]


class PolicyServer:
    """Serves `infer` (observation dict -> answer dict) at ``127.0.0.1:port`` (a free port)."""

    def __init__(self, infer: Infer, metadata: dict[str, Any] | None = None) -> None:
        self.infer = infer
        self.metadata = metadata or {}
        #: Every observation received, in order.
        self.requests: list[dict[str, Any]] = []
        self.connections = 0
        self.closed = 0
        self.port = 0
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Future | None = None

    def __enter__(self) -> PolicyServer:
        self._thread.start()
        if not self._ready.wait(10):
            raise RuntimeError("the test policy server did not start")
        return self

    def __exit__(self, *exc: object) -> None:
        if self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set_result, None)
        self._thread.join(10)

    def _run(self) -> None:
        asyncio.run(self._main())

    async def _main(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = self._loop.create_future()
        async with websockets.asyncio.server.serve(
            self._handler, "127.0.0.1", 0, compression=None, max_size=None
        ) as server:
            self.port = server.sockets[0].getsockname()[1]
            self._ready.set()
            await self._stop

    async def _handler(self, websocket: Any) -> None:
        self.connections += 1
        packer = msgpack_numpy.Packer()
        await websocket.send(packer.pack(self.metadata))
        try:
            while True:
                obs = msgpack_numpy.unpackb(await websocket.recv())
                self.requests.append(obs)
                try:
                    answer = self.infer(obs)
                except Exception:
                    await websocket.send(traceback.format_exc())
                    await websocket.close(
                        code=websockets.frames.CloseCode.INTERNAL_ERROR, reason="policy failed"
                    )
                    return
                await websocket.send(packer.pack(answer))
        except ConnectionClosed:
            pass
        finally:
            self.closed += 1


def hold_chunk(horizon: int = 4) -> Infer:
    """A constant 'home' policy: a chunk of `horizon` copies of the observed state (hold still)."""

    def infer(obs: dict[str, Any]) -> dict[str, Any]:
        state = np.asarray(obs["state"], dtype=np.float32)
        return {"actions": np.tile(state, (horizon, 1))}

    return infer


def numbered_chunk(horizon: int = 4, size: int = 14) -> Infer:
    """Chunks whose row `i` of request `k` is filled with ``100 k + i``: shows which row of which
    chunk each action came from."""
    calls = {"n": 0}

    def infer(obs: dict[str, Any]) -> dict[str, Any]:
        k = calls["n"]
        calls["n"] += 1
        rows = 100.0 * k + np.arange(horizon, dtype=np.float32)
        return {"actions": np.repeat(rows[:, None], size, axis=1), "policy_timing": {"k": k}}

    return infer


def playback_chunk(actions: np.ndarray, states: np.ndarray, horizon: int = 10) -> Infer:
    """Serves one recorded episode as chunks, as a policy imitating it perfectly would: request
    k gets ``actions[k H : (k + 1) H]`` (the last action repeated past the end). The state of
    each request within the episode is compared with the recorded ``states`` of the chunk's
    first frame; ``infer.state_errors`` collects those max |errors| (the test asserts on them:
    raising here would reach the client as the server's traceback)."""
    actions = np.asarray(actions, dtype=np.float32)
    states = np.asarray(states, dtype=np.float32)
    calls = {"n": 0}
    errors: list[float] = []

    def infer(obs: dict[str, Any]) -> dict[str, Any]:
        start = horizon * calls["n"]
        calls["n"] += 1
        if start < len(states):
            errors.append(float(np.max(np.abs(np.asarray(obs["state"]) - states[start]))))
        rows = np.arange(start, start + horizon).clip(max=len(actions) - 1)
        return {"actions": actions[rows]}

    infer.state_errors = errors  # type: ignore[attr-defined]
    return infer
