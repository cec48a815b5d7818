"""Remote policies behind openpi's websocket protocol: ``--policy openpi:HOST:PORT``.

``load_policy("openpi:HOST:PORT")`` connects to a policy server that speaks the protocol of
openpi's ``WebsocketPolicyServer`` / ``openpi_client.websocket_client_policy``: msgpack with
openpi's numpy extension (``openpi_client.msgpack_numpy``), no compression, one frame per
message. On connecting the server sends its metadata (a dict); then each request is an
observation dict and each answer a dict whose ``"actions"`` is an action chunk ``(H, D)``; a
text frame instead is the server's error (its traceback). The client has no reset message
(openpi's ``reset`` is local), so a new rollout only drops what is left of the last chunk.

Each request carries, in the layout of openpi's ALOHA policies (``AlohaInputs``; this
benchmark's robots are ALOHA-like pairs)::

    state    (A,) float32   the measured joints [left n, left opening, right n, right opening]
    images   {cam_high, cam_left_wrist, cam_right_wrist}: (3, S, S) uint8, the head, left and
             right cameras that are rendered, resized with padding to S x S (S = image_size,
             224 by default, as openpi's own clients do; 0 sends them as rendered)
    prompt   str            the instruction of the rollout

The state and the actions are this benchmark's own (joint radians, openings in [0, 1]): the
server's transforms must match the data it was trained on (the LeRobot export). The chunk is
consumed one action per step (an action-chunk broker): a new request is sent when the first
``action_horizon`` rows (default: all of them) have been used, and ``reset`` at the start of a
rollout empties it.

Spec options, after a ``?`` (quote the spec in a shell): ``openpi:HOST:PORT?action_horizon=10&
image_size=224&timeout=10&infer_timeout=300``; in Python also keyword arguments (``api_key``,
``action_size``, ``image_keys``). HOST may be a name, an IPv4 address, ``[IPv6]``, or a
``ws://`` / ``wss://`` URI (``openpi:ws://HOST:PORT/path``).

Errors: a server that does not answer within ``timeout`` seconds (default 10) fails the load
naming host and port; a chunk whose actions are not the environment's size (known from
``bind(env)``, which the evaluation calls after every reset, or ``action_size=``) fails naming
both sizes; a server error, a closed connection or no answer within ``infer_timeout`` seconds
(default 300: a server compiling its model answers its first request late) fails the step,
naming host and port.

Needs ``openpi-client`` (its ``msgpack_numpy`` and ``image_tools``) and
``websockets``: ``pip install -e '.[remote]' && pip install --no-deps openpi-client==0.1.2``
(openpi-client pins ``numpy<2``, which the code it runs here does not need).
"""

from __future__ import annotations

import collections
import inspect
import re
import weakref
from typing import Any

import numpy as np

from bicoord_drake.policies import PolicyLoadError, env_action_size, spec_options

PREFIX = "openpi:"
OPENPI_CLIENT_PIN = "openpi-client==0.1.2"
INSTALL_HINT = f"pip install -e '.[remote]' && pip install --no-deps {OPENPI_CLIENT_PIN}"
#: Our cameras -> the image names of openpi's ALOHA policies.
IMAGE_KEYS = {
    "head_camera": "cam_high",
    "left_camera": "cam_left_wrist",
    "right_camera": "cam_right_wrist",
}
#: Where each camera is found in an observation of either environment.
_CAMERA_FEATURES = {
    "head_camera": "observation.images.head",
    "left_camera": "observation.images.left",
    "right_camera": "observation.images.right",
}
#: Spec options (after ``?``) and their types.
OPTIONS = {"action_horizon": int, "image_size": int, "timeout": float, "infer_timeout": float}
_ADDRESS = re.compile(r"^(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(?P<port>\d{1,5})$")


class RemotePolicyError(RuntimeError):
    """The policy server failed a request (error, closed connection, no answer in time)."""


def _require_client() -> tuple[Any, Any]:
    """openpi_client's msgpack_numpy and image_tools modules, or PolicyLoadError saying how to
    install them (and websockets)."""
    try:
        import websockets.sync.client  # noqa: F401
        from openpi_client import image_tools, msgpack_numpy
    except ImportError as exc:
        raise PolicyLoadError(
            f"openpi policies need openpi-client and websockets ({exc}); install them with "
            f"{INSTALL_HINT}"
        ) from None
    return msgpack_numpy, image_tools


