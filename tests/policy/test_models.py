"""Policy networks: every architecture's shapes, the module contraction against a naive
per-sample reference, the M = 1 reduction to an MLP, gradients into every module, the
absorbed cross-attention against a standard one, the embedding of repeated token sets once,
and the Gaussian actor's maths."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch
from torch.nn import functional as F

from hamnet.policy import layers
from hamnet.policy.config import LOG_STD_AUTHORS
from hamnet.policy.layers import (
    MLP,
    CrossAttention,
    ModularLinear,
    distinct_rows,
    hidden_activation,
)
from hamnet.policy.networks import HAMNet
from hamnet.policy.policy import log_std_at
from hamnet.policy.registry import ARCHITECTURES, build, with_changes
from hamnet.task.rewards import REWARD_NAMES
from tests.policy.inputs import informed, random_action, random_inputs

B = 4


@pytest.mark.parametrize("name", list(ARCHITECTURES))
def test_every_architecture_acts_with_the_contract_shapes(name: str) -> None:
    policy = build(name, seed=0)
    action = policy.act(random_inputs(policy, B))
    assert action.action.shape == (B, 21) and action.log_prob.shape == (B,)
    assert action.values.shape == (B, len(REWARD_NAMES))
    assert action.module_weights.dim() == 3 and action.module_weights.shape[0] == B
    for tensor in (action.action, action.log_prob, action.values, action.module_weights):
        assert torch.isfinite(tensor).all()
    if action.module_weights.shape[1]:  # softmax over modules
        torch.testing.assert_close(
            action.module_weights.sum(-1), torch.ones(action.module_weights.shape[:2])
        )
    assert (action.memory is None) == (not policy.config.recurrent)


def test_hamnet_reports_one_softmax_per_actor_and_critic_layer() -> None:
    policy = build("hamnet", seed=0)
    assert policy.act(random_inputs(policy, B)).module_weights.shape == (B, 10, 8)


def naive_modular(layer: ModularLinear, x, weights, bias_weights, gate):
    """Per-sample reference: build each sample's weight matrix, then multiply."""
    matrices = torch.einsum("bm,mji->bji", weights, layer.weight)  # (B, J, I)
    bias = bias_weights @ layer.bias  # (B, I)
    y = torch.bmm(x.unsqueeze(1), matrices).squeeze(1) + bias
    return y if gate is None else y * gate


@pytest.mark.parametrize("chunk", [1024, 3])
def test_module_contraction_equals_per_sample_weight_matrices(chunk: int, monkeypatch) -> None:
    """Also with the batch mixed 3 rows at a time (B = 4: a full and a partial chunk)."""
    monkeypatch.setattr(layers, "MIXTURE_CHUNK", chunk)
    torch.manual_seed(0)
    layer = ModularLinear(13, 11, 8)
    x = torch.randn(B, 13, dtype=torch.float64)
    layer = layer.double()
    weights = torch.softmax(torch.randn(B, 8, dtype=torch.float64), -1)
    bias_weights = torch.softmax(torch.randn(B, 8, dtype=torch.float64), -1)
    gate = 1 + 0.1 * torch.randn(B, 11, dtype=torch.float64)
    torch.testing.assert_close(
        layer(x, weights, bias_weights, gate), naive_modular(layer, x, weights, bias_weights, gate)
    )
    # The hand-written backward against autograd through the naive reference.
    inputs = [t.clone().requires_grad_() for t in (x, weights, bias_weights, gate)]
    assert torch.autograd.gradcheck(lambda *a: layer(*a), inputs)


def test_hamnet_forward_equals_naive_reference_to_1e5() -> None:
    """The whole actor through `ModularLinear` against the same actor evaluated with
    explicitly built per-sample matrices."""
    policy = build("hamnet", seed=1)
    network: HAMNet = policy.network
    inputs = random_inputs(policy, B, seed=3)
    captured = {}
    hook = network.actor.register_forward_hook(
        lambda m, args, out: captured.update(args=args, out=out)
    )
    network(inputs)
    hook.remove()
    x, weights, bias_weights, gates = captured["args"]
    layers = network.actor.layers
    for index, layer in enumerate(layers):
        x = naive_modular(layer, x, weights[:, index], bias_weights[:, index], gates[index])
        if index < len(layers) - 1:
            x = hidden_activation(x)
    torch.testing.assert_close(x, captured["out"], atol=1e-5, rtol=1e-5)


