"""The in-process loop on the real cores, at tiny sizes: rollouts are on-policy, timeouts are
bootstrapped, metrics and checkpoints are written."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pytest
import torch

from hamnet.perception.checkpoint import SHIPPED_ENCODER, load_checkpoint
from hamnet.perception.core import Perception
from hamnet.perception.unicorn import UniCORN
from hamnet.policy.observation import PoseNoiseConfig
from hamnet.policy.registry import build
from hamnet.policy.rollout_record import merge_environments
from hamnet.policy.weights import read_checkpoint
from hamnet.safety.config import with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.env import VectorEnv
from hamnet.sim.stages import stage_config
from hamnet.sim.task_config import TaskConfig
from hamnet.trainer.algorithms import ppo_learner
from hamnet.trainer.collection.rollout_worker import RolloutWorker, collect_overlapped
from hamnet.trainer.results import evaluate as evaluate_module
from hamnet.trainer.results.evaluate import evaluate, success_rate
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner
from tests.policy.inputs import informed

B = 2


def tiny_sim():
    """The easy stage with B environments, two objects, one physics thread."""
    return stage_config("easy", num_envs=B, num_objects=2, nthread=1)


def worker(timeout: int) -> RolloutWorker:
    sim = stage_config("easy", num_envs=B, num_objects=2, nthread=1)
    env = VectorEnv(
        dataclasses.replace(sim, task=dataclasses.replace(TaskConfig(), timeout=timeout))
    )
    safety = SafetyFilter(np.zeros((B, 7)), with_profile("training"))
    torch.manual_seed(0)  # the same encoder in every worker
    return RolloutWorker(env, Perception(UniCORN(), B), safety)


def test_stored_log_probs_are_the_acting_policys() -> None:
    """PPO's ratio starts at 1 only if the stored inputs reproduce what the policy acted on."""
    policy = build("hamnet", seed=0).eval()
    rollout = worker(timeout=300).collect(policy, steps=3, env_transitions=0)
    actions = rollout.actions.reshape(-1, rollout.actions.shape[-1])
    with torch.no_grad():
        evaluated = policy.evaluate(rollout.inputs, actions)
    torch.testing.assert_close(evaluated.log_prob, rollout.log_prob.flatten(), atol=1e-4, rtol=1e-5)
    torch.testing.assert_close(
        evaluated.values, rollout.values.reshape(-1, rollout.values.shape[-1])
    )


def test_only_timeouts_are_bootstrapped_and_every_end_is_a_done() -> None:
    """With a 2-step timeout, steps 1 and 3 end every episode by truncation: they carry
    V(final state) (non-zero for a random critic), the others nothing."""
    policy = build("hamnet", seed=0).eval()
    rollout = worker(timeout=2).collect(policy, steps=4, env_transitions=0)
    truncated = rollout.dones & ~rollout.success
    assert rollout.dones[[1, 3]].all() and not rollout.dones[[0, 2]].any()
    assert (rollout.final_values[truncated].abs().sum(-1) > 0).all()
    assert (rollout.final_values[~rollout.dones] == 0).all()


def test_runner_iterates_logs_and_checkpoints(tmp_path: Path) -> None:
    config = RunConfig(sim=tiny_sim(), steps_per_rollout=2, run_dir=tmp_path, max_env_transitions=8)
    runner = Runner(config)
    metrics = runner.run()
    rows = [json.loads(line) for line in metrics.read_text().splitlines()]
    assert [row["env_transitions"] for row in rows] == [4, 8]
    for key in (
        "approx_kl",
        "clip_fraction",
        "learning_rate",
        "env_steps_per_s",
        "success_rate",
        "log_std",
    ):
        assert key in rows[-1]
    weights = read_checkpoint(tmp_path / "checkpoints" / "latest.safetensors")
    assert weights.architecture == "hamnet" and weights.version == 3
    torch.testing.assert_close(weights.tensors["log_std"], runner.policy.log_std)


def test_the_policy_reads_the_shipped_encoder_unless_asked_for_a_random_one() -> None:
    """HAMnet learns on the pre-trained UniCORN shipped in the package (frozen, the paper's);
    `random_encoder` freezes a random one (version 0), the same for every worker of a run."""
    shipped, version = load_checkpoint(SHIPPED_ENCODER)
    runner = Runner(RunConfig(sim=tiny_sim(), overlap=True))
    assert runner.source.encoder_version == version >= 1
    for worker in runner.source.workers:
        encoder = worker.perception.encoder
        assert not any(p.requires_grad for p in encoder.parameters())
        assert all(torch.equal(p, q) for p, q in zip(encoder.parameters(), shipped.parameters()))
    random = Runner(RunConfig(sim=tiny_sim(), overlap=True, random_encoder=True))
    first, second = (worker.perception.encoder for worker in random.source.workers)
    assert random.source.encoder_version == 0 and first is second
    assert not torch.equal(first.emb, shipped.emb)


