"""DAgger's demonstrations survive the trip through a RolloutChunk exactly (the student's
inputs, the teacher's labels, who acted, episode starts, rewards, dones, successes), and a
chunk labelled by another teacher, or lacking a label, is refused with a reason."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from hamnet.policy.registry import build
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime.codec import encode
from hamnet.runtime.tensor import PayloadError
from hamnet.runtime.trees import zip_trees
from hamnet.trainer.algorithms.dagger import Demonstrations
from hamnet.trainer.collection.dagger_worker import build_dagger_worker
from hamnet.trainer.config import DaggerConfig
from hamnet.trainer.storage.demonstration_chunks import (
    decode_demonstrations,
    demonstrations_decoder,
    encode_demonstrations,
)
from hamnet.trainer.storage.rollout_chunks import chunk_decoder
from tests.trainer.test_dagger import STEPS, tiny_run

TEACHER = "ab" * 32
"""A teacher checkpoint's SHA-256 (hex)."""


@pytest.fixture(scope="module")
def collected(tmp_path_factory: pytest.TempPathFactory) -> tuple[Demonstrations, torch.nn.Module]:
    """Two rollouts of a 3-step timeout with beta 0.5: episodes end and begin within the
    second, both policies act."""
    teacher, student = build("hamnet", seed=1).eval(), build("student", seed=0).eval()
    config = tiny_run(tmp_path_factory.mktemp("run"), timeout=3)
    worker = build_dagger_worker(config, teacher)
    half = DaggerConfig(beta_initial=0.5, beta_final=0.5)
    worker.collect(teacher, student, STEPS, 0, half)
    return worker.collect(teacher, student, STEPS, 16, half), student


def test_demonstrations_round_trip_exactly(collected) -> None:
    demos, student = collected
    assert demos.dones.any() and not demos.first.all()
    chunk = encode_demonstrations(demos, 7, 3, TEACHER)
    decoded = decode_demonstrations(RolloutChunk.FromString(encode(chunk)), student, TEACHER)
    for field in dataclasses.fields(Demonstrations):
        if field.name != "inputs":
            have, want = getattr(decoded, field.name), getattr(demos, field.name)
            assert have.dtype == want.dtype and torch.equal(have, want), field.name
    zip_trees(
        [decoded.inputs, demos.inputs],
        lambda pair: torch.equal(*pair) or pytest.fail("inputs differ"),
    )
    arrived = demonstrations_decoder(TEACHER)(student)("key", encode(chunk))
    assert arrived.version == 7 and isinstance(arrived.rollout, Demonstrations)


def test_another_teachers_or_an_unlabelled_chunk_is_refused(collected) -> None:
    demos, student = collected
    cases = {
        "teacher": encode_demonstrations(demos, 1, 0, "cd" * 32),
        "missing": encode_demonstrations(demos, 1, 0, TEACHER),
    }
    del cases["missing"].tensors["labels"]
    for reason, chunk in cases.items():
        with pytest.raises(PayloadError) as error:
            demonstrations_decoder(TEACHER)(student)("key", encode(chunk))
        assert error.value.reason == reason, error.value


def test_a_ppo_decoder_refuses_demonstrations(collected) -> None:
    """Read as PPO's rollout, a DAgger chunk lacks actions and log-probs: dropped, not learned."""
    demos, student = collected
    with pytest.raises(PayloadError, match="lacks"):
        chunk_decoder(student)("key", encode(encode_demonstrations(demos, 1, 0, TEACHER)))
