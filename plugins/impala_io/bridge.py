"""io.FoxgloveBridge: a live view of any graph in Foxglove, over Foxglove's WebSocket protocol.

The server is the ``foxglove-sdk`` package's (subprotocol ``foxglove.sdk.v1``, the successor
of ``foxglove.websocket.v1`` with the same operations; the Foxglove app speaks both): open
Foxglove, "Open connection", "Foxglove WebSocket", ``ws://HOST:PORT``. One input per stream,
named after its topic (``topics``: topic -> the ``component.port`` it shows, as for
``io.Recorder``). Each sample is sent stamped with its own time (``log_time`` = its int ns),
the same way a recording shows it (:mod:`impala_flow.io.foxglove`):

- poses, trajectories, grids, point sets, objects, detections and scans in Foxglove's
  protobuf schemas (the 3D, Image and Plot panels show them);
- every other value as its JSON view with a JSON Schema (:mod:`impala_flow.io.jsonview`):
  fields by name, arrays over ``max_array`` values as their shape, plain numbers as
  ``{"value": x}``, so the Plot panel plots any scalar stream (speeds, yaw rates, counters).

The graph never waits for a client: ``Channel.log`` hands the message to the SDK's own
sender, which keeps at most ``backlog`` messages per client and drops the oldest beyond
(a slow client loses samples, not the graph its pace). A sample is encoded only when a
client is subscribed to its topic (``sent`` vs ``unwatched`` in the summary). In a replay
graph the clock's ``speed`` paces the view (``impala-flow view FILE.mcap --speed 2``).
"""

from __future__ import annotations

import logging
import sys
from typing import Any

from impala_flow.component import Component, Input, Param
from impala_flow.io.foxglove import mirror_for
from impala_flow.io.jsonview import encode as encode_json
from impala_flow.io.jsonview import json_schema, to_json

__all__ = ["FoxgloveBridge", "to_json"]  # to_json: the JSON view (impala_flow.io.jsonview)

log = logging.getLogger(__name__)


class FoxgloveBridge(Component):
    """Serves the streams it receives to Foxglove over WebSocket (module doc)."""

    topics = Param(dict, default={}, doc="topic -> 'component.port' it shows")
    host = Param(str, default="127.0.0.1", doc="interface to listen on (0.0.0.0: every interface)")
    port = Param(int, default=8765, ge=0, le=65535, doc="TCP port (0: any free port, see the log)")
    backlog = Param(int, default=1024, ge=1, doc="messages kept per client before the oldest are dropped")
    max_array = Param(int, default=64, ge=0, doc="arrays up to this many values are sent in full as JSON")
    server_name = Param(str, default="impala-flow", doc="server name shown by Foxglove")
    announce = Param(bool, default=False, doc="print the address to connect to on stderr at start")

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Any]]:
        return {t: Input(object, maxsize=64, overflow="drop_oldest", required=False, doc=f"shows {o}")
                for t, o in params["topics"].items()}, {}

    def start(self) -> None:
        import foxglove  # imported here: loading the plugin stays cheap

        self._fx = foxglove
        self._context = foxglove.Context()
        self.server = foxglove.start_server(name=self.server_name, host=self.host, port=self.port,
                                            context=self._context, message_backlog_size=self.backlog)
        self.bound_port = self.server.port
        log.info("Foxglove: open a connection to ws://%s:%d", self.host, self.bound_port)
        if self.announce:
            print(f"Foxglove: open a connection to ws://{self.host}:{self.bound_port} "
                  "(Foxglove > Open connection > Foxglove WebSocket)", file=sys.stderr, flush=True)
        self._channels: dict[str, tuple[Any, Any]] = {}  # topic -> (channel, encoder)
        self.sent: dict[str, int] = {}
        self.unwatched = 0

    def _channel(self, topic: str, value: Any) -> tuple[Any, Any]:
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
        ch.log(encode(s.data, s.timestamp), log_time=s.timestamp)
        self.sent[topic] += 1

    def stop(self) -> None:
        server = getattr(self, "server", None)
        if server is not None:
            server.stop()
            self.server = None

    def summary(self) -> dict[str, Any]:
        return {"port": getattr(self, "bound_port", self.port), "sent": sum(getattr(self, "sent", {}).values()),
                "unwatched": getattr(self, "unwatched", 0), "backlog": self.backlog}
