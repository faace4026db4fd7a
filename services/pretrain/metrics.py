"""Binary classification metrics of patch contact prediction: accuracy, precision, recall
at a threshold, AUROC and the ROC curve (scikit-learn is not a dependency)."""

from __future__ import annotations

import numpy as np


def auroc(scores: np.ndarray, labels: np.ndarray) -> float:
    """Area under the ROC curve: the chance that a random positive scores above a random
    negative, ties counting half (the Mann-Whitney U statistic over both counts).

    Args:
        scores: (N,) higher means more likely positive.
        labels: (N,) bool.
    Returns:
        AUROC in [0, 1]; NaN without both classes.
    """
    labels = np.asarray(labels, dtype=bool)
    positives, negatives = int(labels.sum()), int((~labels).sum())
    if positives == 0 or negatives == 0:
        return float("nan")
    _, inverse, counts = np.unique(scores, return_inverse=True, return_counts=True)
    # Mid-ranks (1-based) of tied groups.
    ends = np.cumsum(counts)
    ranks = (ends - (counts - 1) / 2.0)[inverse]
    u = ranks[labels].sum() - positives * (positives + 1) / 2.0
    return float(u / (positives * negatives))


def roc_curve(
    scores: np.ndarray, labels: np.ndarray, points: int = 200
) -> tuple[np.ndarray, np.ndarray]:
    """False and true positive rates (points,) at thresholds spread over the score quantiles."""
    labels = np.asarray(labels, dtype=bool)
    thresholds = np.quantile(scores, np.linspace(1.0, 0.0, points))
    predicted = scores[None, :] >= thresholds[:, None]  # (points, N)
    tpr = (predicted & labels).sum(1) / max(labels.sum(), 1)
    fpr = (predicted & ~labels).sum(1) / max((~labels).sum(), 1)
    return np.r_[0.0, fpr], np.r_[0.0, tpr]


def classification(scores: np.ndarray, labels: np.ndarray, threshold: float) -> dict[str, float]:
    """accuracy, balanced accuracy (mean of the two classes' recalls: the decoder is trained
    on balanced patches, while held-out patches are mostly negative), precision, recall
    (NaN when undefined) at `threshold`, AUROC, positive share."""
    labels = np.asarray(labels, dtype=bool)
    predicted = np.asarray(scores) >= threshold
    true_positive = int((predicted & labels).sum())
    negatives_right = float((~predicted & ~labels).sum() / max((~labels).sum(), 1))
    recall = true_positive / labels.sum() if labels.any() else float("nan")
    return {
        "accuracy": float((predicted == labels).mean()),
        "balanced_accuracy": (recall + negatives_right) / 2,
        "precision": true_positive / predicted.sum() if predicted.any() else float("nan"),
        "recall": float(recall),
        "auroc": auroc(scores, labels),
        "positive_share": float(labels.mean()),
    }
