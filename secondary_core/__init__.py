"""Emulator of the ESP32 secondary core: power, heartbeat, IR sensors, screens and WiFi portal."""
