"""Everything that touches the outside world: CAN, motors, sensors, the simulator, the host."""
