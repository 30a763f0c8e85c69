"""The agent's leaves; importing this package registers every one in `atemr.trees.behaviours.behaviours`."""

from atemr.trees.leaves import checks, media, monitor, motion, navigation, power, timing

__all__ = ["checks", "media", "monitor", "motion", "navigation", "power", "timing"]
