"""The drive motors: MyActuator RMD-L-7015 codec, a pure motor model, its CAN emulator and the driver."""
