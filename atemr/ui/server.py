"""The dashboard as a robot component: serves the app in a background thread and pushes state at 10 Hz.

``start()`` binds ``ui.host:ui.port`` (port 0 picks a free port, see `port`) and serves Flask-SocketIO
(threading async mode) with werkzeug's threaded server in a daemon thread; ``tick(now)`` — scheduled by
the robot at `PUSH_RATE_HZ` — sends the gateway's snapshot to every logged-in browser and camera frames
to those watching; ``shutdown()`` stops the server and joins the thread (idempotent). The pushes ride on
the robot's scheduler, so there is no timer thread and no wall-clock sleep here.
"""

from __future__ import annotations

import logging
import threading

from flask import Flask
from werkzeug.serving import BaseWSGIServer, make_server

from atemr.clock import Clock
from atemr.config import Config
from atemr.errors import HardwareError
from atemr.ui import sockets
from atemr.ui.app import create_app
from atemr.ui.gateway import RobotGateway
from atemr.ui.users import HASH_METHOD

log = logging.getLogger(__name__)

#: How often the robot should tick the server (state pushes per second).
PUSH_RATE_HZ = 10.0


class DashboardServer:
    """A scheduler component running the operator dashboard.

    Wire it as ``robot.add(DashboardServer(config, gateway, clock=clock), PUSH_RATE_HZ)``.
    """

    name = "dashboard"

    def __init__(
        self,
        config: Config,
        gateway: RobotGateway | None,
        *,
        clock: Clock | None = None,
        hash_method: str = HASH_METHOD,
    ) -> None:
        self.config = config
        self.gateway = gateway
        self.app: Flask = create_app(config, gateway, clock=clock, hash_method=hash_method)
        self._server: BaseWSGIServer | None = None
        self._thread: threading.Thread | None = None
        self.pushes = 0

    @property
    def port(self) -> int:
        """The bound port (the real one when the configuration asked for 0)."""
        if self._server is None:
            raise HardwareError("the dashboard is not started", component=self.name)
        return int(self._server.server_port)

    @property
    def url(self) -> str:
        return f"http://{self.config.ui.host}:{self.port}"

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        if self._server is not None:
            return
        try:
            self._server = make_server(self.config.ui.host, self.config.ui.port, self.app, threaded=True)
        except (OSError, SystemExit) as exc:  # werkzeug exits (!) when the port is taken
            why = exc.strerror if isinstance(exc, OSError) else "the address is in use or not available"
            raise HardwareError(
                f"cannot listen on {self.config.ui.host}:{self.config.ui.port}: {why}", component=self.name
            ) from None
        self._thread = threading.Thread(target=self._server.serve_forever, name="atemr-dashboard", daemon=True)
        self._thread.start()
        if self.app.extensions["atemr.users"].needs_root_password():
            log.warning(
                "the dashboard has no admin password yet: open %s on this machine or run "
                "'atemr user set-password admin'", self.url,
            )
        log.info("dashboard on %s", self.url)

    def tick(self, now: float) -> None:
        """Push the state (and camera frames) to the connected browsers."""
        if self._server is None:
            return
        sockets.push(self.app, self.gateway)
        self.pushes += 1

    def shutdown(self) -> None:
        server, thread = self._server, self._thread
        self._server = self._thread = None
        if server is not None:
            server.shutdown()
            server.server_close()
        if thread is not None:
            thread.join(timeout=5.0)
