"""view.FoxgloveBridge: a live view of any graph in Foxglove, over Foxglove's WebSocket protocol.

The server is the ``foxglove-sdk`` package's (subprotocol ``foxglove.sdk.v1``, the successor
of ``foxglove.websocket.v1`` with the same operations; the Foxglove app speaks both): open
Foxglove, "Open connection", "Foxglove WebSocket", ``ws://HOST:PORT``. One input per stream,
named after its topic (``topics``: topic -> the ``component.port`` it shows, as for
``io.Recorder``). Each sample is sent stamped with its own time (``log_time`` = its int ns),
the same way a recording shows it (:mod:`impala_view.mirrors`):

- poses, trajectories, grids, point sets, objects, detections and scans in Foxglove's
  protobuf schemas (the 3D, Image and Plot panels show them);
- every other value as its JSON view with a JSON Schema (:func:`impala_flow.io.json_schema`):
  fields by name, arrays over ``max_array`` values as their shape, plain numbers as
  ``{"value": x}``, so the Plot panel plots any scalar stream (speeds, yaw rates, counters).

The graph never waits for a client, and the memory the server holds is bounded in bytes, by
construction. The SDK's sender keeps, per client, at most ``backlog`` messages and drops the
oldest beyond (a slow client loses samples, not the graph its pace); the bridge derives that
``backlog`` from a byte budget, ``client_bytes // max_message_bytes`` (8 to 1024), and never sends a
message over ``max_message_bytes`` (dropped and counted per topic as ``oversized``, one
warning per topic). So a client that subscribes to everything and never reads holds at most
``client_bytes`` (plus the one message being written to its socket), and while more than
``max_clients`` clients are connected nothing is sent (each sample counted per topic as
``clients over max_clients``): at most ``max_clients * client_bytes`` in all. The SDK drops
a slow client's oldest messages without counting them; the bridge counts the times it says
so (``slow-client drops (at least)``; it says so at most every 30 s). These drops appear in
the run summary (``LOST at view.<topic>``). A sample is encoded only when a client is
subscribed to its topic (``sent`` vs ``unwatched`` in the summary). In a replay graph the
clock's ``speed`` paces the view (``impala-flow view FILE.mcap --speed 2``).

The server binds 127.0.0.1 unless ``host`` says otherwise and prints where it listens; a
port in use or a host it cannot bind is a one-line error naming ``host:port``. Invalid
frames from a client (the SDK logs one ERROR each) are logged once per kind and then counted
(``client_errors`` in the summary).
"""

from __future__ import annotations

import logging
import re
import sys
import threading
import weakref
from typing import Any

from impala_flow import Component, Input, Param
from impala_flow.io import encode_json, json_schema, to_json

__all__ = ["FoxgloveBridge", "to_json"]  # to_json: the JSON view (impala_flow.io.to_json)

log = logging.getLogger(__name__)

MiB = 1 << 20
OVERSIZED = "oversized"
OVER_CLIENTS = "clients over max_clients"
SLOW = "slow-client drops (at least)"
MIN_BACKLOG = 8  # messages per client: the SDK disconnects a client whose control queue (as long) is full
MAX_BACKLOG = 1024  # the SDK's default

# The SDK's Rust log reaches Python logging through pyo3-log, one logger per Rust module. These
# are the records the bridge reads (client connections, full outboxes) or aggregates (invalid
# frames); the INFO ones are raised to INFO here, read, and never printed.
_SERVER_LOG = "foxglove.websocket.server"
_OUTBOX_LOG = "foxglove.websocket.connected_client.send_lossy"
_WATCHED = (_SERVER_LOG, _OUTBOX_LOG, "foxglove.websocket.connected_client", "foxglove.websocket.advertise",
            "foxglove.websocket.connected_client.poller", "foxglove.websocket_server")  # every one that warns
_ADDR = re.compile(r"\[?[0-9a-fA-F.:]+\]?:\d+")


def _kind(msg: str) -> str:
    """A log line without what varies between occurrences (client addresses, numbers)."""
    return re.sub(r"\d+", "N", _ADDR.sub("ADDR", msg))[:200]


