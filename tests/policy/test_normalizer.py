"""The policy's input statistics: standardise, travel with the weights, fold batches exactly."""

from __future__ import annotations

import torch

from hamnet.policy.normalizer import GROUPS, merge_moments
from hamnet.policy.registry import build
from hamnet.policy.weights import from_bytes, load_into, to_bytes
from tests.policy.inputs import random_inputs


def test_merged_moments_equal_the_whole_streams() -> None:
    torch.manual_seed(0)
    stream = torch.randn(500, 4) * torch.tensor([1.0, 10.0, 0.1, 3.0]) + 2.0
    mean, var, count = torch.zeros(4), torch.ones(4), torch.zeros(())
    for chunk in stream.split(64):
        mean, var, count = merge_moments(mean, var, count, chunk)
    torch.testing.assert_close(mean, stream.mean(0), atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(var, stream.var(0, unbiased=False), atol=1e-4, rtol=1e-5)
    assert count.item() == 500


def test_standardised_inputs_have_zero_mean_unit_variance_and_are_clipped() -> None:
    policy = build("hamnet", seed=0)
    inputs = random_inputs(policy, 256, seed=1)
    scaled = {g: getattr(inputs.observation, g) * 7.0 + 3.0 for g in GROUPS}
    observation = type(inputs.observation)(**scaled)
    unknown = policy.normalizer(observation)  # no statistics yet: every input at its mean
    assert all(not getattr(unknown, group).any() for group in GROUPS)
    policy.normalizer.update(observation)
    out = policy.normalizer(observation)
    for group in GROUPS:
        value = getattr(out, group)
        assert value.mean(0).abs().max() < 0.05 and value.abs().max() <= 5.0
        varied = getattr(observation, group).std(0) > 1e-3
        torch.testing.assert_close(value.std(0)[varied], torch.ones(int(varied.sum())), atol=0.05, rtol=0)


def test_the_statistics_travel_with_the_weights() -> None:
    """A policy service that loads the trainer's weights must standardise as training did:
    same inputs, same actions."""
    trainer_side = build("hamnet", seed=0)
    inputs = random_inputs(trainer_side, 8, seed=2)
    trainer_side.normalizer.update(inputs.observation)
    served = build("hamnet", seed=1)
    load_into(served, from_bytes(to_bytes(trainer_side, version=3)))
    with torch.no_grad():
        expected = trainer_side.act(inputs, deterministic=True).action
        got = served.act(inputs, deterministic=True).action
    torch.testing.assert_close(got, expected)
