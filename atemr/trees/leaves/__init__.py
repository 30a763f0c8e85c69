"""The agent's leaves; importing this package registers every one in `atemr.trees.behaviours.behaviours`."""

from atemr.trees.leaves import checks, mapping, media, monitor, motion, navigation, power, timing

__all__ = ["checks", "mapping", "media", "monitor", "motion", "navigation", "power", "timing"]
