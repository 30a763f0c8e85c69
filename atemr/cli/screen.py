"""``atemr screen``: the robot's screens (its tablet) and their device tokens, from the robot's console."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


class ScreenCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        parser.add_argument("--data-dir", type=Path, help="where the users database lives")
        sub = parser.add_subparsers(dest="action", required=True)
        add = sub.add_parser("add", help="make a screen and print its token once (only its hash is kept)")
        add.add_argument("name")
        sub.add_parser("list", help="list the screens (never their tokens)")
        revoke = sub.add_parser("revoke", help="delete a screen: its token opens nothing from now on")
        revoke.add_argument("name")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.config import load_config
        from atemr.ui.app import database_path
        from atemr.ui.screens import ScreenStore

        config = load_config(args.config, overrides={"data_dir": args.data_dir})
        store = ScreenStore(database_path(config))
        if args.action == "list":
            for screen in store.list():
                made = time.strftime("%Y-%m-%d %H:%M", time.localtime(screen.created_unix_s))
                print(f"{screen.name:32} made {made}")
            return 0
        if args.action == "revoke":
            store.revoke(args.name)
            print(f"screen {args.name} revoked")
            return 0
        token = store.add(args.name)
        print(token)
        scheme = "https" if config.ui.tls_cert is not None else "http"
        print(f"The token of screen {args.name}, shown this once: open {scheme}://ROBOT:{config.ui.port}/screen?"
              f"token={token} on the robot's tablet.", file=sys.stderr)
        if config.ui.tls_cert is None:
            print("Its camera and microphone need HTTPS over the network: see 'atemr tls make-cert'.", file=sys.stderr)
        return 0
