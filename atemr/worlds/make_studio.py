"""Generate the map of the default ``studio`` world: ``python -m atemr.worlds.make_studio [--out DIR]``.

The map is what mapping the apartment with the lidar would give: the walls below plus the furniture marked
``mapped: true`` in ``studio/world.yaml`` where it crosses the lidar's plane (`LidarParams.height_m`): the
dining table's four legs, not the footprint of its top at 0.70 m, which the lidar scans under (as a map made
by SLAM shows it; a map that drew the top would disagree with every scan through the table and pull the
localized pose). At 5 cm per cell, written in the ROS map_server format
(``studio.pgm`` + ``studio.yaml``). The output is a pure function of this file and the world file, so
the shipped map can be checked for being up to date (``tests/io/sim/test_worlds.py``).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np

from atemr.domain.maps import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from atemr.io.sim.lidar import LidarParams
from atemr.io.sim.maps import save_map
from atemr.msgs import Pose2D
from atemr.yamlsafe import load_yaml

HERE = Path(__file__).resolve().parent / "studio"
RESOLUTION_M = 0.05
ORIGIN = Pose2D(-0.5, -2.0, 0.0)
SIZE_CELLS = (190, 200)  # rows (y), cols (x): 9.5 m x 10 m

#: Floor the robot can reach: the apartment's interior and the balcony, [x0, y0, x1, y1] in metres.
FLOOR = [
    (0.0, 0.0, 9.0, 7.0),  # the apartment
    (3.2, -1.65, 5.3, 0.0),  # the balcony (its south edge is open: the drop zone of the world file)
]
#: Walls, 15 cm thick; gaps in them are the 0.8 m doorways.
WALLS = [
    # outer walls; the south wall has the balcony door at x 3.85..4.65
    (-0.15, -0.15, 3.85, 0.0), (4.65, -0.15, 9.15, 0.0),
    (-0.15, 7.0, 9.15, 7.15),
    (-0.15, -0.15, 0.0, 7.15),
    (9.0, -0.15, 9.15, 7.15),
    # living room | bedroom and bathroom, doorway y 1.0..1.8 into the bedroom
    (5.5, 0.0, 5.65, 1.0), (5.5, 1.8, 5.65, 7.0),
    # bedroom | bathroom, doorway x 7.6..8.4
    (5.65, 4.5, 7.6, 4.65), (8.4, 4.5, 9.0, 4.65),
    # balcony railings (east and west sides)
    (3.05, -1.65, 3.2, -0.15), (5.3, -1.65, 5.45, -0.15),
]


def _cells(box: tuple[float, float, float, float], xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    x0, y0, x1, y1 = box
    return (xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)


def rasterize(name: str, size_cells: tuple[int, int], origin: Pose2D, *, floor: list[tuple[float, float, float, float]],
              walls: list[tuple[float, float, float, float]], world_file: Path,
              resolution_m: float = RESOLUTION_M) -> OccupancyMap:
    """An occupancy grid from floor and wall boxes ``[x0, y0, x1, y1]`` (m) and the ``mapped: true`` furniture of
    ``world_file`` that crosses the lidar's plane: what mapping the place with the lidar would give (a table's
    legs, not its top; unknown outside the floor)."""
    rows, cols = np.indices(size_cells)
    xs = origin.x_m + (cols + 0.5) * resolution_m
    ys = origin.y_m + (rows + 0.5) * resolution_m
    data = np.full(size_cells, UNKNOWN, dtype=np.int8)
    for box in floor:
        data[_cells(box, xs, ys)] = FREE
    for box in walls:
        data[_cells(box, xs, ys)] = OCCUPIED
    world = load_yaml(world_file)
    lidar_z = LidarParams().height_m
    for item in world.get("furniture", []):
        if not item.get("mapped", False):
            continue
        if not float(item.get("clearance_m", 0.0)) <= lidar_z <= float(item["height_m"]):
            continue  # above the lidar's plane (a table top) or under it: mapping with the lidar cannot see it
        if "box" in item:
            data[_cells(tuple(item["box"]), xs, ys)] = OCCUPIED
        else:
            cx, cy, r = item["circle"]
            data[(xs - cx) ** 2 + (ys - cy) ** 2 <= r * r] = OCCUPIED
    return OccupancyMap(data, resolution_m, origin, name=name)


def build_studio_map(world_file: Path = HERE / "world.yaml") -> OccupancyMap:
    """The studio's occupancy grid from the walls above and the mapped furniture of the world file."""
    return rasterize("studio", SIZE_CELLS, ORIGIN, floor=FLOOR, walls=WALLS, world_file=world_file)


def write_map(argv: list[str] | None, description: str, build: Callable[[], OccupancyMap], here: Path) -> int:
    """The command line of a world's map generator: ``--out DIR`` (default ``here``), write ``<name>.pgm`` and
    ``<name>.yaml`` there."""
    grid = build()
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--out", type=Path, default=here, help=f"directory to write {grid.name}.pgm and .yaml")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    path = save_map(grid, args.out / f"{grid.name}.yaml")
    print(f"wrote {path} and {path.with_suffix('.pgm')}")
    return 0


def main(argv: list[str] | None = None) -> int:
    return write_map(argv, __doc__.splitlines()[0], build_studio_map, HERE)


if __name__ == "__main__":
    raise SystemExit(main())
