"""The MCAP writer and reader: byte-exact round trips, schemas that standard readers decode,
raw channels, chunking, rotation, and files cut short the way a SIGKILL leaves them."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap_protobuf.decoder import DecoderFactory

from hamnet.recorder.config import RecorderConfig
from hamnet.runtime.numbered_files import file_path, recording_files
from hamnet.runtime.recordings import FileContents, read_file, read_recording
from tests.recorder.recordings import RAW, STATE, lock_step, write

STEPS = 20


def test_every_message_comes_back_byte_for_byte_with_its_times(tmp_path: Path) -> None:
    messages = lock_step(STEPS)
    write(tmp_path / "a.mcap", messages)
    contents = FileContents(tmp_path / "a.mcap")
    back = list(read_file(tmp_path / "a.mcap", contents))
    assert [(m.key, m.payload, m.log_time_ns) for m in back] == messages
    assert all(m.publish_time_ns == m.log_time_ns - 7 for m in back)
    assert {m.key: m.schema for m in back} == {
        STATE: "hamnet.RobotState", RAW: "", messages[-1][0]: "hamnet.Transition"
    }
    assert contents.complete and not contents.stopped
    assert contents.compression == {"zstd"}
    assert contents.metadata["hamnet"]["namespace"] == "rec"


def test_standard_readers_decode_contract_channels_and_keep_raw_ones_raw(tmp_path: Path) -> None:
    write(tmp_path / "a.mcap", lock_step(STEPS), compression="lz4")
    with open(tmp_path / "a.mcap", "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        states = [decoded for _, _, _, decoded in reader.iter_decoded_messages(topics=[STATE])]
        raw = [(schema, channel) for schema, channel, _ in reader.iter_messages(topics=[RAW])]
    # Decoded from the schema in the file alone (a class of its own, not hamnet's).
    assert {type(s).DESCRIPTOR.full_name for s in states} == {"hamnet.RobotState"}
    assert [s.header.step for s in states] == [0, 0, *range(1, STEPS)]
    assert all(schema is None and channel.schema_id == 0 for schema, channel in raw)
    assert len(raw) == STEPS


def test_chunks_close_by_age_and_by_size(tmp_path: Path) -> None:
    """Every 0.25 s of log time (messages 0.1 s apart): a chunk about every 3 steps."""
    contents: list[FileContents] = []
    write(tmp_path / "age.mcap", lock_step(STEPS), chunk_s=0.25)
    list(read_recording([tmp_path / "age.mcap"], contents))
    assert 6 <= contents[0].chunks <= 8
    contents.clear()
    write(tmp_path / "size.mcap", lock_step(STEPS), chunk_mb=1e-6)  # one message per chunk
    list(read_recording([tmp_path / "size.mcap"], contents))
    assert contents[0].chunks == len(lock_step(STEPS))


@pytest.mark.parametrize("rotation", [{"rotate_s": 0.5}, {"rotate_mb": 0.008, "compression": "none"}])
def test_rotation_splits_into_numbered_finished_files_that_merge_back(
    tmp_path: Path, rotation: dict
) -> None:
    messages = lock_step(3 * STEPS)
    writer = write(tmp_path / "run.mcap", messages, chunk_s=0.2, **rotation)
    assert len(writer.paths) >= 3
    assert writer.paths == [tmp_path / f"run-{i:04d}.mcap" for i in range(len(writer.paths))]
    assert sorted(tmp_path.iterdir()) == writer.paths  # nothing else, no empty file
    for path in writer.paths:  # each file is complete on its own: schemas, channels, summary
        with open(path, "rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            assert reader.get_summary().statistics.message_count > 0
            for _, channel, _, decoded in reader.iter_decoded_messages(topics=[STATE]):
                assert type(decoded).DESCRIPTOR.full_name == "hamnet.RobotState", channel.topic
    if "rotate_s" in rotation:  # each file spans under 0.5 s of log time
        for path in writer.paths:
            times = [m.log_time_ns for m in read_file(path)]
            assert times[-1] - times[0] < 0.5e9
    else:  # data up to the size asked for, plus the summary (indexes, schemas again: 5 kB)
        assert all(path.stat().st_size < 8000 + 6000 for path in writer.paths)
    back = [(m.key, m.payload, m.log_time_ns) for m in read_recording(writer.paths)]
    assert back == messages


def test_a_file_cut_anywhere_reads_up_to_its_last_complete_chunk(tmp_path: Path) -> None:
    """What SIGKILL leaves: no summary, no footer, maybe half a chunk. Every cut point gives
    exactly the messages of the chunks that end before it, with the standard reader too."""
    messages = lock_step(STEPS)
    whole = tmp_path / "whole.mcap"
    write(whole, messages, chunk_mb=1e-6)  # one message per chunk: every cut is visible
    data = whole.read_bytes()
    cut_file = tmp_path / "cut.mcap"
    counts = []
    for cut in range(len(data) // 3, len(data) - 100, 97):
        cut_file.write_bytes(data[:cut])
        contents = FileContents(cut_file)
        back = [(m.key, m.payload, m.log_time_ns) for m in read_file(cut_file, contents)]
        assert back == messages[: len(back)]
        assert not contents.complete and contents.stopped
        assert len(back) >= max(counts, default=0)
        counts.append(len(back))
        with open(cut_file, "rb") as stream:  # the mcap package's own sequential reader
            standard = []
            with pytest.raises((McapError, struct.error)):  # its end: no footer
                reader = NonSeekingReader(stream)
                for _, channel, message in reader.iter_messages(log_time_order=False):
                    standard.append((channel.topic, message.data))
        assert standard == [(k, p) for k, p, _ in back]
    assert 0 < counts[0] < max(counts) == len(messages)  # the last cuts are in the summary


def test_an_existing_file_is_never_replaced_the_recording_goes_to_the_next_part(
    tmp_path: Path,
) -> None:
    """A restarted recorder used to reopen its output and overwrite it (27 MB became 3 MB);
    now every run writes the next free part of the sequence and the readers take them all."""
    path = tmp_path / "run.mcap"
    path.write_bytes(b"keep me")
    second = write(path, lock_step(3))
    third = write(path, lock_step(4))
    assert path.read_bytes() == b"keep me"
    assert (second.paths, third.paths) == ([tmp_path / "run.1.mcap"], [tmp_path / "run.2.mcap"])
    assert recording_files([path]) == [path, *second.paths, *third.paths]
    assert recording_files([tmp_path / "run.1.mcap"]) == second.paths  # its own sequence: none


def test_a_rotating_recording_run_again_rotates_within_the_next_part(tmp_path: Path) -> None:
    first = write(tmp_path / "run.mcap", lock_step(STEPS), rotate_s=0.5)
    second = write(tmp_path / "run.mcap", lock_step(3), rotate_s=0.5)
    assert len(first.paths) > 1 and second.paths == [tmp_path / "run.1-0000.mcap"]
    assert recording_files([tmp_path / "run.mcap"]) == first.paths + second.paths
    merged = list(read_recording(recording_files([tmp_path / "run.mcap"])))
    assert len(merged) == len(lock_step(STEPS)) + len(lock_step(3))


def test_file_names_are_predictable() -> None:
    assert file_path(Path("runs/x.mcap"), False, 0) == Path("runs/x.mcap")
    assert file_path(Path("runs/x.mcap"), True, 12) == Path("runs/x-0012.mcap")
    with pytest.raises(ValueError, match=".mcap"):
        RecorderConfig(output=Path("runs/x.bag"))
