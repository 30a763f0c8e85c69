"""Emulator of the ESP32 secondary core: power, heartbeat, IR sensors, screens and WiFi portal.

The board (`board.SecondaryCore`) is a scheduler component on its own python-can bus, like the motor
emulators (`atemr.io.motors.emulator`): the simulator runs it beside the primary (`wiring.emulated_secondary`,
called by `atemr.robot.assembly`), and the ``atemr-secondary`` program (`secondary_core.cli`) runs it on its
own. It lives in `atemr` because the simulation needs it, and `atemr` never imports `secondary_core`
(``tests/test_layers.py``): `secondary_core` is the program around it and its test bench, built on `atemr`.

Nothing is imported here, so importing the board does not start Flask (the portal's).
"""
