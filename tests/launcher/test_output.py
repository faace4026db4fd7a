"""Prefixed output: aligned labels, colour only on a terminal without NO_COLOR."""

from __future__ import annotations

import io

import pytest

from hamnet.launcher.output import Output, use_colour


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_lines_are_prefixed_with_aligned_labels() -> None:
    stream = io.StringIO()
    output = Output(stream, ["sim/0", "watch/0"], colour=False)
    output.write("sim/0", "hello")
    output.write("watch/0", "rates")
    assert stream.getvalue() == "sim/0   | hello\nwatch/0 | rates\n"


def test_colour_wraps_the_prefix_only() -> None:
    stream = io.StringIO()
    Output(stream, ["a/0", "b/0"], colour=True).write("b/0", "x")
    assert stream.getvalue() == "\033[33mb/0 | \033[0mx\n"


@pytest.mark.parametrize(("tty", "no_color", "expected"),
                         [(True, None, True), (True, "1", False), (True, "", True), (False, None, False)])
def test_colour_needs_a_terminal_and_no_NO_COLOR(monkeypatch, tty, no_color, expected) -> None:
    if no_color is None:
        monkeypatch.delenv("NO_COLOR", raising=False)
    else:
        monkeypatch.setenv("NO_COLOR", no_color)
    assert use_colour(Terminal() if tty else io.StringIO()) is expected
