"""The stack as one picture, generated from the topic contract (`hamnet.runtime.contract`):
the processes as nodes and the topics between them as labelled edges, in Mermaid
`flowchart LR` text, which GitHub draws inside a markdown ```mermaid block.

`hamnet topics --graph` prints it or writes it into the marked block of
docs/architecture.md (`with_block`); a test keeps that block equal to `diagram()`, so the
picture cannot drift from the contract. The output is sorted: the same contract always
gives the same text.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from hamnet.runtime.contract import OBSERVERS, SERVICES, TOPICS, Topic

EVERY_SERVICE = "every service"
"""The node that stands for all of SERVICES: the publisher of the per-service topics
(`health/<service>/<w>`, `alive/<service>/<w>`), drawn once instead of once per service."""

EVERY_TOPIC = "every topic"
"""The label of an observer's one edge: observers read every key, so one edge each keeps
them from doubling the picture's edges."""

BEGIN = "<!-- BEGIN hamnet topics --graph -->"
"""The line after which a markdown file holds the generated diagram."""
END = "<!-- END hamnet topics --graph -->"
"""The line before which the generated diagram ends."""

_PLACEHOLDER = re.compile(r"<\w+>")


@dataclass(frozen=True, order=True)
class Edge:
    """One arrow of the picture: every topic `publisher` sends and `reader` takes."""

    publisher: str
    """Identity that publishes (serves a queryable, declares a liveliness token)."""
    reader: str
    """Identity that subscribes (asks the queryable, watches the token)."""
    dotted: bool
    """Queryables and liveliness tokens, which carry no stream of messages."""
    labels: tuple[str, ...]
    """Topic paths, sorted, placeholders written as Zenoh's `*`: `sim/*/state`."""


def label(topic: Topic) -> str:
    """The topic's path as a key expression: `sim/<w>/state` -> `sim/*/state`.

    Mermaid reads `<w>` in a label as HTML; `*` needs no escaping and is what Zenoh's key
    expressions (`hamnet echo`) take."""
    return _PLACEHOLDER.sub("*", topic.path)


def edges(topics: Iterable[Topic] = TOPICS, observers: Sequence[str] = OBSERVERS) -> list[Edge]:
    """One edge per (publisher, reader, kind) with every topic between them, sorted.

    Args:
        topics: contract entries; each publisher gets an edge to each reader.
        observers: identities that read every key; they get one `EVERY_TOPIC` edge each
            from `EVERY_SERVICE` instead of one per topic.
    Returns:
        The edges, sorted by publisher, reader, then solid before dotted.
    """
    grouped: dict[tuple[str, str, bool], set[str]] = defaultdict(set)
    watched: set[str] = set()
    for topic in topics:
        per_service = "service" in topic.placeholders
        publishers = (EVERY_SERVICE,) if per_service else topic.publishers
        for reader in topic.readers:
            if reader in observers:
                watched.add(reader)
                continue
            for publisher in publishers:
                grouped[publisher, reader, topic.message is None].add(label(topic))
    for observer in watched:
        grouped[EVERY_SERVICE, observer, False].add(EVERY_TOPIC)
    return sorted(Edge(p, r, d, tuple(sorted(ls))) for (p, r, d), ls in grouped.items())


def node_id(identity: str) -> str:
    """A Mermaid node id for an identity: `every service` -> `every_service`."""
    return re.sub(r"\W", "_", identity)


def _node(identity: str, services: Sequence[str]) -> str:
    """A node line: processes are boxes, everything else (the operator, every service) is
    rounded."""
    if identity in services:
        return f'{node_id(identity)}["{identity}"]'
    return f'{node_id(identity)}(["{identity}"])'


def _arrow(edge: Edge) -> str:
    """An edge line; several topics share one label, one per line."""
    arrow = "-.->" if edge.dotted else "-->"
    text = "<br/>".join(edge.labels)
    return f'{node_id(edge.publisher)} {arrow}|"{text}"| {node_id(edge.reader)}'


def diagram(
    topics: Iterable[Topic] = TOPICS,
    services: Sequence[str] = SERVICES,
    observers: Sequence[str] = OBSERVERS,
) -> str:
    """The Mermaid text of the stack, ending with a newline.

    Args:
        topics: contract entries to draw (default: the whole contract).
        services: identities that run as processes; each is a node even when no topic
            links it (the router, replay).
        observers: identities that read every key (`edges`).
    Returns:
        `flowchart LR`, then the nodes sorted by id, then the edges sorted (`edges`).
    """
    drawn = edges(topics, observers)
    identities = set(services) | {e.publisher for e in drawn} | {e.reader for e in drawn}
    lines = ["flowchart LR"]
    lines += [f"    {_node(i, services)}" for i in sorted(identities, key=node_id)]
    lines += [f"    {_arrow(e)}" for e in drawn]
    return "\n".join(lines) + "\n"


def fenced(text: str) -> str:
    """`text` as a markdown ```mermaid block, ending with a newline."""
    return f"```mermaid\n{text}```\n"


def block_in(markdown: str) -> str:
    """What lies between the BEGIN and END marker lines of `markdown`.

    Raises:
        ValueError: the markers are missing, repeated or out of order.
    """
    _, inside, _ = _split(markdown)
    return inside


def with_block(markdown: str, text: str) -> str:
    """`markdown` with the part between its markers replaced by `text` as a fenced block."""
    before, _, after = _split(markdown)
    return before + fenced(text) + after


def _split(markdown: str) -> tuple[str, str, str]:
    """(up to and including the BEGIN line, between the markers, from the END line on)."""
    start, stop = markdown.find(BEGIN + "\n"), markdown.find(END)
    if markdown.count(BEGIN) != 1 or markdown.count(END) != 1 or not 0 <= start < stop:
        raise ValueError(f"needs one line {BEGIN!r}, then one line {END!r}")
    cut = start + len(BEGIN) + 1
    return markdown[:cut], markdown[cut:stop], markdown[stop:]
