"""robocog for Python: join a robocog graph as a component, with the same bus, types and launcher
as the Rust components.

    import robocog
    from robocog import msg

    node = robocog.Node("greeter", sys.argv[1:])
    say = node.publisher("speech/say", msg.SayRequest)
    node.subscribe("speech/utterance", msg.Utterance, lambda u: print(u.text))
    node.spin()

The runtime is Rust (`robocog._robocog`, the `interfaces` crate): the connection flags, the
namespace, the liveliness tokens (`robocog component list` shows the node), the `diagnostics`
counters, the clock (`--clock bus` follows a replay) and the CDR bytes are those of every robocog
component. Messages are the dataclasses of `robocog.msg`, generated from the Rust types.
A component with flags, `--describe` and `--preflight`, run by the launcher: `robocog.component`.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import pathlib
import traceback
from typing import Any, Callable

from . import _robocog, msg
from ._robocog import NoServerError, RemoteError

__all__ = [
    "Node",
    "Publisher",
    "RemoteError",
    "NoServerError",
    "ServiceError",
    "encode",
    "decode",
    "plain",
    "type_name",
    "msg",
]

_robocog.set_classes(msg.CLASSES)

#: The name on the bus of every class of `robocog.msg` that is a message type.
TYPE_NAMES: dict[type, str] = {cls: name for name, cls in msg.TYPES.items()}


def ServiceError(code: str, message: str) -> RemoteError:
    """The typed error a service handler raises: `code` is `BadRequest`, `NotFound`, `Refused`
    or `Internal`. The caller gets `RemoteError(code, message)`."""
    if code not in ("BadRequest", "NotFound", "Refused", "Internal"):
        raise ValueError(f"{code!r} is no service error code")
    return RemoteError(code, message)


def type_name(t: type | str | Any) -> str:
    """The bus name of a message class (`msg.Text` gives `robocog.Text`), of a message's class, or
    a name as it is."""
    if isinstance(t, str):
        return t
    cls = t if isinstance(t, type) else type(t)
    try:
        return TYPE_NAMES[cls]
    except KeyError:
        raise TypeError(f"{cls.__name__} is not a message type of robocog.msg") from None


_FIELDS: dict[type, tuple[str, ...] | None] = {}
_AS_IS = (str, int, float, bool, bytes, type(None))


def plain(value: Any) -> Any:
    """A message as plain values (dicts, lists, numbers, text, bytes): what the Rust codec reads.
    NumPy arrays and memoryviews become bytes, NumPy scalars numbers."""
    t = type(value)
    if t in _AS_IS:
        return value
    names = _FIELDS.get(t, ())
    if names == ():
        names = (
            tuple(f.name for f in dataclasses.fields(t)) if dataclasses.is_dataclass(t) else None
        )
        _FIELDS[t] = names
    if names is not None:
        return {n: plain(getattr(value, n)) for n in names}
    if t is list or t is tuple:
        return [plain(v) for v in value]
    if t is dict:
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (bytearray, memoryview)):
        return bytes(value)
    if hasattr(value, "__array_interface__"):
        # A NumPy array (its bytes) or scalar (its number).
        return value.item() if getattr(value, "ndim", 1) == 0 else value.tobytes()
    return value


def encode(message: Any, type: type | str | None = None) -> bytes:
    """The CDR payload of `message` (of its class's type, or `type`): the bytes a Rust publisher
    of that type sends."""
    return _robocog.encode(type_name(type if type is not None else message), message)


def decode(type: type | str, payload: bytes) -> Any:
    """A CDR payload of `type` as its class of `robocog.msg`. Raises ValueError when it does not
    decode."""
    return _robocog.decode(type_name(type), payload)


class Publisher:
    """A publisher of one topic (`Node.publisher`)."""

    def __init__(self, inner: Any, type_name: str):
        self._inner = inner
        self.type_name = type_name
        self.topic: str = inner.topic

    def publish(self, message: Any) -> None:
        """Publish `message`; a zero header stamp is set from the node's clock."""
        self._inner.publish(message)


class Node:
    """A component on the bus: publishers, subscriptions, services, timers, counters, a clock.

    Callbacks run one at a time on the thread that calls `spin`. A callback that raises is
    logged with its traceback and counted on `diagnostics` (`callback_errors/<kind>/<name>`);
    with `on_error="exit"` the exception then leaves `spin` (the launcher restarts the component
    by its policy), with `"log"` (the default) the component goes on.
    """

    def __init__(
        self,
        name: str,
        argv: list[str] | None = None,
        serves: list[str] | tuple[str, ...] = (),
        on_error: str = "log",
    ):
        if on_error not in ("log", "exit"):
            raise ValueError(f"on_error is 'log' or 'exit', not {on_error!r}")
        self._node = _robocog.Node(name, list(argv or []), list(serves))
        self.on_error = on_error
        self.log = logging.getLogger(self._node.name)

    @property
    def name(self) -> str:
        return self._node.name

    @property
    def namespace(self) -> str:
        return self._node.namespace

    @property
    def state_dir(self) -> pathlib.Path | None:
        """The component's state folder, kept across its restarts (the launcher gives it as
        `ROBOCOG_STATE_DIR`), made if missing; None when not launched. Write it atomically (a
        temporary file, then `os.replace`)."""
        d = os.environ.get("ROBOCOG_STATE_DIR")
        if not d:
            return None
        path = pathlib.Path(d)
        path.mkdir(parents=True, exist_ok=True)
        return path

    def now_ns(self) -> int:
        """The node's time in ns since the epoch (the bus clock under `--clock bus`)."""
        return self._node.now_ns()

    def count(self, name: str, n: int = 1) -> None:
        """Add `n` to counter `name` of the component's `diagnostics`."""
        self._node.count(name, n)

    def counter(self, name: str) -> int:
        return self._node.counter(name)

    def publisher(self, topic: str, type: type | str) -> Publisher:
        name = type_name(type)
        return Publisher(self._node.publisher(topic, name), name)

    def subscribe(
        self,
        topic: str,
        type: type | str,
        callback: Callable[..., None],
        queue: int = 256,
        with_seq: bool = False,
    ) -> None:
        """Call `callback(message)` for each message on `topic` (with `with_seq`,
        `callback(message, seq)`: the publisher's sequence number, which the wire form of a
        header does not carry). At most `queue` messages wait for the callback: past that the
        oldest is dropped and counted (`queue_dropped/<topic>`; `queue=1` keeps only the newest);
        a payload that does not decode is dropped and counted (`decode_errors/<topic>`), as in
        Rust."""
        self._node.subscribe(topic, type_name(type), callback, queue, with_seq)

    def serve(
        self,
        service: str,
        request_type: type | str,
        reply_type: type | str,
        handler: Callable[[Any], Any],
    ) -> None:
        """Serve `service`: `handler(request)` returns the reply, or raises `ServiceError(code,
        message)` for a typed refusal. Any other exception is an `Internal` error for the caller,
        logged and counted here."""
        self._node.serve(
            service, type_name(request_type), type_name(reply_type), handler
        )

    def call(
        self, service: str, request: Any, reply_type: type | str, timeout_s: float = 2.0
    ) -> Any:
        """Call `service` and return its reply. Raises `RemoteError(code, message)`,
        `NoServerError` or `TimeoutError`."""
        return self._node.call(
            service, type_name(request), request, type_name(reply_type), timeout_s
        )

    def timer(self, period_s: float, callback: Callable[[], None]) -> None:
        """Call `callback()` every `period_s` seconds of the node's clock."""
        self._node.timer(period_s, callback)

    @property
    def stopping(self) -> bool:
        """Whether the component was asked to stop (SIGTERM or `stop()`)."""
        return self._node.stopping()

    def stop(self) -> None:
        self._node.stop()

    def spin_once(self, timeout_s: float | None = None) -> bool:
        """Run at most one callback, waiting at most `timeout_s`. False once asked to stop."""
        outcome = self._node.spin_once(timeout_s)
        if outcome is None:
            return True
        if outcome[0] == "stop":
            return False
        _, kind, name, error = outcome
        self.count(f"callback_errors/{kind}/{name}")
        self.log.error(
            "the %s callback of %s raised:\n%s",
            kind,
            name,
            "".join(traceback.format_exception(error)).rstrip(),
        )
        if self.on_error == "exit":
            raise error
        return True

    def spin(self, timeout_s: float | None = None) -> None:
        """Run callbacks until the component is asked to stop (or `timeout_s` has passed)."""
        import time

        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                return
            if not self.spin_once(left):
                return
