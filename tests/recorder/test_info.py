"""`hamnet record info` on files whose contents are known: counts, rates, sizes, duration,
and an unfinished file reported as such."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hamnet.recorder.cli import main
from hamnet.recorder.info import format_text, summarise
from tests.recorder.recordings import RAW, STATE, T0, TRANSITION, lock_step, write

STEPS = 11  # 10 periods of 0.1 s


def test_counts_rates_sizes_and_duration_of_a_known_recording(tmp_path: Path) -> None:
    messages = lock_step(STEPS)
    write(tmp_path / "a.mcap", messages)
    info = summarise([tmp_path / "a.mcap"])
    topics = {t.key: t for t in info.topics}
    assert {k: t.messages for k, t in topics.items()} == {STATE: STEPS + 1, RAW: STEPS, TRANSITION: STEPS}
    # States: 12 messages from T0 to T0 + 1 s; raw and transitions: 11 over exactly 1 s.
    assert topics[STATE].rate_hz == pytest.approx(11.0)
    assert topics[RAW].rate_hz == pytest.approx(10.0)
    assert topics[RAW].payload_bytes == sum(len(p) for k, p, _ in messages if k == RAW)
    assert (topics[STATE].schema, topics[RAW].schema) == ("hamnet.RobotState", "")
    assert info.duration_s == pytest.approx(1.0 + 40e-9)
    assert topics[STATE].first_ns == T0
    assert info.messages == len(messages)
    assert [f.complete for f in info.files] == [True]
    text = format_text(info)
    assert f"{len(messages)} on 3 topics" in text and "(raw, no schema)" in text and "finished" in text


def test_cli_prints_json_and_flags_an_unfinished_file(tmp_path: Path, capsys) -> None:
    write(tmp_path / "a.mcap", lock_step(STEPS), chunk_mb=1e-6)
    data = (tmp_path / "a.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 4])
    assert main(["info", str(tmp_path / "a.mcap"), "--json"]) == 0
    whole = json.loads(capsys.readouterr().out)
    assert whole["complete"] and whole["messages"] == len(lock_step(STEPS))
    assert main(["info", str(tmp_path / "cut.mcap"), "--json"]) == 0
    cut = json.loads(capsys.readouterr().out)
    assert not cut["complete"] and 0 < cut["messages"] < whole["messages"]
    assert main(["info", str(tmp_path / "cut.mcap")]) == 0
    assert "UNFINISHED" in capsys.readouterr().out
    assert main(["info", str(tmp_path / "missing.mcap")]) == 2


def test_a_file_that_is_not_mcap_is_refused_by_info_and_replay(tmp_path: Path, capsys) -> None:
    """`record info` and `replay` on a text file exited 0 (issue 13)."""
    from hamnet.recorder.replay_cli import main as replay_main

    path = tmp_path / "notes.mcap"
    path.write_text("not a recording\n")
    assert main(["info", str(path)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"hamnet record info: {path} is not an MCAP file (it does not start with the MCAP magic)")
    assert replay_main([str(path)]) == 2
