"""Building blocks of the policy networks: cross-attention over tokens, plain MLPs, and the
module bank whose per-sample mixture is a contraction over the module axis.

Hidden layers of the actor, critic and modulation networks are Linear -> LayerNorm (no
affine, as in the authors' code) -> tanh; output layers are linear. The cross-attention
embeddings use the authors' Linear -> LayerNorm -> GELU.
Shapes: B batch, N tokens, D token width, M modules, J in, I out.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import torch
from torch import Tensor, nn
from torch.nn import functional as F


def hidden_activation(x: Tensor) -> Tensor:
    """LayerNorm without affine parameters, then tanh (every hidden layer of every network)."""
    return torch.tanh(F.layer_norm(x, x.shape[-1:]))


class MLP(nn.Module):
    """Linear layers with `hidden_activation` between them; the last layer is linear unless
    `activate_last` (an embedding rather than an output)."""

    def __init__(self, dims: Sequence[int], activate_last: bool = False) -> None:
        super().__init__()
        self.layers = nn.ModuleList(nn.Linear(i, o) for i, o in itertools.pairwise(dims))
        self.activate_last = activate_last

    def forward(self, x: Tensor) -> Tensor:
        """(B, dims[0]) -> (B, dims[-1])."""
        for index, layer in enumerate(self.layers):
            x = layer(x)
            if self.activate_last or index < len(self.layers) - 1:
                x = hidden_activation(x)
        return x


def gelu_mlp(dims: Sequence[int], activate_last: bool = False) -> nn.Sequential:
    """Linear -> LayerNorm -> GELU between layers: the authors' MLP with use_ln and GELU
    (ham/models/common.py:419-466), used by their cross-attention embeddings."""
    layers: list[nn.Module] = []
    for index, (i, o) in enumerate(itertools.pairwise(dims)):
        layers.append(nn.Linear(i, o))
        if activate_last or index < len(dims) - 2:
            layers += [nn.LayerNorm(o), nn.GELU()]
    return nn.Sequential(*layers)


class CrossAttention(nn.Module):
    """One query per sample attends over N tokens with H heads, then a projection MLP: the
    authors' cross-attentions (hypernet_modular.py:627-723, 795-804).

    `embed_tokens` False (object tokens): query = linear (their embed_query, then the
    attention's W_q: two linear maps, one here), tokens enter raw (their to_kv is linear).
    True (scene tokens, their cross_big): query and tokens each pass a Linear-LN-GELU
    embedding of width E first (embed_robot, kv_gr), the query then W_q.

    The key and value projections are absorbed into the query side: q_h . (W_k,h t_n)
    equals (W_k,h^T q_h) . t_n and sum_n a_n W_v,h t_n equals W_v,h sum_n a_n t_n, so the
    tokens are never projected by them: O(H N D) per sample instead of O(N D E). Key biases
    shift every score of a query equally (softmax ignores them) and value biases pass
    through the convex sum into the output bias, so nothing is lost (checked against a
    standard implementation in the tests). The attention's output projection and the
    first layer of the projection MLP (E, *out_dims) are two linear maps, one here.
    """

    def __init__(
        self,
        query_dim: int,
        token_dim: int,
        dim: int,
        heads: int,
        out_dims: Sequence[int],
        embed_tokens: bool,
    ) -> None:
        super().__init__()
        self.heads, self.head_dim = heads, dim // heads
        self.query = (
            nn.Sequential(gelu_mlp((query_dim, dim), activate_last=True), nn.Linear(dim, dim))
            if embed_tokens
            else nn.Linear(query_dim, dim)
        )
        self.embed = gelu_mlp((token_dim, dim), activate_last=True) if embed_tokens else None
        keys = dim if embed_tokens else token_dim
        self.key = nn.Parameter(torch.empty(heads, self.head_dim, keys))  # (H, E/H, D')
        self.value = nn.Parameter(torch.empty(heads, self.head_dim, keys))  # (H, E/H, D')
        self.out = gelu_mlp((dim, *out_dims))
        self.width = out_dims[-1]
        bound = 1.0 / math.sqrt(keys)
        nn.init.uniform_(self.key, -bound, bound)
        nn.init.uniform_(self.value, -bound, bound)

    def forward(self, query: Tensor, tokens: Tensor, repeated: bool = False) -> Tensor:
        """(B, Q) queries over (B, N, D) tokens -> (B, out_dims[-1]) summaries.

        `repeated`: many samples share their tokens (a scene's, constant through an
        episode, in a minibatch of many steps of few episodes), so each distinct token set
        is embedded once (`distinct_rows`): the same result, at 2048 samples of a rollout
        of 64 environments a 15-20th of the embedding's work.
        """
        b = query.shape[0]
        if self.embed is not None:
            if repeated:
                distinct, index = distinct_rows(tokens)
                tokens = self.embed(distinct)[index]  # (B, N, E)
            else:
                tokens = self.embed(tokens)  # (B, N, E)
        q = self.query(query).view(b, self.heads, self.head_dim).transpose(0, 1)  # (H, B, E/H)
        # Batched over heads, not broadcast over samples: broadcasting would copy the
        # projections B times.
        q_key = (q @ self.key).transpose(0, 1) / math.sqrt(self.head_dim)  # (B, H, D')
        attention = torch.softmax(q_key @ tokens.transpose(1, 2), dim=-1)  # (B, H, N)
        mixed = (attention @ tokens).transpose(0, 1)  # (H, B, D')
        heads = (mixed @ self.value.transpose(1, 2)).transpose(0, 1).reshape(b, -1)  # (B, E)
        return self.out(heads)


def distinct_rows(x: Tensor) -> tuple[Tensor, Tensor]:
    """The distinct rows of x (B, ...) and where each row of x is among them: (U, ...) and
    (B,) long, x == distinct[index] exactly.

    Rows are matched by one random projection of their values, then checked element for
    element; if two different rows ever shared a projection, every row counts as
    distinct. Costs one (B, prod(...)) product and one comparison.
    """
    b = len(x)
    rows = torch.arange(b, device=x.device)
    if b == 0:
        return x, rows
    flat = x.reshape(b, -1)
    probe = torch.rand(flat.shape[1], generator=torch.Generator().manual_seed(0))
    with torch.autocast(x.device.type, enabled=False):  # keys in float32 under autocast too
        keys = flat.float() @ probe.to(x.device)  # (B,)
    _, index = torch.unique(keys, return_inverse=True)  # (B,) into the U sorted keys
    first = torch.full((int(index.max()) + 1,), b, device=x.device).scatter_reduce(
        0, index, rows, "amin"
    )  # (U,) a row of x with each key
    if not torch.equal(flat[first[index]], flat):
        return x, rows
    return x[first], index


MIXTURE_CHUNK = 1024
"""Rows of the batch mixed at a time. The (rows, M*J) scaled inputs of a whole large batch
(67 MB per layer at 8192) fall out of the CPU caches; chunks of 512-1024 rows trained 15-20%
faster at batch 8192 and the same at 1024 (measured on the 2-core CPU)."""


def _scaled(x: Tensor, weights: Tensor) -> Tensor:
    """(rows, M*J): each sample's input copied once per module and scaled by its weight."""
    return (weights.unsqueeze(2) * x.unsqueeze(1)).reshape(len(x), -1)


class _ModuleMixture(torch.autograd.Function):
    """y = (w (x) x) @ W_stacked: the contraction over modules, with a hand-written backward
    (autograd's reduces two materialised (B, M, J) products; here the input gradient is a
    batched mat-vec, measured faster on the CPU). Works `MIXTURE_CHUNK` rows at a time and,
    beyond one chunk, recomputes the scaled inputs in the backward instead of keeping them."""

    @staticmethod
    @torch.amp.custom_fwd(device_type="cpu", cast_inputs=torch.bfloat16)
    def forward(ctx, x: Tensor, weights: Tensor, stacked: Tensor) -> Tensor:
        """Under autocast (a bfloat16 update) every input is cast to bfloat16, as a linear
        layer's are; otherwise they keep their dtype."""
        out = x.new_empty(len(x), stacked.shape[1])  # (B, I)
        chunks = _chunks(len(x))
        for rows in chunks:
            scaled = _scaled(x[rows], weights[rows])  # (rows, M*J)
            torch.mm(scaled, stacked, out=out[rows])
        # A batch of one chunk keeps its scaled inputs for the backward (2-3% of HAMnet's
        # training step at batch 1024); larger batches recompute them chunk by chunk.
        ctx.scaled = scaled if len(chunks) == 1 else None
        ctx.save_for_backward(x, weights, stacked)
        return out

    @staticmethod
    @torch.amp.custom_bwd(device_type="cpu")
    def backward(ctx, grad: Tensor) -> tuple[Tensor | None, ...]:
        x, weights, stacked = ctx.saved_tensors
        inputs = ctx.needs_input_grad[0] or ctx.needs_input_grad[1]
        grad_x = torch.empty_like(x) if inputs else None  # (B, J)
        grad_weights = torch.empty_like(weights) if inputs else None  # (B, M)
        grad_stacked = torch.zeros_like(stacked) if ctx.needs_input_grad[2] else None  # (M*J, I)
        for rows in _chunks(len(x)):
            if grad_stacked is not None:
                scaled = ctx.scaled if ctx.scaled is not None else _scaled(x[rows], weights[rows])
                grad_stacked.addmm_(scaled.T, grad[rows])
            if inputs:
                grad_scaled = (grad[rows] @ stacked.T).view(-1, weights.shape[1], x.shape[1])
                grad_x[rows] = (weights[rows].unsqueeze(1) @ grad_scaled).squeeze(1)
                grad_weights[rows] = (grad_scaled @ x[rows].unsqueeze(2)).squeeze(2)  # (rows, M)
        return grad_x, grad_weights, grad_stacked


def _chunks(batch: int) -> list[slice]:
    return [slice(start, start + MIXTURE_CHUNK) for start in range(0, batch, MIXTURE_CHUNK)]


class ModularLinear(nn.Module):
    """A bank of M linear modules mixed per sample: y = g * (sum_m w_m W_m x + sum_m v_m b_m),
    with separate module weights w, v for the weights and the bias, as the authors'
    GateModMLP (gate_mod_mlp.py:181-200), and one per-unit gate g (the paper's; the authors
    also give the bias its own gate, see docs/policy.md).

    The mixture is one contraction over the module axis: the sample's module weights scale
    copies of its input, (B, M*J), which one GEMM maps through the stacked modules
    (M*J, I). Per-sample weight matrices (B, I, J) are never built, and the cost is that of
    a single linear layer M times as wide at the input.
    """

    def __init__(self, in_dim: int, out_dim: int, num_modules: int) -> None:
        super().__init__()
        self.in_dim, self.out_dim, self.num_modules = in_dim, out_dim, num_modules
        bound = 1.0 / math.sqrt(in_dim)  # nn.Linear's initialisation, module by module
        self.weight = nn.Parameter(
            torch.empty(num_modules, in_dim, out_dim).uniform_(-bound, bound)
        )
        self.bias = nn.Parameter(torch.empty(num_modules, out_dim).uniform_(-bound, bound))

    def forward(
        self, x: Tensor, weights: Tensor, bias_weights: Tensor, gate: Tensor | None
    ) -> Tensor:
        """Mix the modules for each sample.

        Args:
            x: (B, J) inputs.
            weights: (B, M) softmax over modules for the weight matrices.
            bias_weights: (B, M) softmax over modules for the biases.
            gate: (B, I) per-unit gates, or None.

        Returns:
            (B, I) outputs.
        """
        stacked = self.weight.view(-1, self.out_dim)  # (M*J, I)
        y = _ModuleMixture.apply(x, weights, stacked) + bias_weights @ self.bias  # (B, I)
        return y if gate is None else y * gate


class ModularMLP(nn.Module):
    """Base network of HAMnet: one module bank per layer (`ModularLinear`)."""

    def __init__(self, dims: Sequence[int], num_modules: int) -> None:
        super().__init__()
        self.layers = nn.ModuleList(
            ModularLinear(i, o, num_modules) for i, o in itertools.pairwise(dims)
        )

    @property
    def out_dims(self) -> list[int]:
        """Output width of every layer (the widths the gates scale)."""
        return [layer.out_dim for layer in self.layers]

    def forward(
        self, x: Tensor, weights: Tensor, bias_weights: Tensor, gates: Sequence[Tensor | None]
    ) -> Tensor:
        """(B, J) -> (B, out) with (B, L, M) module weights and, per layer, its gates (B, D_l)
        (None: ungated; the output layer never has any, hypernet_modular.py:956-962)."""
        for index, layer in enumerate(self.layers):
            x = layer(x, weights[:, index], bias_weights[:, index], gates[index])
            if index < len(self.layers) - 1:
                x = hidden_activation(x)
        return x
