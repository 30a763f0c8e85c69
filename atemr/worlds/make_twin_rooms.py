"""Generate the map of the ``twin_rooms`` world: ``python -m atemr.worlds.make_twin_rooms [--out DIR]``.

Two identical furnished rooms joined by a doorway, laid out point-symmetrically: turned half a turn about the
middle of the doorway, the flat is itself, cell for cell. Whatever the robot sees standing in one room, it
would see the same at the matching pose in the other, so no scan can say which room it is in. The world that
shows global localization answering "ambiguous" (both rooms, as candidates) instead of guessing
(`tests/skills/localization/test_global_search.py`). The output is a pure function of this file and
``twin_rooms/world.yaml`` (`tests/io/sim/test_world.py` checks the shipped map is up to date).
"""

from __future__ import annotations

from pathlib import Path

from atemr.io.sim.maps import OccupancyMap
from atemr.msgs import Pose2D
from atemr.worlds.make_studio import rasterize, write_map

HERE = Path(__file__).resolve().parent / "twin_rooms"
ORIGIN = Pose2D(-0.5, -0.5, 0.0)
SIZE_CELLS = (90, 183)  # rows (y), cols (x): 4.5 m x 9.15 m, centred on the doorway (4.075, 1.75)
#: Interior of both rooms (x 0..4 and 4.15..8.15, y 0..3.5) and the doorway between them.
FLOOR = [(0.0, 0.0, 8.15, 3.5)]
#: Walls, 15 cm thick; the partition at x 4.0..4.15 has the 0.8 m doorway at y 1.35..2.15.
WALLS = [
    (-0.15, -0.15, 8.3, 0.0), (-0.15, 3.5, 8.3, 3.65), (-0.15, -0.15, 0.0, 3.65), (8.15, -0.15, 8.3, 3.65),
    (4.0, 0.0, 4.15, 1.35), (4.0, 2.15, 4.15, 3.5),
]


def build_twin_rooms_map(world_file: Path = HERE / "world.yaml") -> OccupancyMap:
    """The twin rooms' occupancy grid from the walls above and the mapped furniture of the world file."""
    return rasterize("twin_rooms", SIZE_CELLS, ORIGIN, floor=FLOOR, walls=WALLS, world_file=world_file)


def main(argv: list[str] | None = None) -> int:
    return write_map(argv, __doc__.splitlines()[0], build_twin_rooms_map, HERE)


if __name__ == "__main__":
    raise SystemExit(main())
