"""The domain layer: pure types that several layers share, and nothing that does I/O.

A type lands here when code on both sides of a layer boundary needs it: a skill and the simulator both
use the occupancy grid, the agent and the CAN codec both speak the lifecycle state codes. Modules here
import only the base modules (`atemr.errors`, `atemr.msgs`, ...), numpy and the standard library, so any
layer may import them (see ``tests/test_layers.py``). Nothing is imported here, so importing one module
stays light.

* `maps` — `OccupancyMap`, the occupancy grid, and its cell values;
* `status` — what the robot reports about itself: lifecycle state codes, sub-module and hardware bits,
  the power handshake, a component's health.
"""