class _SdkLog(logging.Filter):
    """One per process (loggers are): counts the SDK's connected clients and full outboxes for
    every live bridge, and its warnings and errors by kind (an invalid frame, a failed handshake,
    a subscription to an unknown channel: one line per occurrence from the SDK): lets the first
    of each kind through and swallows the rest. Clients are counted over every server of the
    process (the records name the client, not the server): a conservative count."""

    def __init__(self) -> None:
        super().__init__()
        self.lock = threading.Lock()
        self.clients: set[str] = set()
        self.started: set[str] = set()  # host:port of the servers started
        self.bridges: weakref.WeakSet[FoxgloveBridge] = weakref.WeakSet()

    def filter(self, record: logging.LogRecord) -> bool:
        msg = record.getMessage()
        name = record.name
        if name == _SERVER_LOG and msg.startswith("Started server on "):
            self.started.add(msg.split()[3])
        elif name == _SERVER_LOG and msg.startswith(("Registered client ", "Unregistered client ")):
            addr = msg.split()[-1]
            with self.lock:
                (self.clients.add if msg.startswith("Registered") else self.clients.discard)(addr)
                n = len(self.clients)
            for b in list(self.bridges):
                b._clients_now(n)
        elif name == _OUTBOX_LOG and "full" in msg:
            for b in list(self.bridges):
                b._slow_client()
        if record.levelno < logging.WARNING:  # raised to INFO to be read here: printed only if asked (--debug)
            return logging.getLogger().isEnabledFor(record.levelno)
        bridges = list(self.bridges)
        if not bridges:
            return True
        kind = _kind(msg)
        if not [b for b in bridges if b._client_error(kind)]:
            return False
        record.msg, record.args = msg + " (further ones of this kind are counted, not logged)", None
        return True


_SDK_LOG: _SdkLog | None = None


def _watch_sdk_log() -> _SdkLog:
    global _SDK_LOG
    if _SDK_LOG is None:
        _SDK_LOG = _SdkLog()
        for name in _WATCHED:
            logger = logging.getLogger(name)
            logger.addFilter(_SDK_LOG)
            if name in (_SERVER_LOG, _OUTBOX_LOG):
                logger.setLevel(logging.INFO)  # before the SDK's first record: pyo3-log caches levels
    return _SDK_LOG


