"""A rollout survives the trip through a RolloutChunk exactly, sends per-episode tokens once
per episode, and a chunk that does not fit the trainer's policy is refused with a reason."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from hamnet.policy.chunk_codec import INDEX, encode_rollout
from hamnet.policy.registry import build
from hamnet.policy.rollout_record import Rollout
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime.codec import encode
from hamnet.runtime.tensor import PayloadError, to_tensor
from hamnet.runtime.trees import zip_trees
from hamnet.trainer.storage.rollout_chunks import chunk_decoder, decode_rollout
from tests.trainer.test_runner import worker

T = 3


@pytest.fixture(scope="module")
def collected() -> tuple[Rollout, torch.nn.Module]:
    policy = build("hamnet", seed=0).eval()
    return worker(timeout=300).collect(policy, steps=T, env_transitions=0), policy


def test_a_rollout_round_trips_exactly(collected) -> None:
    rollout, policy = collected
    decoded = decode_rollout(RolloutChunk.FromString(encode(encode_rollout(rollout, 7, 0))), policy)
    for name in (field.name for field in dataclasses.fields(Rollout) if field.name != "inputs"):
        if getattr(rollout, name) is None:  # a run without a guide
            assert getattr(decoded, name) is None, name
        else:
            assert torch.equal(getattr(decoded, name), getattr(rollout, name)), name
    zip_trees(
        [decoded.inputs, rollout.inputs],
        lambda pair: torch.equal(*pair) or pytest.fail("inputs differ"),
    )


def test_episode_tokens_travel_once_per_episode(collected) -> None:
    rollout, _ = collected
    chunk = encode_rollout(rollout, 7, 0)
    envs = rollout.actions.shape[1]
    assert chunk.header.policy_version == 7 and chunk.horizon == T
    assert chunk.tensors["inputs.object_tokens"].shape[0] == envs  # no episode ended in T steps
    assert chunk.tensors["inputs.object_tokens" + INDEX].shape[0] == T * envs
    assert chunk.tensors["inputs.local_tokens"].shape[0] == T * envs


def copy_of(chunk: RolloutChunk) -> RolloutChunk:
    out = RolloutChunk()
    out.CopyFrom(chunk)
    return out


def with_a_nan(chunk: RolloutChunk, name: str, values: torch.Tensor) -> RolloutChunk:
    """A copy of `chunk` whose tensor `name` is `values` (T, B, ...) with its first entry NaN."""
    out, array = copy_of(chunk), values.numpy().copy()
    array.flat[0] = np.nan
    to_tensor(array, out.tensors[name])
    return out


def refused(chunk: RolloutChunk, policy, reason: str) -> None:
    with pytest.raises(PayloadError) as error:
        chunk_decoder(policy)("key", encode(chunk))
    assert error.value.reason == reason, error.value


def test_unfit_chunks_are_refused_with_a_reason(collected) -> None:
    rollout, policy = collected
    good = encode_rollout(rollout, 1, 0)
    missing = copy_of(good)
    del missing.tensors["log_prob"]
    refused(missing, policy, "missing")
    refused(with_a_nan(good, "actions", rollout.actions), policy, "nonfinite")
    unknown = copy_of(good)
    to_tensor(np.zeros(3, np.float32), unknown.tensors["inputs.extra"])
    refused(unknown, policy, "shape")
    short = copy_of(good)
    to_tensor(rollout.inputs.local_tokens[:, :, :5].numpy(), short.tensors["inputs.local_tokens"])
    refused(short, policy, "shape")  # inputs the policy cannot read
    pointing = copy_of(good)
    index = np.full(T * rollout.actions.shape[1], 99, np.int32)
    to_tensor(index, pointing.tensors["inputs.object_tokens" + INDEX])
    refused(pointing, policy, "shape")
    assert chunk_decoder(policy)("key", encode(good)).version == 1


def test_a_guided_rollouts_pusher_actions_travel_with_it_and_are_checked(collected) -> None:
    """A guided run's workers send the scripted pusher's actions (`Rollout.guide`) beside the
    rollout: they arrive as sent, and a wrong shape or a NaN is refused like any field."""
    rollout, policy = collected
    guided = dataclasses.replace(rollout, guide=torch.rand(rollout.actions.shape))
    chunk = encode_rollout(guided, 1, 0)
    decoded = decode_rollout(RolloutChunk.FromString(encode(chunk)), policy)
    assert torch.equal(decoded.guide, guided.guide)
    narrow = copy_of(chunk)
    to_tensor(guided.guide[..., :5].numpy(), narrow.tensors["guide"])
    refused(narrow, policy, "shape")
    refused(with_a_nan(chunk, "guide", guided.guide), policy, "nonfinite")