def parse_spec(spec: str) -> tuple[str, str, dict[str, Any]]:
    """``"openpi:HOST:PORT?k=v"`` -> (URI, ``HOST:PORT`` as named in errors, options);
    PolicyLoadError for anything else."""
    body = spec[len(PREFIX) :].strip() if spec.startswith(PREFIX) else spec.strip()
    body, _, query = body.partition("?")
    usage = f"policy {spec!r}: expected openpi:HOST:PORT (e.g. openpi:localhost:8000)"
    if body.startswith(("ws://", "wss://")):
        scheme, _, rest = body.partition("://")
        address, slash, path = rest.partition("/")
        match = _ADDRESS.match(address)
        uri = f"{scheme}://{address}{slash}{path}"
    else:
        match = _ADDRESS.match(body)
        uri = f"ws://{body}"
    if match is None:
        raise PolicyLoadError(usage)
    port = int(match["port"])
    if not 0 < port < 65536:
        raise PolicyLoadError(f"{usage}; port {port} is not in 1..65535")
    options = spec_options(spec, query, OPTIONS)
    return uri, f"{match['host']}:{port}", options


class OpenPIClient:
    """The client side of openpi's websocket protocol, with timeouts (see the module
    docstring); ``openpi_client.websocket_client_policy.WebsocketClientPolicy`` speaks the same
    protocol but waits for a server without a limit.

    `uri`: ``ws://HOST:PORT``; `address`: how errors name the server; `timeout`: seconds to
    connect and receive the metadata; `infer_timeout`: seconds to wait for each answer.
    """

    def __init__(
        self,
        uri: str,
        address: str,
        *,
        timeout: float = 10.0,
        infer_timeout: float | None = 300.0,
        api_key: str | None = None,
    ) -> None:
        self.msgpack_numpy, _ = _require_client()
        self.uri = uri
        self.address = address
        self.timeout = float(timeout)
        self.infer_timeout = infer_timeout
        self._headers = {"Authorization": f"Api-Key {api_key}"} if api_key else None
        self._packer = self.msgpack_numpy.Packer()
        self._ws: Any = None
        self._finalizer: Any = None
        #: What the server sent on connecting.
        self.metadata: dict[str, Any] = {}
        self.connect()

    def connect(self) -> None:
        """Open the connection and read the server's metadata; ConnectionError naming the
        server when it does not answer within ``timeout`` seconds."""
        import websockets.sync.client

        self.close()
        options: dict[str, Any] = {}
        if "legacy" in inspect.signature(websockets.sync.client.connect).parameters:
            options["legacy"] = True  # websockets >= 17: a connection we close ourselves
        try:
            ws = websockets.sync.client.connect(
                self.uri,
                compression=None,
                max_size=None,
                open_timeout=self.timeout,
                # The server may not answer pings while its model runs; infer_timeout is the limit.
                ping_interval=None,
                additional_headers=self._headers,
                **options,
            )
        except Exception as exc:
            raise ConnectionError(
                f"cannot connect to the openpi policy server at {self.address} ({self.uri}) "
                f"within {self.timeout:g} s: {type(exc).__name__}: {exc}; is it running?"
            ) from None
        self._ws = ws
        self._finalizer = weakref.finalize(self, ws.close)
        try:
            metadata = self._receive(self.timeout, "metadata")
        except RemotePolicyError as exc:
            self.close()
            raise ConnectionError(str(exc)) from None
        self.metadata = dict(metadata) if isinstance(metadata, dict) else {}

    @property
    def connected(self) -> bool:
        return self._ws is not None

    def infer(self, obs: dict[str, Any]) -> dict[str, Any]:
        """One request: `obs` out, the server's answer (a dict) back."""
        if self._ws is None:
            self.connect()
        try:
            self._ws.send(self._packer.pack(obs))
        except Exception as exc:
            self.close()
            raise RemotePolicyError(
                f"openpi policy server at {self.address}: sending the observation failed "
                f"({type(exc).__name__}: {exc})"
            ) from None
        answer = self._receive(self.infer_timeout, "answer")
        if not isinstance(answer, dict):
            raise RemotePolicyError(
                f"openpi policy server at {self.address} answered a {type(answer).__name__}, "
                "not a dict with 'actions'"
            )
        return answer

    def _receive(self, timeout: float | None, what: str) -> Any:
        from websockets.exceptions import ConnectionClosed

        try:
            message = self._ws.recv(timeout=timeout)
        except TimeoutError:
            self.close()  # a late answer would be taken for the next request's
            raise RemotePolicyError(
                f"openpi policy server at {self.address} sent no {what} within {timeout:g} s"
            ) from None
        except ConnectionClosed as exc:
            self.close()
            raise RemotePolicyError(
                f"openpi policy server at {self.address} closed the connection ({exc})"
            ) from None
        if isinstance(message, str):  # openpi's servers send their traceback as text
            self.close()
            raise RemotePolicyError(
                f"openpi policy server at {self.address} failed:\n{message.rstrip()}"
            )
        try:
            return self.msgpack_numpy.unpackb(message)
        except Exception as exc:
            self.close()
            raise RemotePolicyError(
                f"openpi policy server at {self.address} sent a message that is not "
                f"msgpack-numpy ({type(exc).__name__}: {exc})"
            ) from None

    def reset(self) -> None:
        """openpi's protocol has no reset message (its client's ``reset`` does nothing)."""

    def close(self) -> None:
        """Close the connection (also done when the client is garbage collected)."""
        if self._finalizer is not None:
            self._finalizer()  # ws.close(), once
        self._ws = self._finalizer = None


