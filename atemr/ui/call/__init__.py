"""The two-way call between an operator's browser and the robot's screen: the signalling state machine
(`atemr.ui.call.machine`, pure) and its Socket.IO events (`atemr.ui.call.events`)."""
