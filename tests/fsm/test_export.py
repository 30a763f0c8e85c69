"""Drawing the agent and missions, and the ``atemr tree`` / ``atemr mission`` commands."""

from __future__ import annotations

import json
from pathlib import Path

import pydot
import pytest

from atemr.cli.main import main
from atemr.fsm import export
from atemr.fsm.export import ExportError, drawing_of, exporters
from atemr.fsm.spec import AgentSpec
from atemr.trees.behaviours import behaviours

ROOT = Path(__file__).resolve().parents[2]
AGENT = ROOT / "trees" / "agent.yaml"
MISSIONS = sorted((ROOT / "trees" / "missions").glob("*.yaml"))


def edges(spec: AgentSpec) -> int:
    return sum(len(t.sources) for t in spec.transitions)


def test_ascii_lists_states_transitions_and_trees(agent_spec: AgentSpec) -> None:
    text = exporters.get("ascii")(drawing_of(agent_spec))
    assert isinstance(text, str)
    assert "IDLE.AUTO --goal [not goal_valid]--> ERROR  (before record_error, before remember_task_failed)" in text
    assert "  STARTUP  (code 0x01;" in text and "    MANUAL  (tree 'manual')" in text
    assert "--> left motor (CheckComponent component=left_motor timeout_s=5.0 critical=True)" in text
    assert text.count("\ntree ") == 9  # eight state trees and the monitor


def test_mermaid_machine_has_every_transition(agent_spec: AgentSpec) -> None:
    text = export.mermaid_machine(agent_spec)
    assert text.startswith("stateDiagram-v2\n    [*] --> STARTUP\n")
    assert text.count(" --> ") - text.count("[*] --> ") == edges(agent_spec)
    assert "state IDLE {" in text and "IDLE_AUTO --> ERROR : goal [not goal_valid]" in text
    document = exporters.get("mermaid")(drawing_of(agent_spec))
    assert isinstance(document, str) and document.count("```mermaid") == 10
    single = exporters.get("mermaid")(drawing_of(agent_spec, "EXEC"))
    assert isinstance(single, str) and single.startswith("flowchart TD") and "[task] task" in single


def test_json_round_trips_the_document(agent_spec: AgentSpec) -> None:
    data = json.loads(str(exporters.get("json")(drawing_of(agent_spec))))
    assert len(data["machine"]["transitions"]) == len(agent_spec.transitions)
    assert {s["name"]: s["code"] for s in data["machine"]["states"]}["SHUTDOWN.POWEROFF"] == 5
    assert data["trees"]["STARTUP"]["children"][0]["children"][0]["options"]["component"] == "left_motor"


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # pydot's parser uses old pyparsing names
def test_dot_parses_and_has_an_edge_per_transition(agent_spec: AgentSpec) -> None:
    text = exporters.get("dot")(drawing_of(agent_spec))
    graphs = pydot.graph_from_dot_data(str(text))
    assert graphs and len(graphs) == 1
    machine = graphs[0].get_subgraph("cluster_machine")[0]
    labelled = [e for e in machine.get_edges() if e.get("label")]
    assert len(labelled) == edges(agent_spec)


def test_svg_and_png_need_graphviz(agent_spec: AgentSpec, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(export.shutil, "which", lambda name: None)
    for fmt in ("svg", "png"):
        with pytest.raises(ExportError, match=r"needs Graphviz's 'dot' program.*ascii, mermaid, json and dot work"):
            exporters.get(fmt)(drawing_of(agent_spec))


def test_state_selection_errors(agent_spec: AgentSpec) -> None:
    with pytest.raises(ExportError, match="no state 'IDEL'"):
        drawing_of(agent_spec, "IDEL")
    assert drawing_of(agent_spec, "monitor").trees[0][0] == "monitor"
    assert drawing_of(agent_spec, "IDLE.AUTO").trees[0][1].name == "auto"


def test_cli_tree_validate_and_export(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["tree", "validate", str(AGENT)]) == 0
    assert "OK, agent: 10 states (8 leaf states), 22 transitions" in capsys.readouterr().out
    assert main(["tree", "export", str(AGENT), "--format", "mermaid", "--state", "IDLE.MANUAL"]) == 0
    assert capsys.readouterr().out.startswith("flowchart TD")
    out = tmp_path / "agent.json"
    assert main(["tree", "export", str(AGENT), "-f", "json", "-o", str(out)]) == 0
    assert json.loads(out.read_text())["machine"]["initial"] == "STARTUP"
    assert main(["tree", "export", str(MISSIONS[0]), "-f", "ascii"]) == 0
    assert "tree mission" in capsys.readouterr().out
    bad = tmp_path / "bad.yaml"
    bad.write_text(AGENT.read_text().replace("type: Halt", "type: Hult"))
    assert main(["tree", "validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:" in err and "unknown node type 'Hult' (did you mean 'Halt'?)" in err


def test_cli_mission_validate(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                              monkeypatch: pytest.MonkeyPatch) -> None:
    assert main(["mission", "validate", "--strict", *map(str, MISSIONS)]) == 0
    out = capsys.readouterr().out
    assert out.count(": OK, mission") == len(MISSIONS) and "not runnable" not in out
    monkeypatch.delitem(behaviours._items, "GoToPose")  # a build without navigation's leaf
    patrol = ROOT / "trees" / "missions" / "living-room-patrol.yaml"
    assert main(["mission", "validate", str(patrol)]) == 0
    assert "not runnable in this build: needs GoToPose; steps 0 (patrol, line 10)" in capsys.readouterr().out
    assert main(["mission", "validate", "--strict", str(patrol)]) == 1
    look = ROOT / "trees" / "missions" / "look-around.yaml"
    assert main(["mission", "validate", "--strict", str(look)]) == 0
    capsys.readouterr()
    bad = tmp_path / "bad.yaml"
    bad.write_text("mission:\n  name: x\n  steps:\n    - wait: {duration_s: forever}\n")
    assert main(["mission", "validate", "--json", str(bad)]) == 2
    report = json.loads(capsys.readouterr().out)
    assert report["valid"] is False and (report["line"], report["column"]) == (4, 26)
    assert report["path"] == "mission.steps[0].wait.duration_s"
