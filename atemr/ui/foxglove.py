"""`FoxgloveLive`: the robot's channels served live to Foxglove over its WebSocket protocol (``ui.foxglove``).

The server is the Foxglove SDK's (`foxglove.start_server`), in a context of its own so two robots in one
process (tests) never share channels. Every topic of `atemr.io.recording.topics` is advertised with the same
schema as in a recording, so a layout made on a recording works live and back. A message is encoded only
when a client subscribed to its topic (`wants`), and `write` only hands the bytes to the SDK: each client
has its own bounded queue on the server's threads, and a client that reads too slowly loses its oldest
messages there (``message_backlog_size``), never the robot's time. Topics that change rarely (the map, the
static transforms, the plan, the agent's state) are sent again to a client when it subscribes, as a ROS
latched topic would be.

On the real robot the same channels come from the same parts (`atemr.robot.recorder`): set
``ui.foxglove.enabled`` and ``ui.foxglove.host`` to the address Foxglove reaches the robot on.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

import foxglove
from foxglove.websocket import ChannelView, Client, ServerListener

from atemr.errors import ConfigError
from atemr.io.recording.mcap_writer import Entry
from atemr.io.recording.topics import AGENT_STATE, MAP, PLAN, TF_STATIC, TOPICS

log = logging.getLogger(__name__)

#: Topics a new subscriber gets the last message of at once.
LATCHED = frozenset({MAP.name, TF_STATIC.name, PLAN.name, AGENT_STATE.name})
#: Messages queued per client on the server before the oldest are dropped.
BACKLOG = 256


class _Listener(ServerListener):
    """The server's callbacks (its own threads): a new subscriber to a latched topic gets its last message."""

    def __init__(self, live: FoxgloveLive) -> None:
        self.live = live

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.live.resend(channel.topic)


class FoxgloveLive:
    """A Foxglove WebSocket server on ``host``:``port`` (0: any free port) carrying the robot's topics."""

    name = "foxglove"
    #: Takes encoded messages (`write`).
    encodes = False

    def __init__(self, host: str = "127.0.0.1", port: int = 8765, *, backlog: int = BACKLOG,
                 robot_name: str = "ATEMR") -> None:
        self.host = host
        self.requested_port = port
        self.backlog = backlog
        self.robot_name = robot_name
        self.context = foxglove.Context()
        self.channels: dict[str, foxglove.Channel] = {
            t.name: foxglove.Channel(t.name, message_encoding=t.message_encoding, context=self.context,
                                     schema=foxglove.Schema(name=t.schema_name, encoding=t.schema_encoding,
                                                            data=t.schema_data))
            for t in TOPICS.values()
        }
        self.sent = 0
        self._latched: dict[str, Entry] = {}
        self._lock = threading.Lock()
        self._server: Any = None

    @property
    def port(self) -> int:
        """The port the server listens on (once started)."""
        return int(self._server.port) if self._server is not None else self.requested_port

    def start(self) -> None:
        """Start listening; a port in use is a `ConfigError` naming ``ui.foxglove.port``."""
        if self._server is not None:
            return
        try:
            self._server = foxglove.start_server(name=self.robot_name, host=self.host, port=self.requested_port,
                                                 context=self.context, server_listener=_Listener(self),
                                                 message_backlog_size=self.backlog)
        except Exception as exc:
            raise ConfigError(f"the Foxglove server cannot listen on {self.host}:{self.requested_port}: {exc}",
                              path="ui.foxglove.port") from None
        log.info("Foxglove live view on ws://%s:%d", self.host, self.port)

    # -- the recorder's sink --------------------------------------------------------------------------------
    def wants(self, topic: str) -> bool:
        channel = self.channels.get(topic)
        return topic in LATCHED or (channel is not None and channel.has_sinks())

    def write(self, topic: str, log_time: int, data: bytes) -> None:
        if topic in LATCHED:
            with self._lock:
                self._latched[topic] = (topic, log_time, data)
        channel = self.channels.get(topic)
        if channel is not None and channel.has_sinks():
            channel.log(data, log_time=log_time)
            self.sent += 1

    def write_message(self, topic: str, log_time: int, message: Any) -> None:
        raise TypeError("FoxgloveLive takes encoded messages: use write()")

    def resend(self, topic: str) -> None:
        """Send ``topic``'s last message again (a client just subscribed to it)."""
        with self._lock:
            entry = self._latched.get(topic)
        if entry is not None:
            self.channels[topic].log(entry[2], log_time=entry[1])

    # -- scheduler component ------------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Nothing to do on the robot's thread: the SDK's threads serve the clients."""

    def shutdown(self) -> None:
        """Stop the server (idempotent)."""
        server, self._server = self._server, None
        if server is not None:
            server.stop()


__all__ = ["BACKLOG", "LATCHED", "FoxgloveLive"]
