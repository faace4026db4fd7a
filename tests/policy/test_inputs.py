"""The input builder the service and the trainer share: resets at new episodes, the
previous action carried, the EnvCode cache."""

from __future__ import annotations

import torch

from hamnet.policy import inputs as builder
from hamnet.policy.observation import PoseNoiseConfig
from hamnet.policy.registry import build
from tests.policy.inputs import informed, random_robot

B = 3


def tokens() -> tuple[torch.Tensor, ...]:
    g = torch.Generator().manual_seed(0)
    return tuple(torch.randn(B, 17, 128, generator=g) for _ in range(3))


def test_new_episodes_zero_their_previous_action_and_memory_only() -> None:
    policy = build("student", seed=0)
    carry = builder.initial_carry(policy, B)
    carry = builder.begin_step(carry, torch.zeros(B, dtype=torch.int64), torch.zeros(B))
    carry = builder.end_step(carry, torch.ones(B, 21), torch.ones(B, policy.memory_width))
    # env 1 starts a new episode (new id), env 2 restarts (step 0), env 0 continues.
    carry = builder.begin_step(carry, torch.tensor([0, 5, 0]), torch.tensor([1, 0, 0]))
    assert carry.previous_action[0].eq(1).all() and carry.previous_action[1:].eq(0).all()
    assert carry.memory[0].eq(1).all() and carry.memory[1:].eq(0).all()


def test_the_previous_action_changes_the_next_action() -> None:
    policy = informed("hamnet")
    carry = builder.initial_carry(policy, B)
    carry = builder.begin_step(carry, torch.zeros(B, dtype=torch.int64), torch.zeros(B))
    robot = random_robot(B)
    first = policy.act(builder.policy_inputs(policy.config, carry, robot, tokens()), True)
    carry = builder.end_step(carry, first.action, first.memory)
    carry = builder.begin_step(carry, torch.zeros(B, dtype=torch.int64), torch.ones(B))
    second = policy.act(builder.policy_inputs(policy.config, carry, robot, tokens()), True)
    assert not torch.allclose(first.action, second.action)


def test_env_code_cache_grows_to_the_largest_id() -> None:
    cache = builder.store_env_code(torch.zeros(0, 25), torch.tensor([2]), torch.ones(1, 25))
    cache = builder.store_env_code(cache, torch.tensor([0]), 2 * torch.ones(1, 25))
    assert cache.shape == (3, 25)
    assert cache[:, 0].tolist() == [2.0, 0.0, 1.0]


def test_the_trainer_builds_inputs_from_the_sim_in_process() -> None:
    """The in-process seam: VectorEnv observations -> the same builder -> an action, for the
    teacher and the student, with the widths the spec names."""
    from hamnet.sim.config import SimConfig
    from hamnet.sim.env import VectorEnv

    env = VectorEnv(SimConfig(num_envs=B, num_objects=2, nthread=1))
    observation = env.observe()
    robot = builder.robot_observation(observation)
    ids = torch.from_numpy(observation.episode_ids).long()
    steps = torch.from_numpy(observation.episode_step).long()
    for name in ("hamnet", "student"):
        policy = build(name, seed=0)
        carry = builder.initial_carry(policy, B)
        carry = builder.begin_step(carry, ids, steps)
        carry, read = builder.observed_state(policy.config, carry, robot, PoseNoiseConfig())
        inputs = builder.policy_inputs(policy.config, carry, read, tokens())
        assert inputs.observation.context.shape == (B, policy.config.observation.width("context"))
        action = policy.act(inputs)
        assert action.action.shape == (B, 21) and torch.isfinite(action.action).all()