class FoxgloveBridge(Component):
    """Serves the streams it receives to Foxglove over WebSocket, in bounded memory (module doc)."""

    topics = Param(dict, default={}, doc="topic -> 'component.port' it shows")
    host = Param(str, default="127.0.0.1", doc="interface to listen on (0.0.0.0: every interface)")
    port = Param(int, default=8765, ge=0, le=65535, doc="TCP port (0: any free port, printed at start)")
    client_bytes = Param(int, default=128 * MiB, ge=1,
                         doc="bytes of messages kept per client that reads slowly (oldest dropped beyond)")
    max_message_bytes = Param(int, default=8 * MiB, ge=1024,
                              doc="largest message sent (encoded); larger ones are dropped and counted")
    max_clients = Param(int, default=4, ge=1, doc="while more clients are connected, nothing is sent")
    max_array = Param(int, default=64, ge=0, doc="arrays up to this many values are sent in full as JSON")
    server_name = Param(str, default="impala-flow", doc="server name shown by Foxglove")
    stop_timeout_s = Param(float, default=5.0, gt=0, le=3600,
                           doc="how long stop() waits for the clients to be told goodbye")
    announce = Param(bool, default=True, doc="print the address to connect to on stderr at start")

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Any]]:
        return {t: Input(object, maxsize=64, overflow="drop_oldest", required=False, doc=f"shows {o}")
                for t, o in params["topics"].items()}, {}

    @property
    def backlog(self) -> int:
        """Messages the SDK keeps per client: the byte budget over the largest message, at most
        MAX_BACKLOG (the SDK's queue of control messages, error answers included, is as long)."""
        return max(1, min(MAX_BACKLOG, self.client_bytes // self.max_message_bytes))

    def start(self) -> None:
        import foxglove  # imported here: loading the plugin stays cheap

        if self.backlog < MIN_BACKLOG:
            raise ValueError(f"client_bytes={self.client_bytes} holds {self.backlog} message(s) of max_message_bytes="
                             f"{self.max_message_bytes}; at least {MIN_BACKLOG} are needed (the SDK's queue of "
                             "control messages per client is as long)")
        self._fx = foxglove
        self._channels: dict[str, tuple[Any, Any]] = {}  # topic -> (channel, encoder)
        self.sent: dict[str, int] = {}
        self.unwatched = 0
        self.dropped: dict[str, dict[str, int]] = {}
        self.client_errors: dict[str, int] = {}
        self.slow_reports = 0
        self._clients = 0
        self.clients_max = 0
        self._warned: set[tuple[str, str]] = set()
        self._sdk_log = _watch_sdk_log()
        self._sdk_log.bridges.add(self)
        self._context = foxglove.Context()
        try:
            self.server = foxglove.start_server(name=self.server_name, host=self.host, port=self.port,
                                                context=self._context, message_backlog_size=self.backlog)
        except RuntimeError as e:  # the SDK's FoxgloveError: "Failed to bind port: <OS reason>"
            self._sdk_log.bridges.discard(self)
            why = str(e).split("Failed to bind port: ", 1)[-1]
            raise OSError(f"cannot listen on {self.host}:{self.port}: {why}") from None
        self.bound_port = self.server.port
        if not any(a.rsplit(":", 1)[-1] == str(self.bound_port) for a in self._sdk_log.started):
            log.warning("%s: the foxglove SDK's log does not reach Python logging here: clients are not counted "
                        "(max_clients=%d not enforced)", self.name, self.max_clients)
        host = f"[{self.host}]" if ":" in self.host else self.host  # IPv6
        where = f"ws://{host}:{self.bound_port}"
        log.info("Foxglove: open a connection to %s", where)
        if self.announce:
            every = " (every interface)" if self.host in ("0.0.0.0", "::") else ""
            print(f"Foxglove: open a connection to {where}{every} "
                  "(Foxglove > Open connection > Foxglove WebSocket)", file=sys.stderr, flush=True)

    # -- called by the SDK's log records (_SdkLog), from the SDK's threads
    def _clients_now(self, n: int) -> None:
        self._clients = n
        self.clients_max = max(self.clients_max, n)

    def _slow_client(self) -> None:
        self.slow_reports += 1

    def _client_error(self, kind: str) -> bool:
        n = self.client_errors.get(kind, 0)
        self.client_errors[kind] = n + 1
        return n == 0

    def _drop(self, topic: str, kind: str, why: str) -> None:
        per = self.dropped.setdefault(topic, {})
        per[kind] = per.get(kind, 0) + 1
        if (topic, kind) not in self._warned:
            self._warned.add((topic, kind))
            log.warning("%s: %s (dropped and counted; said once per topic)", self.name, why)

    def _channel(self, topic: str, value: Any) -> tuple[Any, Any]:
        from .mirrors import mirror_for  # protobuf is imported when the first sample is shown

        fx = self._fx
        mirror = mirror_for(type(value))
        if mirror is not None:
            ch = fx.Channel(topic, schema=fx.Schema(name=mirror.schema_name, encoding="protobuf",
                                                    data=mirror.schema_data),
                            message_encoding="protobuf", context=self._context)
            return ch, mirror.convert
        name, schema = json_schema(type(value))
        ch = fx.Channel(topic, schema=fx.Schema(name=name, encoding="jsonschema", data=schema),
                        message_encoding="json", context=self._context)
        max_array = self.max_array
        return ch, lambda v, t: encode_json(v, max_array)

    def process(self, t: int) -> None:
        topic = self.trigger
        s = self.inputs[topic].take_sample()
        entry = self._channels.get(topic)
        if entry is None:
            entry = self._channels[topic] = self._channel(topic, s.data)
            self.sent[topic] = 0
        ch, encode = entry
        if not ch.has_sinks():  # nobody subscribed: not even encoded
            self.unwatched += 1
            return
        if self._clients > self.max_clients:  # each client costs up to client_bytes: none sent
            self._drop(topic, OVER_CLIENTS, f"{self._clients} clients connected, max_clients={self.max_clients}: "
                       f"'{topic}' is not sent until some disconnect")
            return
        payload = encode(s.data, s.timestamp)
        if len(payload) > self.max_message_bytes:
            self._drop(topic, OVERSIZED, f"'{topic}' at t={s.timestamp} ns encodes to {len(payload)} bytes, over "
                       f"max_message_bytes={self.max_message_bytes}")
            return
        ch.log(payload, log_time=s.timestamp)
        self.sent[topic] += 1

    def stop(self) -> None:
        server = getattr(self, "server", None)
        if server is not None:
            self.server = None
            # The SDK's stop() waits for every client task, and the task of a client that does
            # not read waits forever to write its goodbye: stop in a thread, give up after a while
            # (the port is closed by then; the stuck task ends with the process).
            stopper = threading.Thread(target=server.stop, name=f"{self.name}-stop", daemon=True)
            stopper.start()
            stopper.join(self.stop_timeout_s)
            if stopper.is_alive():
                log.warning("%s: a client that does not read held the server's shutdown; left behind after %g s",
                            self.name, self.stop_timeout_s)
        sdk_log = getattr(self, "_sdk_log", None)
        if sdk_log is not None:
            sdk_log.bridges.discard(self)

    def summary(self) -> dict[str, Any]:
        dropped = {t: dict(k) for t, k in getattr(self, "dropped", {}).items()}
        if getattr(self, "slow_reports", 0):
            dropped["clients"] = {SLOW: self.slow_reports}
        out: dict[str, Any] = {
            "port": getattr(self, "bound_port", self.port), "sent": sum(getattr(self, "sent", {}).values()),
            "unwatched": getattr(self, "unwatched", 0), "backlog": self.backlog, "client_bytes": self.client_bytes,
            "max_message_bytes": self.max_message_bytes, "clients_max": getattr(self, "clients_max", 0)}
        if dropped:
            out["dropped"] = dropped
        if getattr(self, "client_errors", None):
            out["client_errors"] = dict(self.client_errors)
        return out
