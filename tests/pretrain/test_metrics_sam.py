"""AUROC against hand-counted examples, and one SAM step against its formula."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from hamnet.pretrain.metrics import auroc, classification
from hamnet.pretrain.sam import cosine_lr, sam_step


def test_auroc_counts_ordered_pairs_and_ties_as_half() -> None:
    """Positives 0.8 and 0.4, negatives 0.5, 0.4 and 0.1: of the 6 (positive, negative) pairs
    0.8 wins 3, 0.4 beats 0.1, ties 0.4 (half) and loses to 0.5: (3 + 1 + 0.5) / 6."""
    scores = np.array([0.8, 0.4, 0.5, 0.4, 0.1])
    labels = np.array([True, True, False, False, False])
    assert auroc(scores, labels) == pytest.approx(4.5 / 6)
    assert auroc(-scores, labels) == pytest.approx(1.5 / 6)
    assert math.isnan(auroc(scores, np.zeros(5, dtype=bool)))


def test_classification_at_a_threshold() -> None:
    scores = np.array([0.9, 0.6, 0.4, 0.2])
    labels = np.array([True, False, True, False])
    metrics = classification(scores, labels, 0.5)
    assert metrics["accuracy"] == 0.5 and metrics["precision"] == 0.5 and metrics["recall"] == 0.5
    assert metrics["balanced_accuracy"] == 0.5 and metrics["auroc"] == 0.75


def test_sam_takes_the_gradient_at_the_perturbed_point() -> None:
    """f(w) = 0.5 w^T A w: SAM with plain SGD moves w by -lr A (w + rho g / |g|), g = A w."""
    a = torch.diag(torch.tensor([1.0, 4.0]))
    w = torch.nn.Parameter(torch.tensor([1.0, 1.0]))
    sgd = torch.optim.SGD([w], lr=0.1)
    rho = 0.5
    g = a @ w.detach()
    expected = w.detach() - 0.1 * (a @ (w.detach() + rho * g / g.norm()))
    loss, grad_norm = sam_step([w], sgd, lambda: 0.5 * w @ a @ w, rho, max_grad_norm=1e3)
    assert torch.allclose(w.detach(), expected)
    assert float(loss) == pytest.approx(2.5)
    assert grad_norm == pytest.approx(float((a @ (torch.ones(2) + rho * g / g.norm())).norm()))


def test_cosine_schedule_runs_from_base_to_min() -> None:
    assert cosine_lr(0, 100, 2e-4, 1e-6) == pytest.approx(2e-4)
    assert cosine_lr(50, 100, 2e-4, 1e-6) == pytest.approx((2e-4 + 1e-6) / 2)
    assert cosine_lr(100, 100, 2e-4, 1e-6) == pytest.approx(1e-6)
