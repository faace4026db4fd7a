"""Learner benchmark: one PPO update of HAMnet, timed three ways on the same batch from the
same state, so each cut of issue 28 shows its own ratio.

The policy is the shipped easy-stage teacher (`easy-teacher`) and the batch its own rollout
on the easy stage: a late update of a run, where the actor reaches the KL bound after a few
steps and the critic goes on alone through the rest (27 of 31 steps in the hour run's last
updates). One update on a first rollout warms the optimizer (a fresh Adam's first step
overshoots the bound and is undone); each setup then starts from the same weights and
optimizer state, on a second rollout, with the same minibatch order:
- baseline: one torch thread, every critic-only step through the whole network;
- critic: one thread, the critic-only steps on features computed once per update
  (`ppo.update`'s `critic`, the trainer's default);
- default: that, on every core (`RunConfig.learner_threads`: an in-process trainer's
  rollouts wait for its update), in float32;
- bfloat16: that under bfloat16 autocast (`PPOConfig.precision`, the trainer's default
  on a CPU with native bfloat16), with how the whole batch's gradient at the start state
  agrees with float32's (cosine).

And, on one minibatch of the batch (one thread), the global scene cross-attention's forward
and backward with every sample's tokens embedded (`repeated=False`) against each distinct
token set embedded once (`repeated=True`, what HAMnet does: a scene's tokens are constant
through an episode), next to a whole-network step (`Policy.evaluate`, forward and
backward) of the same minibatch.

Produces a progress line per setup on stderr and, as the last stdout line, one JSON object
with `update_s` per setup, `critic_speedup` (baseline / critic), `threads_speedup`
(critic / default), `update_speedup` (baseline / default), `bfloat16_speedup` (default /
bfloat16), `bfloat16_gradient_cosine`, the steps each update took, `scene_embedding_s`
(per sample, distinct), `scene_embedding_speedup`, `distinct_scenes` (of the minibatch's
samples), `whole_step_s` and `whole_step_speedup` (the whole step with the per-sample
embedding against it as run).

    .venv/bin/python benchmarks/learner.py --quick   # 16 envs, 2048 samples: about 40 s
    .venv/bin/python benchmarks/learner.py           # 64 envs, 8192 samples (the run's): 2-3 min
"""

from __future__ import annotations

import argparse
import copy
import os
import time
from collections.abc import Callable
from pathlib import Path
from tempfile import TemporaryDirectory

import torch
from common import durations, header, progress, report

from hamnet.policy.layers import distinct_rows
from hamnet.policy.policy import Policy
from hamnet.policy.shipped import read_shipped
from hamnet.policy.weights import load_into
from hamnet.runtime.compute import bfloat16_autocast, torch_threads
from hamnet.runtime.trees import take_rows
from hamnet.sim.stages import stage_config
from hamnet.trainer.algorithms.ppo import Batch, UpdateStats, update
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner

TEACHER = "easy-teacher"
CORES = os.cpu_count() or 1
SETUPS = {
    "baseline": (1, False, False),
    "critic": (1, True, False),
    "default": (CORES, True, False),
    "bfloat16": (CORES, True, True),
}
"""Setup -> (torch threads, critic-only steps on features computed once, bfloat16)."""


def timed_update(
    runner: Runner, batch: Batch, threads: int, cached: bool, bfloat16: bool
) -> tuple[float, UpdateStats]:
    """Seconds and stats of one update of `runner`'s policy on `batch` (the policy and its
    optimizer are left where the update put them)."""
    policy, ppo, algorithm = runner.policy, runner.config.ppo, runner.algorithm
    policy.train()
    with torch_threads(threads), bfloat16_autocast(bfloat16):
        started = time.perf_counter()
        stats = update(policy.evaluate, policy.parameters(), algorithm.optimizer, batch,
                       algorithm.action_bounds, ppo, generator=torch.Generator().manual_seed(0),
                       energy=algorithm.energy,
                       critic=policy if cached else None)  # fmt: skip
        return time.perf_counter() - started, stats


