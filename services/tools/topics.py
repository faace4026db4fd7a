"""`hamnet topics`: every key expression of the contract with its message type and publisher,
or (`--graph`) the whole stack as a Mermaid diagram (`hamnet.tools.graph`).

    hamnet topics --graph                                 # print the diagram
    hamnet topics --graph --output docs/architecture.md   # refresh the doc's diagram block
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from hamnet.runtime.cli import parse
from hamnet.runtime.contract import TOPICS
from hamnet.runtime.errors import ConfigError
from hamnet.tools.graph import diagram, with_block


@dataclass(frozen=True)
class TopicsConfig:
    """List the topic contract."""

    json: bool = False
    """Print one JSON array instead of a table."""
    graph: bool = False
    """Print the stack as a Mermaid diagram (flowchart LR): the processes as nodes, the
    topics between them as labelled edges; GitHub draws it in a ```mermaid block."""
    output: Path | None = None
    """With --graph: write the diagram to this file instead of printing it. A .md file
    keeps its text; only the block between its two `hamnet topics --graph` marker lines
    is replaced (docs/architecture.md)."""

    def __post_init__(self) -> None:
        if self.graph and self.json:
            raise ConfigError("--graph and --json are two outputs: give one")
        if self.output is not None and not self.graph:
            raise ConfigError("--output writes the diagram: give --graph too")


def rows() -> list[dict[str, str | bool]]:
    """The contract as plain records."""
    return [
        {
            "key": t.template,
            "type": t.type_name,
            "publisher": t.publisher,
            "when": t.when,
            "finite": t.finite,
        }
        for t in TOPICS
    ]


CONFIG = TopicsConfig
"""The config `hamnet topics` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet topics` with command-line arguments `argv`; returns the exit status."""
    config = parse(CONFIG, argv, "hamnet topics", __doc__)
    if config.graph:
        return write_graph(config.output)
    table = rows()
    if config.json:
        print(json.dumps(table, indent=2))
        return 0
    columns = ("key", "type", "publisher", "when")
    widths = {c: max(len(c), *(len(str(r[c])) for r in table)) for c in columns}
    print("  ".join(c.upper().ljust(widths[c]) for c in columns))
    for row in table:
        print("  ".join(str(row[c]).ljust(widths[c]) for c in columns))
    return 0


def write_graph(output: Path | None) -> int:
    """Print the diagram, or write it to `output` (into the marked block of a .md file)."""
    text = diagram()
    if output is None:
        print(text, end="")
        return 0
    if output.suffix == ".md":
        try:
            text = with_block(output.read_text(), text)
        except (OSError, ValueError) as error:
            raise ConfigError(f"{output}: {error}") from None
    output.write_text(text)
    print(f"wrote {output}")
    return 0
