"""Weights as safetensors with metadata: round trip, checkpoints, and every way bad weights
are refused (the model they were meant for stays untouched)."""

from __future__ import annotations

import json

import pytest
import torch
from safetensors.torch import save as save_tensors

from hamnet.policy.registry import build, with_changes
from hamnet.policy.weights import (
    WeightsError,
    check_action_space,
    check_fits,
    from_bytes,
    load_into,
    policy_from,
    read_checkpoint,
    save_checkpoint,
    to_bytes,
)
from tests.policy.inputs import random_inputs


def test_round_trip_rebuilds_the_same_policy_from_metadata() -> None:
    policy = build("hamnet", seed=0)
    policy.set_env_transitions(50 * 2**20)
    weights = from_bytes(to_bytes(policy, version=7))
    assert (weights.architecture, weights.version, weights.config) == ("hamnet", 7, policy.config)
    rebuilt = policy_from(weights)
    inputs = random_inputs(policy)
    torch.testing.assert_close(rebuilt.act(inputs, True).action, policy.act(inputs, True).action)
    torch.testing.assert_close(rebuilt.log_std, policy.log_std)


def test_the_action_space_travels_with_the_weights_and_is_checked() -> None:
    """Weights trained on paddle twists say so in their metadata; a filter of the other
    space refuses them. Weights written before the field (no `action_space` in their
    config JSON, as the shipped ones of issue 28) read "joint"."""
    paddle = build("state-mlp", with_changes("state-mlp", action_space="paddle"), seed=0)
    weights = from_bytes(to_bytes(paddle, version=1))
    assert weights.config.action_space == "paddle"
    check_action_space(weights, "paddle")
    with pytest.raises(WeightsError, match="'paddle' action space"):
        check_action_space(weights, "joint")
    older = json.loads(build("state-mlp", seed=0).config.to_json())
    del older["action_space"]
    assert type(paddle.config).from_json(json.dumps(older)).action_space == "joint"


def test_checkpoint_file_holds_what_an_announcement_carries(tmp_path) -> None:
    policy = build("student", seed=0)
    save_checkpoint(tmp_path / "p.safetensors", policy, 3)
    weights = read_checkpoint(tmp_path / "p.safetensors")
    assert (weights.architecture, weights.version, weights.config) == ("student", 3, policy.config)
    for name, tensor in policy.state_dict().items():
        assert torch.equal(weights.tensors[name], tensor), name


def test_missing_checkpoint_is_a_clear_error(tmp_path) -> None:
    with pytest.raises(WeightsError, match="cannot read checkpoint"):
        read_checkpoint(tmp_path / "absent.safetensors")


def _unchanged_after(policy, data: bytes, match: str) -> None:
    before = {k: v.clone() for k, v in policy.state_dict().items()}
    with pytest.raises(WeightsError, match=match):
        load_into(policy, from_bytes(data))
    for name, tensor in policy.state_dict().items():
        assert torch.equal(tensor, before[name]), name


def test_bad_weights_are_refused_and_the_old_ones_stay() -> None:
    serving = build("hamnet", seed=0)
    _unchanged_after(serving, to_bytes(build("mlp", seed=1), 2), "architecture 'mlp'")
    other = build("hamnet", with_changes("hamnet", num_modules=4), seed=1)
    _unchanged_after(serving, to_bytes(other, 2), "config differs")
    tensors = {k: v.clone() for k, v in build("hamnet", seed=1).state_dict().items()}
    metadata = from_bytes(to_bytes(serving, 2))
    header = {"format": "hamnet-policy/1", "architecture": "hamnet",
              "config": metadata.config.to_json(), "version": "2"}  # fmt: skip
    name = "network.actor.layers.0.weight"
    tensors[name] = torch.zeros(8, 3, 256)
    _unchanged_after(serving, save_tensors(tensors, metadata=header), name)
    tensors[name] = torch.full_like(serving.state_dict()[name], float("nan"))
    _unchanged_after(serving, save_tensors(tensors, metadata=header), "NaN")
    del tensors[name]
    _unchanged_after(serving, save_tensors(tensors, metadata=header), "missing")


@pytest.mark.parametrize(
    "data, match",
    [
        (b"", "not safetensors"),
        (b"\x10\x00\x00\x00\x00\x00\x00\x00not json at all!", "bad header"),
        (save_tensors({"x": torch.zeros(2)}), "without metadata"),
        (save_tensors({"x": torch.zeros(2)}, metadata={"format": "other"}), "format 'other'"),
        (save_tensors({"x": torch.zeros(2)}, metadata={"format": "hamnet-policy/1"}), "bad metadata"),
    ],
)
def test_undecodable_weights_raise_weights_error(data: bytes, match: str) -> None:
    with pytest.raises(WeightsError, match=match):
        from_bytes(data)


def test_check_fits_accepts_its_own_weights() -> None:
    policy = build("sm", seed=0)
    check_fits(policy, from_bytes(to_bytes(policy, 1)))
