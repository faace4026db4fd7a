"""`modulation_embedding` returns the z_tau that `Policy.act` itself feeds the modulation
heads, without gradients, and refuses architectures that have none."""

from __future__ import annotations

import pytest
import torch

from hamnet.evaluation.skills import modulation_embedding
from tests.policy.inputs import informed, random_inputs


@pytest.mark.parametrize("name", ["hamnet", "student"])
def test_embedding_is_what_act_feeds_the_heads(name: str) -> None:
    """The actor heads' input during `act`, captured by a forward hook, equals the returned
    (B, Z) embedding; for the student that is z after its GRU step, so returning the
    modulation MLP's output instead would fail here."""
    policy = informed(name)
    inputs = random_inputs(policy, batch=4)
    seen: list[torch.Tensor] = []
    hook = policy.network.actor_heads.register_forward_hook(
        lambda m, args, out: seen.append(args[0])
    )
    with torch.no_grad():
        policy.act(inputs, deterministic=True)
    hook.remove()
    z = modulation_embedding(policy, inputs)
    assert z.shape == (4, policy.config.modulation_hidden[-1])
    assert not z.requires_grad
    torch.testing.assert_close(z, seen[0])


def test_baselines_have_no_embedding() -> None:
    policy = informed("mlp")
    with pytest.raises(TypeError):
        modulation_embedding(policy, random_inputs(policy, batch=2))