def test_evaluation_plays_one_held_out_episode_per_environment() -> None:
    """One whole episode per environment (at most the 300-step timeout), acting with the mean:
    the rate is a multiple of 1/2 and the same on a second call."""
    config = RunConfig(sim=tiny_sim())
    policy = build("hamnet", seed=0)
    rate = success_rate(policy, config, episodes=2, env_transitions=0)
    assert rate in (0.0, 0.5, 1.0)
    assert success_rate(policy, config, episodes=2, env_transitions=0) == rate


def test_the_state_baseline_trains_without_perception(tmp_path: Path) -> None:
    config = RunConfig(architecture="state-mlp", sim=tiny_sim(), steps_per_rollout=2, run_dir=tmp_path,
                       max_env_transitions=4)  # fmt: skip
    runner = Runner(config)
    assert all(worker.perception is None for worker in runner.source.workers)
    runner.run()
    assert (
        read_checkpoint(tmp_path / "checkpoints" / "latest.safetensors").architecture == "state-mlp"
    )


@pytest.fixture
def held_out_workers(monkeypatch) -> list[RolloutWorker]:
    """The workers `evaluate` builds from now on, in order."""
    built: list[RolloutWorker] = []
    original = evaluate_module.held_out_worker

    def spy(*args, **kwargs) -> RolloutWorker:
        built.append(original(*args, **kwargs))
        return built[-1]

    monkeypatch.setattr(evaluate_module, "held_out_worker", spy)
    return built


def test_a_paddle_space_run_carries_its_space_to_filters_weights_and_evaluation(
    tmp_path: Path, held_out_workers: list[RolloutWorker]
) -> None:
    """`--action-space paddle`: the policy's config, every worker's filter and the
    checkpoint say "paddle", and the held-out evaluation of those weights acts through a
    paddle-space filter whatever run config it is given."""
    config = RunConfig(architecture="state-mlp", action_space="paddle", sim=tiny_sim(),
                       steps_per_rollout=2, run_dir=tmp_path, max_env_transitions=4)  # fmt: skip
    runner = Runner(config)
    assert runner.policy.config.action_space == "paddle"
    spaces = {w.safety.config.action_magnitude.space for w in runner.source.workers}
    assert spaces == {"paddle"}
    runner.run()
    weights = read_checkpoint(tmp_path / "checkpoints" / "latest.safetensors")
    assert weights.config.action_space == "paddle"
    evaluate(runner.policy, dataclasses.replace(config, action_space="joint"), 2, 0)
    assert [w.safety.config.action_magnitude.space for w in held_out_workers] == ["paddle"]


def test_overlapped_collection_equals_each_worker_collecting_alone() -> None:
    """Two groups stepped in turn with their physics in a thread must give, per group,
    exactly the rollout that group gives alone (same seeds): the overlap changes timing,
    never data. The merged rollout puts the first group's environments first."""
    policy = build("hamnet", seed=0).eval()
    alone = [worker(timeout=3).collect(policy, steps=4, env_transitions=0) for _ in range(2)]
    merged = collect_overlapped(
        (worker(timeout=3), worker(timeout=3)), policy, steps=4, env_transitions=0
    )
    expected = merge_environments(alone)
    for name in (
        "actions",
        "log_prob",
        "values",
        "rewards",
        "final_values",
        "dones",
        "next_values",
    ):
        torch.testing.assert_close(getattr(merged, name), getattr(expected, name), msg=name)
    torch.testing.assert_close(
        merged.inputs.observation.context, expected.inputs.observation.context
    )
    assert merged.actions.shape[:2] == (4, 2 * B)
    torch.testing.assert_close(merged.actions[:, :B], alone[0].actions)


def test_the_held_out_goal_return_sums_the_first_episodes_goal_term() -> None:
    """A policy that never moves leaves every object where it is: its goal return is the
    arm's incidental nudges only, near 0; the rate agrees with success_rate."""
    policy = build("state-mlp", seed=0)
    for parameter in policy.parameters():
        parameter.data.zero_()  # the mean action is 0: no residual, middle gains
    config = RunConfig(architecture="state-mlp", sim=tiny_sim(), steps_per_rollout=4)
    held_out = evaluate(policy, config, episodes=2, env_transitions=0)
    assert abs(held_out.goal_return) < 0.01
    # Unpushed, each object ends about where it started: at least the stage's 15 cm away.
    np.testing.assert_allclose(held_out.final_distance, held_out.start_distance, atol=0.02)
    assert (held_out.start_distance >= 0.15 - 1e-6).all() and held_out.within(0.05) == 0.0
    assert held_out.success_rate == success_rate(policy, config, episodes=2, env_transitions=0)


