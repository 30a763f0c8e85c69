"""ATEMR: the software of an autonomous telepresence robot for assistive care at home."""

__version__ = "0.1.0"
