"""The agent: its lifecycle machine (transitions' HierarchicalMachine) built from ``trees/agent.yaml``.

- `atemr.fsm.spec`: the agent document → validated `AgentSpec` (states, transitions, trees, Monitor);
- `atemr.fsm.guards`: the guard and callback registries the document names;
- `atemr.fsm.machine`: `Lifecycle` (fire a trigger, never raise; the trace) and `replay`;
- `atemr.fsm.agent`: `Agent`, the scheduler component (machine + state tree + Monitor, commands, snapshot);
- `atemr.fsm.mission_run`: run one mission on an agent to its end with a JSON result;
- `atemr.fsm.autonomy`: operator autonomy levels: which transitions wait for the operator's confirmation;
- `atemr.fsm.reload`: hot reload at a safe boundary (IDLE for the document, between steps for a mission);
- `atemr.fsm.export`: the machine and its trees drawn as ASCII, Mermaid, JSON, DOT, SVG or PNG.

State names and their CAN 0x153 codes (`state_code`, `top_level`) are domain values, `atemr.domain.status`.
"""
