"""Behaviour trees of the agent: YAML → py_trees builder, leaves, the Monitor and missions.

- `atemr.trees.ports`: the `RobotPort` and `LinkPort` protocols, the agent's only doors to the robot;
- `atemr.trees.behaviours`: the behaviour registry and the `Leaf` base; `atemr.trees.leaves`: the leaves;
- `atemr.trees.nodes`/`atemr.trees.builder`: composites and decorators by name, validation and building;
- `atemr.trees.missions`: mission files → trees; `atemr.trees.progress`: what Exec reports;
- `atemr.trees.fakes`: recording ports for tests; the real ports' adapters are the robot's (`atemr.robot.port`,
  `atemr.robot.navigator_port`).

This package is the agent's lower layer: it never imports `atemr.fsm`, which builds the lifecycle machine
on top of it (and draws both, `atemr.fsm.export`).
"""