def test_one_module_without_gates_is_a_plain_mlp() -> None:
    policy = build("hamnet", with_changes("hamnet", num_modules=1, gates=False), seed=2)
    network: HAMNet = policy.network
    inputs = random_inputs(policy, B)
    x = network.object(inputs)
    dims = [network.actor.layers[0].in_dim] + network.actor.out_dims
    mlp = MLP(dims)
    with torch.no_grad():
        for linear, modular in zip(mlp.layers, network.actor.layers):
            linear.weight.copy_(modular.weight[0].T)
            linear.bias.copy_(modular.bias[0])
    torch.testing.assert_close(network(inputs).mean, mlp(x), atol=1e-6, rtol=1e-5)


@pytest.mark.parametrize("name", ["hamnet", "sm", "student"])
def test_gradients_reach_every_module(name: str) -> None:
    policy = informed(name)
    inputs = random_inputs(policy, 16)
    if policy.config.recurrent:  # from zero memory the recurrent weights get no gradient
        memory = policy.act(inputs).memory.detach()
        inputs = dataclasses.replace(inputs, memory=memory)
    evaluation = policy.evaluate(inputs, torch.randn(16, 21))
    (evaluation.log_prob.mean() + evaluation.values.square().mean()).backward()
    for parameter_name, parameter in policy.named_parameters():
        assert parameter.grad is not None, parameter_name
        if parameter.dim() >= 2 and parameter.shape[0] == policy.config.num_modules:
            per_module = parameter.grad.flatten(1).abs().sum(1)  # (M,)
            assert (per_module > 0).all(), parameter_name
        else:
            assert parameter.grad.abs().sum() > 0, parameter_name


@pytest.mark.parametrize("embed_tokens", [False, True])
def test_absorbed_cross_attention_equals_standard_attention(embed_tokens: bool) -> None:
    torch.manual_seed(0)
    attention = CrossAttention(5, 12, 8, 2, (6, 3), embed_tokens).double()
    query, tokens = torch.randn(B, 5).double(), torch.randn(B, 7, 12).double()
    q = attention.query(query).view(B, 2, 1, 4)  # (B, H, 1, E/H)
    keys = attention.embed(tokens) if embed_tokens else tokens  # (B, N, D')
    k = torch.einsum("hed,bnd->bhne", attention.key, keys)  # (B, H, N, E/H)
    v = torch.einsum("hed,bnd->bhne", attention.value, keys)
    standard = F.scaled_dot_product_attention(q, k, v).reshape(B, 8)
    torch.testing.assert_close(attention(query, tokens), attention.out(standard))


def test_distinct_rows_finds_each_repeated_row_once() -> None:
    rows = torch.randn(5, 7, 3)
    picks = torch.tensor([3, 0, 3, 3, 1, 0, 4, 3])
    distinct, index = distinct_rows(rows[picks])
    assert len(distinct) == 4  # rows 0, 1, 3, 4
    assert torch.equal(distinct[index], rows[picks])
    near = rows[:2].clone()
    near[1] = near[0]
    near[1, 6, 2] += 1e-6  # differs in one value
    assert len(distinct_rows(near)[0]) == 2
    assert len(distinct_rows(rows[:0])[0]) == 0


def test_distinct_rows_counts_every_row_when_projections_collide(monkeypatch) -> None:
    rows = torch.randn(3, 4, 2)
    unique = torch.unique
    monkeypatch.setattr(
        torch, "unique", lambda keys, return_inverse: unique(keys * 0, return_inverse=True)
    )
    distinct, index = distinct_rows(rows)
    assert torch.equal(distinct, rows) and torch.equal(index, torch.arange(3))


