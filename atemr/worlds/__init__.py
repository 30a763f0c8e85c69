"""Worlds shipped with the package (``atemr/worlds/<name>/world.yaml`` + its map), loaded by name.

See `atemr.io.sim.world` for the world file format and `atemr.worlds.make_studio` for how the default
world's map is generated.
"""
