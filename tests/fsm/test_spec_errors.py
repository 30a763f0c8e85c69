"""Every kind of error in an agent document is a ConfigError with file, line, column and YAML path.

Each case edits a small valid document; the expected position is where the offending text starts
(found in the document, so the test says exactly which token the message must point at).
"""

from __future__ import annotations

import pytest

from atemr.errors import ConfigError
from atemr.fsm.spec import AgentSpec, parse_agent
from atemr.yamlsafe import load_yaml

VALID = """\
version: 1
initial: STARTUP
states:
  - name: STARTUP
    on_success: startup_ok
    tree:
      type: Sequence
      children:
        - {type: Wait, params: {duration_s: 1}}
  - name: IDLE
    initial: MANUAL
    children:
      - name: MANUAL
      - name: AUTO
  - name: SHUTDOWN
transitions:
  - {trigger: startup_ok, source: STARTUP, dest: IDLE}
  - {trigger: set_auto, source: IDLE.MANUAL, dest: IDLE.AUTO, conditions: level1_ok}
  - {trigger: shutdown, source: IDLE, dest: SHUTDOWN, before: stop_motors}
monitor:
  type: Parallel
  children:
    - {type: PublishStatus}
"""


def parse(text: str) -> AgentSpec:
    return parse_agent(load_yaml("agent.yaml", text=text), "agent.yaml")


def position(text: str, needle: str, nth: int = 0) -> tuple[int, int]:
    """1-based line and column of the ``nth`` occurrence of ``needle``."""
    index = -1
    for _ in range(nth + 1):
        index = text.index(needle, index + 1)
    line = text.count("\n", 0, index) + 1
    column = index - (text.rfind("\n", 0, index) + 1) + 1
    return line, column


def test_the_valid_document_parses() -> None:
    spec = parse(VALID)
    assert spec.leaves() == ["STARTUP", "IDLE.MANUAL", "IDLE.AUTO", "SHUTDOWN"]
    assert spec.leaf_of("IDLE") == "IDLE.MANUAL"


# (edit: old -> new, the text the error must point at, words the message must contain, path)
CASES = [
    ("unknown top key", ("version: 1", "version: 1\nverison: 2"), "verison", ["unknown key 'verison'"], "verison"),
    ("unknown state key", ("  - name: SHUTDOWN", "  - name: SHUTDOWN\n    on_enterr: []"), "on_enterr",
     ["unknown key 'on_enterr'", "on_enter"], "states[2].on_enterr"),
    ("unknown transition key", ("dest: IDLE}", "dest: IDLE, guard: x}"), "guard",
     ["unknown key 'guard'"], "transitions[0].guard"),
    ("wrong type", ("duration_s: 1}", "duration_s: soon}"), "soon", ["expected a number"],
     "states[0].tree.children[0].params.duration_s"),
    ("unknown behaviour", ("{type: Wait,", "{type: Wiat,"), "Wiat", ["unknown node type 'Wiat'", "'Wait'"],
     "states[0].tree.children[0].type"),
    ("bad parameter", ("duration_s: 1}", "duration_s: -1}"), "-1", ["must be at least 0"],
     "states[0].tree.children[0].params.duration_s"),
    ("missing parameter", ("{type: Wait, params: {duration_s: 1}}", "{type: Wait}"), "{type: Wait}",
     ["missing required parameter: duration_s"], "states[0].tree.children[0].params"),
    ("unknown leaf param", ("duration_s: 1}", "duration_s: 1, seconds: 2}"), "seconds",
     ["unknown key 'seconds'"], "states[0].tree.children[0].params.seconds"),
    ("transition to a missing state", ("dest: SHUTDOWN,", "dest: SHUTDOWM,"), "SHUTDOWM",
     ["transition to a missing state", "'SHUTDOWN'"], "transitions[2].dest"),
    ("missing source state", ("source: IDLE.MANUAL", "source: IDLE.MANUEL"), "IDLE.MANUEL",
     ["unknown source state 'IDLE.MANUEL'", "'IDLE.MANUAL'"], "transitions[1].source"),
    ("unreachable state", ("  - name: SHUTDOWN\n", "  - name: SHUTDOWN\n  - name: ERROR\n"), "name: ERROR",
     ["state 'ERROR' is unreachable"], "states[3]"),
    ("unknown guard", ("conditions: level1_ok", "conditions: level_ok"), "level_ok",
     ["unknown guards 'level_ok'", "'level1_ok'"], "transitions[1].conditions"),
    ("unknown callback", ("before: stop_motors", "before: [stop_motor]"), "stop_motor]",
     ["unknown callbacks 'stop_motor'"], "transitions[2].before"),
    ("duplicate state", ("      - name: AUTO", "      - name: MANUAL"), "MANUAL\n  - name: SHUTDOWN",
     ["declared twice"], "states[1].children[1].name"),
    ("bad nested initial", ("initial: MANUAL", "initial: MANUL"), "MANUL", ["unknown child of IDLE 'MANUL'"],
     "states[1].initial"),
    ("outcome trigger without transition", ("on_success: startup_ok", "on_success: started"), "name: STARTUP",
     ["on_success trigger 'started' has no transition out of STARTUP"], "states[0]"),
    ("state without a code", ("  - name: SHUTDOWN\n", "  - name: SHUTDOWN\n  - name: DOCKING\n"), "name: DOCKING",
     ["'DOCKING' has no CAN 0x153 state code"], "states[3]"),
    ("Task in the monitor", ("    - {type: PublishStatus}", "    - {type: Task}"), "Task",
     ["'Task' may only appear in a state's tree"], "monitor.children[0].type"),
    ("composite without children", ("      type: Sequence\n      children:\n        - {type: Wait, params: "
                                    "{duration_s: 1}}", "      type: Sequence"), "type: Sequence",
     ["Sequence needs 'children'"], "states[0].tree.children"),
    ("wrong option type", ("  type: Parallel", "  type: Parallel\n  policy: most"), "most",
     ["expected one of 'all', 'one'"], "monitor.policy"),
]


@pytest.mark.parametrize(("kind", "edit", "at", "words", "path"), CASES, ids=[c[0] for c in CASES])
def test_error_names_file_line_column_and_path(kind: str, edit: tuple[str, str], at: str, words: list[str],
                                               path: str) -> None:
    old, new = edit
    assert old in VALID, kind
    text = VALID.replace(old, new, 1)
    with pytest.raises(ConfigError) as info:
        parse(text)
    error = info.value
    assert (error.file, error.line, error.column) == ("agent.yaml", *position(text, at)), str(error)
    assert error.path == path, str(error)
    for word in words:
        assert word in error.reason, str(error)
    assert str(error).startswith(f"agent.yaml:{error.line}:{error.column} {path}: ")


def test_yaml_level_errors_keep_their_position() -> None:
    text = VALID.replace("initial: STARTUP", "initial: STARTUP\ninitial: IDLE")
    with pytest.raises(ConfigError) as info:
        parse(text)
    assert "duplicate key 'initial'" in str(info.value) and info.value.line == 3


def test_the_shipped_agent_document_is_valid(agent_spec: AgentSpec) -> None:
    assert {s.split(".")[0] for s in agent_spec.leaves()} == {"STARTUP", "IDLE", "EXEC", "MAPPING", "ERROR",
                                                              "SHUTDOWN"}
    assert agent_spec.tree_state("IDLE.AUTO") is agent_spec.states["IDLE.AUTO"]
    assert agent_spec.monitor is not None