def test_repeated_tokens_embedded_once_give_the_same_summaries_and_gradients() -> None:
    torch.manual_seed(0)
    attention = CrossAttention(5, 12, 8, 2, (6, 3), True).double()
    query = torch.randn(9, 5).double()
    tokens = torch.randn(3, 7, 12).double()[torch.tensor([0, 2, 2, 1, 0, 0, 2, 1, 1])]
    results = []
    for repeated in (False, True):
        attention.zero_grad()
        out = attention(query, tokens, repeated=repeated)
        out.square().sum().backward()
        results.append((out, [p.grad.clone() for p in attention.parameters()]))
    (plain, plain_grads), (once, once_grads) = results
    torch.testing.assert_close(once, plain)
    for a, b in zip(once_grads, plain_grads):
        torch.testing.assert_close(a, b)


def test_log_prob_and_entropy_match_torch_normal() -> None:
    policy = build("mlp", seed=0)
    policy.set_env_transitions(100 * 2**20)
    inputs = random_inputs(policy, B)
    action = policy.act(inputs, generator=torch.Generator().manual_seed(0))
    mean = policy.act(inputs, deterministic=True).action
    normal = torch.distributions.Normal(mean, policy.log_std.exp())
    torch.testing.assert_close(action.log_prob, normal.log_prob(action.action).sum(-1))
    evaluation = policy.evaluate(inputs, action.action)
    torch.testing.assert_close(evaluation.log_prob, action.log_prob)
    torch.testing.assert_close(evaluation.entropy, normal.entropy().sum(-1))


def test_log_std_schedule_counts_env_transitions_as_the_authors_vectorized_steps() -> None:
    """One decay per started 1024 x 1024 transitions, no floor: about -1.12 after 2e9."""
    config = LOG_STD_AUTHORS
    assert log_std_at(0, config) == -0.4
    assert math.isclose(log_std_at(1024, config), -0.4 - 0.000367)
    assert math.isclose(log_std_at(1000 * 2**20, config), -0.4 - 0.367)
    assert math.isclose(log_std_at(2_048_000_000, config), -0.4 - 1954 * 0.000367)
    policy = build("hamnet", with_changes("hamnet", log_std=config))
    policy.set_env_transitions(1000 * 2**20)
    torch.testing.assert_close(policy.log_std, torch.full((21,), -0.767))


def test_a_schedule_with_a_horizon_reaches_its_final_value_within_the_run() -> None:
    config = dataclasses.replace(LOG_STD_AUTHORS, horizon=1000, final=-1.4)
    assert log_std_at(0, config) == -0.4
    assert math.isclose(log_std_at(500, config), -0.9)
    assert log_std_at(1000, config) == log_std_at(5000, config) == -1.4


def test_a_learned_log_std_is_trained_by_the_loss_and_kept_by_the_counter() -> None:
    """The default log std is a parameter: a loss that rewards a narrower Gaussian moves it,
    and the schedule's counter leaves it alone."""
    policy = build("state-mlp", seed=0)
    assert isinstance(policy.log_std, torch.nn.Parameter)
    inputs = random_inputs(policy, B, seed=0)
    optimizer = torch.optim.Adam(policy.parameters(), lr=0.01)
    for _ in range(5):  # the likelihood of the mean itself grows as the std shrinks
        means = policy.act(inputs, deterministic=True).action.detach()
        optimizer.zero_grad()
        (-policy.evaluate(inputs, means).log_prob.mean()).backward()
        optimizer.step()
    assert (policy.log_std < -0.5).all()
    before = policy.log_std.detach().clone()
    policy.set_env_transitions(10**9)
    torch.testing.assert_close(policy.log_std.detach(), before)


@pytest.mark.parametrize("name", ["state-mlp", "hamnet"])
def test_orthogonal_initialization_starts_the_action_mean_near_zero(name: str) -> None:
    """Actor output scaled to 0.01: the mean starts near 0 whatever the inputs (torch's
    default initialization behind LayerNorm + tanh starts it at tenths)."""
    inputs = random_inputs(build(name, seed=0), B, seed=1)
    ours = build(name, seed=0).act(inputs, deterministic=True).action
    torch_init = build(name, with_changes(name, init="torch"), seed=0)
    theirs = torch_init.act(inputs, deterministic=True).action
    assert ours.abs().max() < 0.05 < theirs.abs().max()


