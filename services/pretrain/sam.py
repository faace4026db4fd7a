"""Sharpness-aware minimisation (SAM, Foret et al. 2021), the optimiser of UniCORN
pre-training (Table tab:pretrain-params), around any torch optimiser.

One step: the gradient g at w; the weights moved to the worst nearby point
w + rho g / |g|; the gradient there; the weights moved back; that gradient (clipped to
`max_grad_norm`) taken by the base optimiser. Each step costs two forward-backward passes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import torch


def sam_step(
    params: Sequence[torch.Tensor],
    base: torch.optim.Optimizer,
    closure: Callable[[], torch.Tensor],
    rho: float,
    max_grad_norm: float,
) -> tuple[torch.Tensor, float]:
    """One SAM step on `params`.

    Args:
        params: the trained tensors (those `base` updates).
        base: the optimiser that takes the sharpness-aware gradient (AdamW here).
        closure: computes the loss on the step's batch and returns it (not yet backpropagated);
            called twice, so it must see the same batch both times.
        rho: radius of the neighbourhood, in parameter norm (0: plain base step).
        max_grad_norm: clip of the second gradient's total norm.
    Returns:
        The loss at the unperturbed weights and the second gradient's norm before clipping.
    """
    params = [p for p in params if p.requires_grad]
    base.zero_grad(set_to_none=True)
    loss = closure()
    loss.backward()
    with torch.no_grad():
        grads = [p.grad if p.grad is not None else torch.zeros_like(p) for p in params]
        scale = rho / (torch.linalg.vector_norm(torch.stack([g.norm() for g in grads])) + 1e-12)
        steps = [g * scale for g in grads]
        for p, e in zip(params, steps):
            p.add_(e)
    base.zero_grad(set_to_none=True)
    closure().backward()
    with torch.no_grad():
        for p, e in zip(params, steps):
            p.sub_(e)
    grad_norm = float(torch.nn.utils.clip_grad_norm_(params, max_grad_norm))
    base.step()
    return loss.detach(), grad_norm


def cosine_lr(step: int, steps: int, lr: float, min_lr: float) -> float:
    """Learning rate at `step` of `steps`: from `lr` down to `min_lr` along half a cosine."""
    progress = min(step / max(steps, 1), 1.0)
    return min_lr + 0.5 * (lr - min_lr) * (1.0 + math.cos(math.pi * progress))
