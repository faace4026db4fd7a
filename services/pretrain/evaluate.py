"""Held-out evaluation of pre-training runs: every patch of every held-out pair, both roles,
no augmentation or balancing; accuracy, precision, recall and AUROC of contact per run, a
JSON summary and a PNG of the training loss curves and ROC curves.

The JSON's top-level `heldout_auroc` and `heldout_accuracy` are the first run's (the
UniCORN run; the others are baselines under `runs`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display on a training machine
import matplotlib.pyplot as plt
import numpy as np
import torch

from hamnet.pretrain.config import EvalConfig
from hamnet.pretrain.dataset import load_pairs
from hamnet.pretrain.metrics import classification, roc_curve
from hamnet.pretrain.model import ContactModel
from hamnet.pretrain.state import load_run
from hamnet.pretrain.train import METRICS, PairTensors
from hamnet.runtime.runs import read_metrics


@torch.no_grad()
def predict(
    model: ContactModel, data: PairTensors, batch_size: int
) -> tuple[np.ndarray, np.ndarray]:
    """Contact probabilities and labels of every patch, both roles: two (N 2 K,) arrays."""
    model.eval()
    scores, labels = [], []
    for start in range(0, len(data), batch_size):
        rows = slice(start, start + batch_size)
        a, b = data.points_a[rows], data.points_b[rows]
        scores.append(torch.sigmoid(model(a, b)).numpy())
        labels.append(model.labels(a, b, data.labels_a[rows], data.labels_b[rows]).numpy())
    return np.concatenate(scores), np.concatenate(labels)


def evaluate(config: EvalConfig) -> dict:
    """Evaluate every run of `config` on the held-out pairs; writes the JSON and PNG."""
    data = PairTensors(load_pairs(config.data, config.max_pairs))
    results, curves = {}, {}
    for run in config.runs:
        model, state = load_run(run)
        scores, labels = predict(model, data, config.batch_size)
        results[str(run)] = {
            "encoder": state["encoder"],
            "step": state["step"],
            "train_s": state["train_s"],
            **classification(scores, labels, config.threshold),
        }
        rows = read_metrics(Path(run)) if (Path(run) / METRICS).is_file() else []
        curves[str(run)] = (rows, roc_curve(scores, labels))
    first = results[str(config.runs[0])]
    summary = {
        "heldout_auroc": first["auroc"],
        "heldout_accuracy": first["accuracy"],
        "data": str(config.data),
        "pairs": len(data),
        "threshold": config.threshold,
        "runs": results,
    }
    out = Path(config.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(_finite(summary), indent=1))
    plot(curves, results, out.with_suffix(".png"))
    return summary


def _finite(value):
    """`value` with NaN (an undefined metric) as None, which JSON can hold."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    return None if isinstance(value, float) and math.isnan(value) else value


def plot(curves: dict, results: dict, out: Path) -> Path:
    """Training loss against step, and held-out ROC, one line per run."""
    figure, (loss_axis, roc_axis) = plt.subplots(1, 2, figsize=(11, 4.5))
    for run, (rows, (fpr, tpr)) in curves.items():
        name = f"{Path(run).name} ({results[run]['encoder']})"
        if rows:
            loss_axis.plot([r["step"] for r in rows], [r["loss"] for r in rows], label=name)
        roc_axis.plot(fpr, tpr, label=f"{name}: AUROC {results[run]['auroc']:.3f}")
    loss_axis.set(xlabel="step", ylabel="BCE (balanced patches)", title="training loss")
    roc_axis.plot([0, 1], [0, 1], color="grey", linestyle=":")
    roc_axis.set(
        xlabel="false positive rate",
        ylabel="true positive rate",
        title="held-out patch contact ROC",
    )
    for axis in (loss_axis, roc_axis):
        axis.legend(fontsize=8)
        axis.grid(alpha=0.3)
    figure.tight_layout()
    figure.savefig(out, dpi=120)
    plt.close(figure)
    return out
