"""Logging set-up for the command line: one handler on the root logger, one logger per module."""

from __future__ import annotations

import logging
import sys

FORMAT = "%(asctime)s %(levelname)-7s %(name)s: %(message)s"


def configure_logging(level: str = "INFO") -> None:
    """Send every ``atemr`` logger to stderr at ``level``; safe to call more than once."""
    root = logging.getLogger()
    for handler in list(root.handlers):
        if getattr(handler, "_atemr", False):
            root.removeHandler(handler)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(FORMAT, datefmt="%H:%M:%S"))
    handler._atemr = True  # type: ignore[attr-defined]
    root.addHandler(handler)
    root.setLevel(level.upper())
    # transitions logs every callback at INFO: that is library tracing, not robot events.
    logging.getLogger("transitions").setLevel(max(logging.WARNING, root.level))
