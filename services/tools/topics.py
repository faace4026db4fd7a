"""`hamnet topics`: every key expression of the contract with its message type and publisher."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass

from hamnet.runtime.cli import parse
from hamnet.runtime.contract import TOPICS


@dataclass(frozen=True)
class TopicsConfig:
    """List the topic contract."""

    json: bool = False
    """Print one JSON array instead of a table."""


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
