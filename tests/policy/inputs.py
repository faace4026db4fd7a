"""Random but well-formed policy inputs for tests (tiny batches, real tensor shapes)."""

from __future__ import annotations

import torch

from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import RobotObservation, assemble
from hamnet.policy.policy import Policy
from hamnet.task.physics import PHYSICS_PARAM_NAMES


def random_robot(batch: int, seed: int = 0) -> RobotObservation:
    """A random robot state with unit quaternions and the privileged block."""
    g = torch.Generator().manual_seed(seed)
    r = lambda *shape: torch.randn(*shape, generator=g)  # noqa: E731
    unit = lambda q: q / q.norm(dim=-1, keepdim=True)  # noqa: E731
    pose = lambda: torch.cat((r(batch, 3), unit(r(batch, 4))), dim=-1)  # noqa: E731
    return RobotObservation(
        r(batch, J), r(batch, J), r(batch, 9), pose(), pose(), r(batch, 6),
        r(batch, len(PHYSICS_PARAM_NAMES)),
    )  # fmt: skip


def random_action(batch: int, seed: int = 0) -> torch.Tensor:
    """(B, A) a previous action."""
    return torch.randn(batch, 21, generator=torch.Generator().manual_seed(seed + 2))


def random_inputs(policy: Policy, batch: int = 4, seed: int = 0) -> PolicyInputs:
    """Inputs for `policy` with every optional piece its architecture may read."""
    config = policy.config
    g = torch.Generator().manual_seed(seed + 1)
    tokens = lambda: torch.randn(batch, config.num_tokens, config.token_dim, generator=g)  # noqa: E731
    return PolicyInputs(
        observation=assemble(
            random_robot(batch, seed), random_action(batch, seed), config.observation
        ),
        object_tokens=tokens(),
        local_tokens=tokens(),
        global_tokens=tokens(),
        env_code=torch.randn(batch, config.env_code_dim, generator=g),
        memory=policy.initial_memory(batch),
    )


def informed(name: str, seed: int = 0, **changes) -> Policy:
    """A policy whose actions vary visibly with every input: PyTorch's initialization (an
    orthogonally initialized actor starts near 0 everywhere) and input statistics (without
    them every input reads 0); `changes` to its preset config besides."""
    from hamnet.policy.registry import build, with_changes  # the registry imports networks

    policy = build(name, with_changes(name, init="torch", **changes), seed=seed)
    policy.normalizer.update(random_inputs(policy, 64, seed=seed + 100).observation)
    return policy
