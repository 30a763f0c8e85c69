"""The DBC file shipped with the package: the whole bus (inter-core protocol and RMD motors) for CAN tools.

cantools, SavvyCAN, Vector tools and ``candump | cantools decode`` read it to decode a capture of this
robot's bus. The codec in `atemr.io.can.protocol` is the authority; a test decodes codec output with
this file and checks the values agree.
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
