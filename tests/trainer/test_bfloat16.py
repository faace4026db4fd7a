"""A bfloat16 update (`PPOConfig.precision`): only the network runs in low precision. On a
real HAMnet batch its log-probabilities stay float32 and near float32's, and its gradient
points where float32's does; a whole update under it runs and keeps the parameters float32."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import torch

from hamnet.runtime.compute import Precision, bfloat16_autocast, native_bfloat16
from hamnet.sim.stages import stage_config
from hamnet.trainer.config import PPOConfig
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner

B, T = 4, 16


def runner(tmp_path: Path, precision: Precision = "float32") -> Runner:
    sim = stage_config("easy", num_envs=B, num_objects=2, nthread=1)
    ppo = dataclasses.replace(PPOConfig(), precision=precision)
    config = RunConfig(sim=sim, steps_per_rollout=T, eval_episodes=0, run_dir=tmp_path, ppo=ppo)
    return Runner(config)


def test_the_gradient_of_a_bfloat16_pass_agrees_with_float32s(tmp_path: Path) -> None:
    run = runner(tmp_path)
    run.iterate()  # fills the input statistics
    batch = run.algorithm.batch(run.source.collect(run.policy, T, 0, 1).rollout)
    full, low = run.algorithm.gradient(batch), run.algorithm.gradient(batch, bfloat16=True)
    assert low.dtype == torch.float32
    assert torch.nn.functional.cosine_similarity(full, low, dim=0) > 0.98
    with torch.no_grad(), bfloat16_autocast():
        low_log_prob = run.policy.evaluate(batch.inputs, batch.actions).log_prob
    full_log_prob = run.policy.evaluate(batch.inputs, batch.actions).log_prob.detach()
    assert low_log_prob.dtype == torch.float32
    assert (low_log_prob - full_log_prob).abs().max() < 0.1  # of log-densities around -10


def test_a_bfloat16_update_learns_and_keeps_float32_parameters(tmp_path: Path) -> None:
    run = runner(tmp_path, "bfloat16")
    assert run.algorithm.bfloat16
    before = [p.detach().clone() for p in run.policy.parameters()]
    run.iterate()
    row = run.iterate()
    assert row["gradient_steps"] >= 1 and abs(row["approx_kl"]) < 1.0
    after = list(run.policy.parameters())
    assert all(p.dtype == torch.float32 for p in after)
    assert any(not torch.equal(a, b) for a, b in zip(after, before, strict=True))


def test_passes_after_a_step_inside_the_block_read_the_stepped_weights() -> None:
    """An update steps the weights inside one autocast block: a pass after the step must
    see them (autocast's cache of cast weights served the old ones, and the KL stop read a
    policy that was no longer there)."""
    layer = torch.nn.Linear(8, 8)
    x = torch.ones(4, 8)
    with bfloat16_autocast():
        before = layer(x)
        with torch.no_grad():
            layer.weight.add_(1.0)
        after = layer(x)
    assert (after - before).abs().min() > 0.5  # every output moved by sum(x) = 8


def test_by_default_the_update_runs_in_bfloat16_where_the_cpu_has_it(tmp_path: Path) -> None:
    assert PPOConfig().precision == "auto"
    assert runner(tmp_path, "auto").algorithm.bfloat16 == native_bfloat16()
    assert not runner(tmp_path, "float32").algorithm.bfloat16
    with pytest.raises(ValueError, match="precision"):
        PPOConfig(precision="float16")
