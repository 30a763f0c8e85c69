"""The ESP32 secondary core as a program of its own (``atemr-secondary``, `secondary_core.cli`) and the
link test bench (`secondary_core.harness`).

The board itself (power, heartbeat, IR sensors, screens and WiFi portal) is `atemr.io.secondary_emulator`,
which the simulator also runs. This package depends on `atemr`, never the reverse.
"""
