"""``atemr dashboard``: a dashboard worker without a robot of its own, delivering the state the robots
publish into ``ui.message_queue`` (several robots on one page, or several workers behind a proxy)."""

from __future__ import annotations

import argparse
from pathlib import Path

from atemr.cli.signals import stop_on_signals
from atemr.errors import ConfigError


class DashboardCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        parser.add_argument("--message-queue", help="Redis URL the robots publish to, e.g. redis://127.0.0.1:6379/0")
        parser.add_argument("--host", help="address to listen on (default 127.0.0.1; 0.0.0.0: every interface, "
                                           "which exposes it to the network)")
        parser.add_argument("--port", type=int, help="TCP port (default 5000; 0: any free port)")
        parser.add_argument("--data-dir", type=Path, help="where the users database and the session key live")

    def run(self, args: argparse.Namespace) -> int:
        import threading

        from atemr.config import load_config
        from atemr.logsetup import configure_logging
        from atemr.ui.server import DashboardServer

        config = load_config(args.config, overrides={
            "log_level": args.log_level, "ui.message_queue": args.message_queue, "ui.host": args.host,
            "ui.port": args.port, "data_dir": args.data_dir,
        })
        configure_logging(config.log_level)
        if config.ui.message_queue is None:
            raise ConfigError("a dashboard without a robot shows the robots of a message queue: set "
                              "--message-queue or ui.message_queue (redis://...)", path="ui.message_queue")
        server = DashboardServer(config, None)
        stop = threading.Event()
        with stop_on_signals(stop.set):
            server.start()
            try:
                print(f"ATEMR dashboard on {server.url}, robots from {config.ui.message_queue}. Ctrl-C stops.",
                      flush=True)
                while not stop.wait(1.0):
                    pass
            finally:
                server.shutdown()
        print("ATEMR dashboard stopped.", flush=True)
        return 0
