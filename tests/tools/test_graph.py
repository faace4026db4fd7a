"""`hamnet topics --graph`: the diagram of the stack generated from the topic contract, and
the copy of it in docs/architecture.md, which must not go stale."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from hamnet.runtime.contract import Topic
from hamnet.runtime.errors import ConfigError
from hamnet.tools import topics
from hamnet.tools.graph import (
    BEGIN,
    END,
    EVERY_SERVICE,
    EVERY_TOPIC,
    Edge,
    block_in,
    diagram,
    edges,
    fenced,
    with_block,
)

ROOT = Path(__file__).resolve().parents[2]
ARCHITECTURE = ROOT / "docs" / "architecture.md"


def test_the_committed_diagram_is_the_contract() -> None:
    """The picture in docs/architecture.md is the contract's: a topic, publisher or reader
    added to `hamnet.runtime.contract` without `hamnet topics --graph --output
    docs/architecture.md` leaves the committed block different from the generated one."""
    assert block_in(ARCHITECTURE.read_text()) == fenced(diagram())


def test_a_topic_with_two_publishers_gives_an_edge_from_each() -> None:
    state = Topic("sim/<w>/state", None, ("sim", "bridge"), ("policy",), "every step")
    assert edges([state], observers=()) == [
        Edge("bridge", "policy", True, ("sim/*/state",)),
        Edge("sim", "policy", True, ("sim/*/state",)),
    ]


def test_topics_between_the_same_two_processes_share_one_sorted_label() -> None:
    scene = Topic("sim/<w>/scene", None, ("sim",), ("policy",), "at resets")
    state = Topic("sim/<w>/state", None, ("sim",), ("policy",), "every step")
    (edge,) = edges([state, scene], observers=())
    assert edge.labels == ("sim/*/scene", "sim/*/state")
    assert '"sim/*/scene<br/>sim/*/state"' in diagram([state, scene], services=(), observers=())


def test_observers_get_one_edge_and_per_service_topics_one_publisher() -> None:
    """Observers read every key and every service reports health: drawn per topic and per
    service they would triple the edges, so each is one edge from `every service`."""
    health = Topic("health/<service>/<w>", None, ("sim", "policy"), ("up", "echo"), "1 Hz")
    action = Topic("policy/<w>/action", None, ("policy",), ("safety", "echo"), "every step")
    assert edges([health, action], observers=("echo",)) == [
        Edge(EVERY_SERVICE, "echo", False, (EVERY_TOPIC,)),
        Edge(EVERY_SERVICE, "up", True, ("health/*/*",)),
        Edge("policy", "safety", True, ("policy/*/action",)),
    ]


def test_message_topics_are_solid_and_queryables_dotted() -> None:
    from hamnet.proto import policy_pb2

    action = Topic("policy/<w>/action", policy_pb2.PolicyAction, ("policy",), ("safety",), "")
    estop = Topic("safety/<w>/estop", None, ("safety",), ("operator",), "", queryable=True)
    text = diagram([action, estop], services=("policy", "safety"), observers=())
    assert 'policy -->|"policy/*/action"| safety' in text
    assert 'safety -.->|"safety/*/estop"| operator' in text
    assert 'operator(["operator"])' in text and 'safety["safety"]' in text


def test_the_diagram_lists_every_process_even_without_topics() -> None:
    text = diagram([], services=("router", "sim"), observers=())
    assert text == 'flowchart LR\n    router["router"]\n    sim["sim"]\n'


def test_the_block_is_replaced_between_its_markers_only() -> None:
    page = f"# Title\n\n{BEGIN}\nold\n{END}\n\nafter\n"
    updated = with_block(page, "flowchart LR\n")
    assert updated == f"# Title\n\n{BEGIN}\n```mermaid\nflowchart LR\n```\n{END}\n\nafter\n"
    assert block_in(updated) == fenced("flowchart LR\n")
    with pytest.raises(ValueError, match="needs one line"):
        block_in(f"{END}\n{BEGIN}\n")
    with pytest.raises(ValueError, match="needs one line"):
        block_in("no markers")


def test_graph_prints_or_writes_the_diagram(tmp_path, capsys) -> None:
    assert topics.main(["--graph"]) == 0
    assert capsys.readouterr().out == diagram()
    mmd = tmp_path / "stack.mmd"
    assert topics.main(["--graph", "--output", str(mmd)]) == 0
    assert mmd.read_text() == diagram()
    page = tmp_path / "page.md"
    page.write_text(f"intro\n{BEGIN}\n{END}\noutro\n")
    assert topics.main(["--graph", "--output", str(page)]) == 0
    assert page.read_text() == f"intro\n{BEGIN}\n{fenced(diagram())}{END}\noutro\n"


def test_graph_refuses_a_markdown_file_without_markers_and_output_without_graph(
    tmp_path, capsys
) -> None:
    page = tmp_path / "page.md"
    page.write_text("no markers\n")
    with pytest.raises(ConfigError, match="needs one line"):
        topics.main(["--graph", "--output", str(page)])
    assert page.read_text() == "no markers\n"
    with pytest.raises(SystemExit) as refused:
        topics.main(["--output", str(tmp_path / "x.mmd")])
    assert refused.value.code == 2
    assert "--output writes the diagram: give --graph too" in capsys.readouterr().err
    assert not (tmp_path / "x.mmd").exists()


def test_every_path_in_where_is_x_exists() -> None:
    """The "Where is X" table of docs/architecture.md names files and folders that exist: a
    file moved or renamed without the table fails here."""
    section = ARCHITECTURE.read_text().split("## Where is X", 1)[1]
    paths = re.findall(r"`([\w./*-]+/[\w./*-]*)`", section)
    assert len(paths) >= 12
    missing = [p for p in paths if not list(ROOT.glob(p.rstrip("/")))]
    assert not missing, f"docs/architecture.md names paths that do not exist: {missing}"
