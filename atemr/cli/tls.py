"""``atemr tls make-cert``: a self-signed certificate for the dashboard, so calls work over the home network.

Browsers give a page the camera and microphone only over HTTPS (or on localhost): the carer's laptop and the
robot's tablet both reach the robot by its address, so a call needs the dashboard on HTTPS. This writes the
certificate and key into ``data_dir/tls`` (or ``--out``) and prints the two settings that turn HTTPS on and
the fingerprint to compare on each device the first time it connects.
"""

from __future__ import annotations

import argparse
import os
import socket
from pathlib import Path

from atemr.errors import ConfigError


class TlsCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="action", required=True)
        make = sub.add_parser("make-cert", help="make a self-signed certificate for the names and addresses the "
                                                "robot is reached by")
        make.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        make.add_argument("--data-dir", type=Path, help="where to keep the certificate (data_dir/tls)")
        make.add_argument("--host", action="append", default=[], metavar="NAME",
                          help="a name or address of the robot (repeat; default: this machine's host name, "
                               "NAME.local, localhost, 127.0.0.1)")
        make.add_argument("--days", type=int, default=825, help="validity in days (at most 825)")
        make.add_argument("--out", type=Path, help="directory for cert.pem and key.pem (default: data_dir/tls)")
        make.add_argument("--force", action="store_true", help="replace a certificate already there")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.config import load_config
        from atemr.ui.tls import fingerprint, make_certificate

        config = load_config(args.config, overrides={"data_dir": args.data_dir})
        out = args.out or config.data_dir / "tls"
        cert_path, key_path = out / "cert.pem", out / "key.pem"
        if not args.force and (cert_path.exists() or key_path.exists()):
            raise ConfigError("a certificate is already there: --force replaces it (each device must then "
                              "accept the new one)", file=str(cert_path), path="--force")
        name = socket.gethostname()
        hosts = args.host or [name, f"{name}.local", "localhost", "127.0.0.1"]
        cert, key = make_certificate(hosts, days=args.days)
        out.mkdir(parents=True, exist_ok=True)
        fd = os.open(key_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)  # the key: the robot's alone
        with os.fdopen(fd, "wb") as handle:
            handle.write(key)
        cert_path.write_bytes(cert)
        print(f"certificate for {', '.join(hosts)} written to {cert_path} (key: {key_path})")
        print(f"SHA-256 fingerprint {fingerprint(cert)}")
        print("Turn HTTPS on in the configuration:")
        print(f"  ui:\n    tls_cert: {cert_path}\n    tls_key: {key_path}")
        print(f"then open https://{hosts[0]}:{config.ui.port}/ on each device and accept the certificate once "
              "(check the fingerprint), or install cert.pem as trusted on it.")
        return 0