def test_a_fresh_run_fills_the_input_statistics_before_any_action_it_learns_from(
    tmp_path: Path,
) -> None:
    """The first rollout (acted on zeros: no statistics yet) only fills the statistics; the
    second, acted on standardised inputs, is the first one learned from."""
    config = RunConfig(sim=tiny_sim(), architecture="state-mlp", steps_per_rollout=2,
                       run_dir=tmp_path, max_env_transitions=8, eval_episodes=0)  # fmt: skip
    runner = Runner(config)
    before = [p.detach().clone() for p in runner.policy.parameters()]
    first = runner.iterate()
    assert runner.policy.normalizer.count == B * 2 and first["gradient_steps"] == 0
    assert all(torch.equal(a, b) for a, b in zip(before, runner.policy.parameters(), strict=True))
    second = runner.iterate()
    assert second["gradient_steps"] >= 1 and runner.policy.normalizer.count == 2 * B * 2


def test_the_samples_per_update_set_the_rollout_length_whatever_the_environment_count() -> None:
    """T x environments x workers stays the authors' 8192 samples per update."""
    for envs, workers in ((64, 1), (16, 1), (16, 2), (128, 4)):
        sim = stage_config("easy", num_envs=envs)
        config = RunConfig(sim=sim, workers=workers)
        assert config.rollout_steps * envs * workers == 8192
    explicit = RunConfig(sim=tiny_sim(), steps_per_rollout=3)
    assert explicit.rollout_steps == 3 and explicit.identity["steps_per_rollout"] == 3


def test_the_runner_learns_the_critic_at_its_own_rate(tmp_path: Path) -> None:
    """The optimizer's second param group is the critic's, at `value_lr`."""
    config = RunConfig(sim=tiny_sim(), architecture="state-mlp", steps_per_rollout=2,
                       run_dir=tmp_path, eval_episodes=0)  # fmt: skip
    runner = Runner(config)
    critic = {id(p) for p in runner.policy.network.critic.parameters()}
    groups = runner.algorithm.optimizer.param_groups
    assert {id(p) for p in groups[1]["params"]} == critic
    assert groups[1]["lr"] == config.ppo.value_lr
    assert any(p is runner.policy.log_std for p in groups[0]["params"])  # learned by default


def test_the_update_takes_every_core_while_the_environments_wait(
    tmp_path: Path, monkeypatch
) -> None:
    """In process the environments stand still while the trainer learns: the update runs on
    every core (`learner_threads` 0), then acting goes back to one thread; a number given
    is kept."""
    seen = []
    original = ppo_learner.update

    def spy(*args, **kwargs):
        seen.append(torch.get_num_threads())
        return original(*args, **kwargs)

    monkeypatch.setattr(ppo_learner, "update", spy)
    for threads, expected in ((0, os.cpu_count()), (1, 1)):
        config = RunConfig(sim=tiny_sim(), run_dir=tmp_path / str(threads), steps_per_rollout=2,
                           learner_threads=threads, eval_episodes=0)  # fmt: skip
        runner = Runner(config)
        assert runner.source.alone_in_update and runner.learner_threads == expected
        runner.iterate()  # fills the input statistics
        runner.iterate()
        assert seen.pop() == expected and torch.get_num_threads() == 1


def test_a_held_out_student_reads_the_pose_estimate_error_it_is_given(
    held_out_workers: list[RolloutWorker],
) -> None:
    """`evaluate(pose_noise=...)` replaces the worker's estimate error (scripts/
    student_inputs.py measures what the error costs a student); without it the student
    reads the error it was trained with."""
    policy = build("student", seed=0)
    config = RunConfig(architecture="student", sim=tiny_sim(), steps_per_rollout=4)
    exact = PoseNoiseConfig(position_std=0.0, rotation_std=0.0)
    evaluate(policy, config, episodes=2, env_transitions=0, pose_noise=exact)
    evaluate(policy, config, episodes=2, env_transitions=0)
    assert [w.pose_noise for w in held_out_workers] == [exact, PoseNoiseConfig()]


def test_a_held_out_policy_reads_every_observation_as_edited() -> None:
    """`evaluate(edit=...)` changes each observation before the policy reads it (scripts/
    teacher_privileged.py measures what a teacher's inputs are worth): a teacher whose
    object velocity is replaced acts differently on the same episodes, and the edit sees
    the first observation and every one after a step."""
    policy = informed("state-mlp")
    config = RunConfig(architecture="state-mlp", sim=tiny_sim(), steps_per_rollout=4)
    read = []

    def edit(observation) -> None:
        read.append(observation.episode_step.copy())
        observation.object_velocity[...] = 100.0

    edited = evaluate(policy, config, episodes=2, env_transitions=0, edit=edit)
    plain = evaluate(policy, config, episodes=2, env_transitions=0)
    np.testing.assert_array_equal(read[0], 0)
    assert len(read) >= 2 and (read[1] == 1).all()
    assert not np.allclose(edited.final_distance, plain.final_distance)
