"""The built-in simulator: worlds, base physics and sensors, run by the scheduler from one clock.

Modules, one job each:

* `maps` — ROS map_server maps (YAML + PGM/PNG) to `atemr.domain.maps.OccupancyMap` and back (`load_map`,
  `save_map`);
* `world` — world files: map + furniture, drop zones, moving obstacles, start pose (`load_world`);
* `scene` — what is really there, cell by cell: walls, furniture, dropped obstacles, drop depths;
* `raycast` — exact grid traversal (`GridCaster`, a compiled walk) and ray-circle intersection;
* `movers` — people walking paths, pets wandering;
* `base` — differential-drive physics on two `WheelMotor`s, slip, odometry noise, collisions;
* `lidar`, `imu`, `cliff`, `camera` — the sensors;
* `simulation` — `build_simulation(world, seed)` → `Simulation`, whose components a `Scheduler` ticks.

Nothing is imported here, so ``from atemr.io.sim.maps import load_map`` stays light.
"""
