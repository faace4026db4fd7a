"""The stack's combined output: every line a child prints, prefixed with its process label
(`sim/0 | ...`) and coloured per process when stdout is a terminal and NO_COLOR is unset.

One thread per child process copies its output (stdout and stderr merged) line by line,
so a chatty service never blocks on a full pipe and lines of two services never mix.
"""

from __future__ import annotations

import os
import threading
from typing import IO, TextIO

_COLOURS = (36, 33, 32, 35, 34, 96, 93, 92, 95, 94)
"""ANSI foreground colours given to processes in turn (red is left to errors)."""


def use_colour(stream: TextIO) -> bool:
    """Colour when `stream` is a terminal and NO_COLOR (no-color.org) is unset or empty."""
    return stream.isatty() and not os.environ.get("NO_COLOR")


class Output:
    """Writes prefixed lines of every process of a stack to one stream."""

    def __init__(self, stream: TextIO, labels: list[str], colour: bool) -> None:
        self._stream = stream
        self._lock = threading.Lock()
        width = max((len(label) for label in labels), default=0)
        self._prefixes = {}
        for index, label in enumerate(labels):
            prefix = f"{label:<{width}} | "
            if colour:
                prefix = f"\033[{_COLOURS[index % len(_COLOURS)]}m{prefix}\033[0m"
            self._prefixes[label] = prefix

    def write(self, label: str, line: str) -> None:
        """Write one line of the process `label`."""
        with self._lock:
            self._stream.write(f"{self._prefixes[label]}{line}\n")
            self._stream.flush()

    def follow(self, label: str, pipe: IO[bytes]) -> threading.Thread:
        """Copy `pipe` to the output until it closes, in a daemon thread (returned, started)."""
        thread = threading.Thread(
            target=self._copy, args=(label, pipe), name=f"output {label}", daemon=True
        )
        thread.start()
        return thread

    def _copy(self, label: str, pipe: IO[bytes]) -> None:
        with pipe:
            for raw in iter(pipe.readline, b""):
                self.write(label, raw.decode(errors="replace").rstrip("\r\n"))