class OpenPIPolicy:
    """A policy server behind the policy interface (see the module docstring).

    `host`, `port`: the server; `action_horizon`: actions used from each chunk (default all);
    `image_size`: images are resized with padding to this square (0: as rendered);
    `action_size`: the environment's (else learned from ``bind(env)``); `image_keys`: our
    camera -> the server's image name (default openpi's ALOHA names, :data:`IMAGE_KEYS`).
    """

    def __init__(
        self,
        host: str = "localhost",
        port: int = 8000,
        *,
        action_horizon: int | None = None,
        image_size: int = 224,
        timeout: float = 10.0,
        infer_timeout: float | None = 300.0,
        api_key: str | None = None,
        action_size: int | None = None,
        image_keys: dict[str, str] | None = None,
        uri: str | None = None,
    ) -> None:
        _, self._image_tools = _require_client()
        if action_horizon is not None and action_horizon < 1:
            raise PolicyLoadError(
                f"openpi policy: action_horizon must be >= 1, not {action_horizon}"
            )
        if image_size < 0:
            raise PolicyLoadError(f"openpi policy: image_size must be >= 0, not {image_size}")
        unknown = sorted(set(image_keys or {}) - set(IMAGE_KEYS))
        if unknown:
            raise PolicyLoadError(
                f"openpi policy: image_keys names unknown cameras {unknown}; cameras are "
                f"{', '.join(IMAGE_KEYS)}"
            )
        self.address = f"{host}:{port}"
        self.action_horizon = action_horizon
        self.image_size = int(image_size)
        self.image_keys = dict(IMAGE_KEYS if image_keys is None else image_keys)
        self.action_size = action_size
        self.instruction = ""
        self.requests = 0
        self._queue: collections.deque[np.ndarray] = collections.deque()
        try:
            self.client = OpenPIClient(
                uri or f"ws://{host}:{port}",
                self.address,
                timeout=timeout,
                infer_timeout=infer_timeout,
                api_key=api_key,
            )
        except ConnectionError as exc:
            raise PolicyLoadError(f"openpi policy: {exc}") from None

    def __repr__(self) -> str:
        return f"OpenPIPolicy({self.address!r})"

    @property
    def metadata(self) -> dict[str, Any]:
        """What the server sent on connecting."""
        return self.client.metadata

    # ---------------------------------------------------------------- policy interface
    def bind(self, env: Any) -> None:
        """Learn the environment's action size (:class:`bicoord_drake.env.Env` or the
        Gymnasium environment); the evaluation calls this after every reset."""
        size = env_action_size(env)
        if size is not None:
            self.action_size = size

    def reset(self, instruction: str) -> None:
        """A new rollout: drop what is left of the last chunk; reconnect if the server closed
        the connection."""
        self.instruction = str(instruction)
        self._queue.clear()
        if not self.client.connected:
            try:
                self.client.connect()
            except ConnectionError as exc:
                raise RemotePolicyError(str(exc)) from None
        self.client.reset()

    def act(self, obs: dict[str, Any]) -> np.ndarray:
        """The next action of the chunk (float64), asking the server for a new chunk when it
        is used up."""
        if not self._queue:
            self._queue.extend(self.chunk(obs))
        return self._queue.popleft().copy()

    def close(self) -> None:
        """Close the connection to the server."""
        self._queue.clear()
        self.client.close()

    # ---------------------------------------------------------------- one request
    def chunk(self, obs: dict[str, Any]) -> np.ndarray:
        """Ask the server for a chunk for `obs`: its first ``action_horizon`` actions, (H, A)."""
        answer = self.client.infer(self.request(obs))
        self.requests += 1
        if "actions" not in answer:
            raise RemotePolicyError(
                f"openpi policy server at {self.address}: its answer has no 'actions' (it has "
                f"{', '.join(map(str, answer)) or 'nothing'})"
            )
        actions = np.asarray(answer["actions"], dtype=float)
        if actions.ndim == 1:
            actions = actions[None]
        if actions.ndim != 2 or not actions.size:
            raise RemotePolicyError(
                f"openpi policy server at {self.address}: 'actions' has shape {actions.shape}, "
                "expected (H, action size)"
            )
        if self.action_size is not None and actions.shape[1] != self.action_size:
            raise ValueError(
                f"openpi policy server at {self.address} sends actions of {actions.shape[1]} "
                f"numbers; the environment takes {self.action_size} (chunk shape "
                f"{actions.shape})"
            )
        if not np.isfinite(actions).all():
            raise RemotePolicyError(
                f"openpi policy server at {self.address} sent non-finite actions"
            )
        return actions[: self.action_horizon]

    def request(self, obs: dict[str, Any]) -> dict[str, Any]:
        """`obs` (of either environment) as the request openpi's ALOHA policies read."""
        state = obs.get("observation.state", obs.get("joint_state"))
        if state is None:
            raise ValueError(
                "openpi policy: the observation has no joint state ('observation.state' or "
                f"'joint_state'; it has {', '.join(sorted(map(str, obs)))})"
            )
        images = {}
        for camera, name in self.image_keys.items():
            image = obs.get(_CAMERA_FEATURES[camera], obs.get(camera))
            if image is not None:
                images[name] = self._image(image)
        prompt = obs.get("instruction", obs.get("task", self.instruction))
        return {
            "state": np.asarray(state, dtype=np.float32).reshape(-1),
            "images": images,
            "prompt": str(prompt),
        }

    def _image(self, image: Any) -> np.ndarray:
        """(H, W, 3) RGB -> (3, S, S) uint8, resized with padding as openpi's clients do."""
        array = np.asarray(image)
        if array.ndim != 3 or array.shape[-1] != 3:
            raise ValueError(f"openpi policy: expected an (H, W, 3) RGB image, got {array.shape}")
        array = self._image_tools.convert_to_uint8(array)
        if self.image_size:
            array = self._image_tools.resize_with_pad(array, self.image_size, self.image_size)
        return np.ascontiguousarray(array.transpose(2, 0, 1))


def load_openpi_policy(spec: str, **kwargs: Any) -> OpenPIPolicy:
    """``"openpi:HOST:PORT[?options]"`` -> :class:`OpenPIPolicy`, connected (keyword arguments:
    those of :class:`OpenPIPolicy`; they override the spec's options)."""
    _require_client()
    uri, address, options = parse_spec(spec)
    known = {*OPTIONS, "api_key", "action_size", "image_keys"}
    unknown = sorted(set(kwargs) - known)
    if unknown:
        raise PolicyLoadError(
            f"policy {spec!r}: unknown arguments {unknown} (known: {', '.join(sorted(known))})"
        )
    host, _, port = address.rpartition(":")
    try:
        return OpenPIPolicy(host, int(port), uri=uri, **{**options, **kwargs})
    except PolicyLoadError:
        raise
    except Exception as exc:  # anything else of the connection is the load's failure too
        raise PolicyLoadError(f"policy {spec!r}: {type(exc).__name__}: {exc}") from None