def test_student_memory_carries_information_between_steps() -> None:
    policy = build("student", seed=0)
    first = random_inputs(policy, B, seed=0)
    step = policy.act(first, deterministic=True)
    again = random_inputs(policy, B, seed=0)
    fresh = policy.act(again, deterministic=True).action
    carried = policy.act(dataclasses.replace(again, memory=step.memory), deterministic=True).action
    assert not torch.allclose(fresh, carried)


def test_teacher_config_refuses_a_recurrent_baseline() -> None:
    with pytest.raises(ValueError, match="no recurrent variant"):
        build("mlp", with_changes("mlp", recurrent=True))


def test_hamnet_biases_have_their_own_softmax_and_the_output_layers_no_gates() -> None:
    """The authors give every parameter tensor its own module weights and leave the output
    layer ungated (hypernet_modular.py:956-962, 1029-1049): a shared softmax would make
    the two weight sets equal, a gated output layer would show a gate at the last index."""
    policy = build("hamnet", seed=0)
    network: HAMNet = policy.network
    with torch.no_grad():
        network.actor_heads.linear.weight.normal_()  # gates away from their initial 1
    captured = {}
    hook = network.actor.register_forward_hook(lambda m, args, out: captured.update(args=args))
    network(random_inputs(policy, B))
    hook.remove()
    _, weights, bias_weights, gates = captured["args"]
    assert not torch.allclose(weights, bias_weights)
    assert gates[-1] is None and len(gates) == len(network.actor.layers)
    for gate, width in zip(gates[:-1], network.actor.out_dims):
        assert gate.shape == (B, width) and not torch.allclose(gate, torch.ones_like(gate))


def test_modulation_reads_the_emb_token_last() -> None:
    """The authors append [EMB] after the patch tokens (unicorn.py:153-154) and read the
    last token (reduce "last", rss_train.yaml:324): token 0 is a patch and must not matter."""
    policy = build("hamnet", seed=0)
    context = policy.network.context
    inputs = random_inputs(policy, B)
    base = context(inputs)
    tokens = inputs.object_tokens.clone()
    tokens[:, 0] += 1.0
    torch.testing.assert_close(context(dataclasses.replace(inputs, object_tokens=tokens)), base)
    tokens[:, -1] += 1.0
    assert not torch.allclose(context(dataclasses.replace(inputs, object_tokens=tokens)), base)


@pytest.mark.parametrize("shared", [False, True])
def test_the_value_loss_trains_the_shared_layers_only_when_asked(shared: bool) -> None:
    """By default the critic reads the shared features with their gradient stopped: the
    value loss reaches the critic and its header alone, the policy's mean is untouched by
    it, and the outputs are those of the shared graph (the authors', `shared_value_gradient`)."""
    policy = build("hamnet", with_changes("hamnet", shared_value_gradient=shared), seed=0)
    inputs = random_inputs(policy, B)
    out = policy.network(inputs)
    out.values.square().sum().backward()
    critic = {id(p) for p in policy.critic_parameters()}
    reached = {name.split(".")[1] for name, p in policy.named_parameters()
               if p.grad is not None and p.grad.abs().sum() > 0 and id(p) not in critic}  # fmt: skip
    assert reached == ({"context", "modulation", "object"} if shared else set())
    assert {id(p) for p in policy.network.critic_heads.parameters()} <= critic
    other = build("hamnet", with_changes("hamnet", shared_value_gradient=not shared), seed=0)
    with torch.no_grad():
        torch.testing.assert_close(other.network(inputs).values, out.values.detach())


@pytest.mark.parametrize("name", ["hamnet", "student"])
def test_values_from_the_value_features_are_the_networks_values(name: str) -> None:
    """PPO's critic-only steps run the critic on features computed once
    (`Policy.value_features`): its values there are those of the whole network."""
    policy = informed(name)
    inputs = random_inputs(policy, B)
    assert policy.reads_value_features
    with torch.no_grad():
        whole = policy.evaluate(inputs, random_action(B)).values
        split = policy.values_from(policy.value_features(inputs))
    torch.testing.assert_close(split, whole)
