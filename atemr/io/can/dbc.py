"""The DBC file shipped with the package: the whole bus (inter-core protocol and RMD motors) for CAN tools.

cantools, SavvyCAN, Vector tools and ``candump | cantools decode`` read it to decode a capture of this
robot's bus. The codecs in `atemr.io.can.protocol` and `atemr.io.motors.rmd_protocol` are the authority;
a test decodes codec output with this file and checks the values agree.

The motors appear in both protocol versions the RMD-L ships with: ``RMD_MOTOR_1``/``_2`` (0x141/0x142)
describe MyActuator's protocol V1.61, whose requests and replies share that ID, and ``RMD_V4_REPLY_1``/``_2``
(0x241/0x242) the replies of protocol V4.2, whose requests keep the V1.61 layout on 0x141/0x142. Which one a
capture holds follows the robot's ``devices.motors.protocol`` setting (``atemr can decode --protocol``).
"""

from __future__ import annotations

from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

#: Name of the DBC resource inside the ``atemr.io.can`` package.
DBC_NAME = "atemr.dbc"


def dbc_text() -> str:
    """The DBC file's text."""
    return files("atemr.io.can").joinpath(DBC_NAME).read_text(encoding="utf-8")


def dbc_path() -> Path:
    """A filesystem path to the shipped DBC (the package is installed as plain files)."""
    with as_file(files("atemr.io.can").joinpath(DBC_NAME)) as path:
        return Path(path)


def load_database() -> Any:
    """The DBC as a ``cantools.database.can.Database`` (cantools is imported only here)."""
    import cantools

    return cantools.database.load_string(dbc_text(), database_format="dbc")
