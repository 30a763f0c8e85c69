"""The command line's parser and the argument types every subcommand shares.

`Parser` is argparse's, with two changes that users of a robot's command line expect:

* A value that starts with a minus sign and a digit is a value, not an option: ``--start -1.625,0.8,2``
  works as well as ``--start=-1.625,0.8,2``. ROS maps put their origin anywhere, so half of a map's poses
  have negative coordinates. Plain argparse takes only bare negative numbers (``-1.5``) for values and
  calls ``-1.625,0.8,2`` an unknown option. No ATEMR option is spelt like a negative number, so nothing is
  lost.
* An error is one line, ``atemr mission run: error: argument --goal: ...``, with a pointer to ``--help``,
  instead of the usage block followed by the error.

`pose_argument` and `kidnap_argument` read poses, so every command that takes one says the same thing
about a bad one.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from typing import TYPE_CHECKING, Any, NoReturn

if TYPE_CHECKING:  # numpy comes with it: only a command that reads a pose pays for it
    from atemr.msgs import Pose2D

#: A token that starts like a negative number (``-1``, ``-.5``, ``-1.625,0.8,2``) is a value.
NEGATIVE_VALUE = re.compile(r"^-\.?\d")

POSE_FORM = "X,Y,YAW (metres, metres, radians; e.g. -1.6,0.8,2.0)"


class Parser(argparse.ArgumentParser):
    """argparse's parser that takes negative values after an option and reports errors in one line."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse decides "option or value?" with this pattern (bare negative numbers only); sub-parsers
        # are built with the parent's class, so every subcommand gets the wider one.
        self._negative_number_matcher = NEGATIVE_VALUE

    def error(self, message: str) -> NoReturn:
        """One line naming the command and what is wrong, then exit 2 (argparse's code for usage errors)."""
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")

    def exit(self, status: int = 0, message: str | None = None) -> NoReturn:
        if message:
            sys.stderr.write(message)
        sys.exit(status)


def pose_argument(text: str) -> Pose2D:
    """``"X,Y,YAW"`` (metres, metres, radians) → `Pose2D`; argparse names the option in its error."""
    from atemr.msgs import Pose2D

    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected {POSE_FORM}: three finite numbers, got {text!r}")
    return Pose2D(*values)


def kidnap_argument(text: str) -> tuple[float, Pose2D]:
    """``"T,X,Y,YAW"`` → (robot seconds after the start, pose); argparse names the option in its error."""
    when, _, pose = text.partition(",")
    try:
        t = float(when)
    except ValueError:
        t = math.nan
    if not (math.isfinite(t) and t >= 0):
        raise argparse.ArgumentTypeError(f"expected T,X,Y,YAW with T >= 0 robot seconds, got {text!r}")
    try:
        return t, pose_argument(pose)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected T,X,Y,YAW: T >= 0 robot seconds, then {POSE_FORM}, got {text!r}") from None
