"""Beyond one machine: robots publish their state into Flask-SocketIO's message queue (Redis).

With ``ui.message_queue`` set, every dashboard worker subscribes to the queue (`atemr.ui.app.create_app`
passes the URL to `SocketIO`), so a ``state`` event emitted into it by any process reaches the operators
of every worker. A robot with its own dashboard emits through that dashboard's Socket.IO server; a robot
without one (``ui.enabled: false``) runs a `StatePublisher`, a write-only ``SocketIO(message_queue=...)``
that emits the same ``state`` event at the dashboard's push rate. Each state names its robot (``robot``),
so an operator watching several robots tells them apart. Camera frames, the agent view and commands stay
with the robot's own dashboard.

The robot's thread only takes the snapshot; a sender thread does the network I/O, keeping just the newest
snapshot, so a slow or unreachable Redis never stalls the robot's tick.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
from typing import Any

from flask_socketio import SocketIO

from atemr.errors import ConfigError, HardwareError
from atemr.ui.gateway import RobotGateway
from atemr.ui.sockets import OPERATORS, state_message

log = logging.getLogger(__name__)

#: How long the start-up reachability check waits for Redis.
CONNECT_TIMEOUT_S = 3.0


def check_reachable(url: str, component: str) -> None:
    """Ping the Redis at ``url`` once, so a wrong URL or a stopped server is a clear error at start-up
    instead of log lines from a retrying background thread."""
    try:
        import redis
    except ImportError:
        raise ConfigError("ui.message_queue needs the redis package: pip install 'atemr[redis]'",
                          path="ui.message_queue") from None
    try:
        client = redis.Redis.from_url(url, socket_connect_timeout=CONNECT_TIMEOUT_S,
                                      socket_timeout=CONNECT_TIMEOUT_S)
        try:
            client.ping()
        finally:
            client.close()
    except (redis.RedisError, ValueError) as exc:
        raise HardwareError(f"cannot reach the message queue {url}: {exc}", component=component) from None


class StatePublisher:
    """A scheduler component publishing the robot's state into the message queue (no web server).

    Wire it as ``robot.add(StatePublisher(url, gateway), PUSH_RATE_HZ)``; `start` checks the queue is
    reachable, `tick` hands the newest snapshot to the sender thread, `shutdown` (idempotent) stops it.
    """

    name = "state_publisher"

    def __init__(self, url: str, gateway: RobotGateway) -> None:
        self.url = url
        self.gateway = gateway
        self.published = 0
        self._outbox: queue.Queue[dict[str, Any] | None] = queue.Queue(maxsize=1)
        self._thread: threading.Thread | None = None
        self._socketio: SocketIO | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        if self._thread is not None:
            return
        check_reachable(self.url, self.name)
        self._socketio = SocketIO(message_queue=self.url)  # no app: a write-only emitter
        self._thread = threading.Thread(target=self._send, name="atemr-state-publisher", daemon=True)
        self._thread.start()
        log.info("publishing the robot's state to %s", self.url)

    def tick(self, now: float) -> None:
        if self._thread is None:
            return
        self._offer(state_message(self.gateway))

    def _offer(self, item: dict[str, Any] | None) -> None:
        """Queue ``item``, dropping an older snapshot not yet sent (only the newest matters)."""
        while True:
            try:
                self._outbox.put_nowait(item)
                return
            except queue.Full:
                with contextlib.suppress(queue.Empty):
                    self._outbox.get_nowait()

    def _send(self) -> None:
        socketio = self._socketio
        assert socketio is not None
        while True:
            item = self._outbox.get()
            if item is None:
                return
            try:
                socketio.emit("state", item, to=OPERATORS)
            except Exception:  # a queue hiccup must not end the publishing
                log.exception("publishing the state to %s failed", self.url)
                continue
            self.published += 1

    def shutdown(self) -> None:
        thread, self._thread = self._thread, None
        if thread is None:
            return
        self._offer(None)
        thread.join(timeout=5.0)
        manager = getattr(getattr(self._socketio, "server", None), "manager", None)
        connection = getattr(manager, "redis", None)
        if connection is not None:
            connection.close()
