"""Logging set-up for the command line: one handler on the root logger, one logger per module."""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Iterator

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


@contextlib.contextmanager
def quieted(*names: str, level: int = logging.ERROR) -> Iterator[None]:
    """Raise the loggers ``names`` to ``level`` for the duration, then restore them: a benchmark's table
    would drown in scheduler overruns and a web server's complaints, which its figures already say."""
    loggers = [logging.getLogger(name) for name in names]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(level)
    try:
        yield
    finally:
        for lg, old in zip(loggers, levels, strict=True):
            lg.setLevel(old)