def scene_embedding(policy: Policy, batch: Batch, samples: int) -> dict:
    """Seconds of the global scene cross-attention's forward and backward on the first
    `samples` of a shuffled `batch`, each sample's tokens embedded and each distinct token
    set once, and of the whole network's step on the same rows (one thread)."""
    rows = torch.randperm(len(batch.actions), generator=torch.Generator().manual_seed(0))
    inputs = take_rows(batch.inputs, rows[:samples])
    actions = batch.actions[rows[:samples]]
    query = policy.normalizer(inputs.observation).scene_query
    attention = policy.network.context.global_attention
    policy.train()

    def attend(repeated: bool) -> Callable[[], None]:
        return lambda: attention(query, inputs.global_tokens, repeated).sum().backward()

    def step() -> None:
        evaluation = policy.evaluate(inputs, actions)
        (evaluation.log_prob.mean() + evaluation.values.mean()).backward()

    with torch_threads(1):
        seconds = {
            "per_sample": float(durations(attend(False), 3).min()),
            "distinct": float(durations(attend(True), 3).min()),
        }
        whole = float(durations(step, 3).min())
    policy.zero_grad(set_to_none=True)
    return {
        "scene_embedding_s": {name: round(value, 4) for name, value in seconds.items()},
        "scene_embedding_speedup": round(seconds["per_sample"] / seconds["distinct"], 3),
        "distinct_scenes": len(distinct_rows(inputs.global_tokens)[0]),
        "whole_step_s": round(whole, 4),
        "whole_step_speedup": round(
            (whole + seconds["per_sample"] - seconds["distinct"]) / whole, 3
        ),
    }


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="16 environments, 2048 samples")
    args = parser.parse_args()
    num_envs = 16 if args.quick else 64
    with TemporaryDirectory() as run_dir:
        config = RunConfig(sim=stage_config("easy", num_envs=num_envs), run_dir=Path(run_dir),
                           steps_per_rollout=128, eval_episodes=0)  # fmt: skip
        runner = Runner(config)
        load_into(runner.policy, read_shipped(TEACHER))
        runner.iterate()  # warms the optimizer
        runner.policy.eval()
        rollout = runner.source.collect(runner.policy, config.rollout_steps, 0, 1).rollout
        batch = runner.algorithm.batch(rollout)
        samples = batch.actions.shape[0]
        progress(f"{samples} samples of {TEACHER} on the easy stage collected")
        start = copy.deepcopy((runner.policy.state_dict(), runner.algorithm.optimizer.state_dict()))
        seconds, steps = {}, {}
        full, low = runner.algorithm.gradient(batch), runner.algorithm.gradient(batch, True)
        cosine = float(torch.nn.functional.cosine_similarity(full, low, dim=0))
        progress(f"bfloat16 gradient against float32's: cosine {cosine:.4f}")
        for name, (threads, cached, bfloat16) in SETUPS.items():
            runner.policy.load_state_dict(start[0])
            runner.algorithm.optimizer.load_state_dict(copy.deepcopy(start[1]))
            seconds[name], stats = timed_update(runner, batch, threads, cached, bfloat16)
            steps[name] = {"actor": stats.gradient_steps, "critic_alone": stats.value_steps}
            progress(f"{name}: {seconds[name]:.2f} s, {threads} thread(s), {steps[name]}")
        runner.policy.load_state_dict(start[0])
        embedding = scene_embedding(runner.policy, batch, samples // config.ppo.minibatches)
        progress(f"global scene embedding of a minibatch: {embedding}")
    return {
        **header("learner", args.quick),
        "policy": TEACHER,
        "samples": samples,
        "minibatches": config.ppo.minibatches,
        "update_s": {name: round(value, 3) for name, value in seconds.items()},
        "steps": steps,
        "critic_speedup": round(seconds["baseline"] / seconds["critic"], 3),
        "threads_speedup": round(seconds["critic"] / seconds["default"], 3),
        "update_speedup": round(seconds["baseline"] / seconds["default"], 3),
        "bfloat16_speedup": round(seconds["default"] / seconds["bfloat16"], 3),
        "bfloat16_gradient_cosine": round(cosine, 4),
        **embedding,
        "threads": CORES,
        "cpus": os.cpu_count(),
    }


if __name__ == "__main__":
    report(main())
