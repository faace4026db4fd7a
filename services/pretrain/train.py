"""The pre-training loop: batches of contact pairs, augmented, patch-labelled and balanced,
one SAM step each on a cosine learning-rate schedule (Table tab:pretrain-params), with a
progress line, `metrics.jsonl`, periodic checkpoints, a time budget and resumption.

Every step's randomness is a function of (seed, step) (`batch.step_generator`,
`batch.batch_index`), so a resumed run continues the interrupted one's sequence.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import torch

from hamnet.pretrain.batch import augment, balance_weights, batch_index, step_generator
from hamnet.pretrain.config import TrainConfig
from hamnet.pretrain.dataset import PairArrays, load_pairs
from hamnet.pretrain.model import ContactModel, LossTerms, contact_loss
from hamnet.pretrain.progress import Progress
from hamnet.pretrain.sam import cosine_lr, sam_step
from hamnet.pretrain.state import STATE, RunError, load_run, save_run

log = logging.getLogger(__name__)
METRICS = "metrics.jsonl"


class PairTensors:
    """A dataset as torch tensors (shared memory with the numpy arrays)."""

    def __init__(self, pairs: PairArrays) -> None:
        self.points_a = torch.from_numpy(pairs.points_a)  # (N, P, 3)
        self.points_b = torch.from_numpy(pairs.points_b)
        self.labels_a = torch.from_numpy(pairs.labels_a)  # (N, P)
        self.labels_b = torch.from_numpy(pairs.labels_b)

    def __len__(self) -> int:
        return len(self.points_a)


def train_step(
    model: ContactModel,
    optimizer: torch.optim.Optimizer,
    data: PairTensors,
    step: int,
    config: TrainConfig,
) -> dict[str, float]:
    """One SAM step at `step` (0-based); returns its metrics."""
    generator = step_generator(config.seed, step)
    index = batch_index(step, config.batch_size, len(data), config.seed)  # (B,)
    a, b = augment(data.points_a[index], data.points_b[index], config.augment, generator)
    labels = model.labels(a, b, data.labels_a[index], data.labels_b[index])  # (2BK,)
    weights = balance_weights(labels, config.positive_fraction)
    model.freeze_encoder(step < config.encoder_warmup)
    lr = cosine_lr(step, config.steps, config.optim.lr, config.optim.min_lr)
    for group in optimizer.param_groups:
        group["lr"] = lr * group["lr_scale"]
    first: list[LossTerms] = []

    def closure() -> torch.Tensor:
        terms = contact_loss(model, a, b, labels, weights)
        first.append(terms)
        return terms.loss

    params = [p for group in optimizer.param_groups for p in group["params"]]
    loss, grad_norm = sam_step(
        params, optimizer, closure, config.optim.sam_rho, config.optim.max_grad_norm
    )
    return {
        "loss": float(loss),
        "accuracy": first[0].accuracy,
        "positive_share": first[0].positive_share,
        "lr": lr,
        "grad_norm": grad_norm,
    }


def new_optimizer(model: ContactModel, config: TrainConfig) -> torch.optim.Optimizer:
    """AdamW (SAM's base optimiser) over the decoder and, unless frozen for good, the encoder,
    each group with the share of the scheduled rate it takes (`lr_scale`)."""
    groups = [{"params": list(model.decoder.parameters()), "lr_scale": 1.0}]
    if config.encoder != "random-frozen":
        groups.append(
            {"params": list(model.encoder.parameters()), "lr_scale": config.encoder_lr_scale}
        )
    return torch.optim.AdamW(groups, lr=config.optim.lr, weight_decay=config.optim.weight_decay)


def _mean(rows: list[dict[str, float]]) -> dict[str, float]:
    return {key: sum(r[key] for r in rows) / len(rows) for key in rows[0]}


def _save(
    folder: Path, model: ContactModel, optimizer: torch.optim.Optimizer, counters: dict
) -> int:
    """Write a checkpoint with the next encoder version; returns the step saved."""
    counters["version"] += 1
    save_run(folder, model, optimizer, counters)
    return counters["step"]


def train(config: TrainConfig, commit: str = "") -> dict:
    """Train (or resume) the run in `config.out`; returns its final state.

    Raises:
        RunError: --resume without a checkpoint, a checkpoint of another model, or a fresh
            run into a folder that holds one.
        ConfigError: the dataset is missing or unfinished.
    """
    folder = Path(config.out)
    data = PairTensors(load_pairs(config.data, config.max_pairs))
    if len(data) < config.batch_size:
        raise RunError(
            f"the dataset has {len(data)} pairs, fewer than --batch-size {config.batch_size}"
        )
    torch.manual_seed(config.seed)
    model = ContactModel(config.encoder, config.architecture, config.decoder)
    optimizer = new_optimizer(model, config)
    counters = {
        "step": 0,
        "version": 0,
        "train_s": 0.0,
        "seed": config.seed,
        "data": str(config.data),
        "pairs": len(data),
        "steps": config.steps,
        "batch_size": config.batch_size,
        "commit": commit,
    }
    if config.resume:
        _, state = load_run(folder, model, optimizer)
        counters.update({k: state[k] for k in ("step", "version", "train_s")})
        log.info("resuming %s at step %d", folder, counters["step"])
    elif (folder / STATE).is_file():
        raise RunError(
            f"{folder} already holds a run: pass --resume to continue it, or another --out"
        )
    folder.mkdir(parents=True, exist_ok=True)
    model.train()
    progress = Progress("train", config.steps, "steps", 10.0, counters["step"])
    started, rows, saved = time.monotonic(), [], counters["step"]
    logged = started
    with open(folder / METRICS, "a") as metrics:
        while counters["step"] < config.steps:
            if config.max_minutes and time.monotonic() - started >= 60 * config.max_minutes:
                log.info(
                    "time budget of %.1f min spent at step %d", config.max_minutes, counters["step"]
                )
                break
            tick = time.monotonic()
            rows.append(train_step(model, optimizer, data, counters["step"], config))
            counters["step"] += 1
            counters["train_s"] += time.monotonic() - tick
            if counters["step"] % config.log_every == 0 or counters["step"] == config.steps:
                row = {
                    "step": counters["step"],
                    **_mean(rows),
                    "train_s": round(counters["train_s"], 2),
                }
                row["pairs_per_s"] = (
                    len(rows) * config.batch_size / max(time.monotonic() - logged, 1e-9)
                )
                logged = time.monotonic()
                metrics.write(json.dumps(row) + "\n")
                metrics.flush()
                progress.advance(
                    len(rows), f", loss {row['loss']:.4f}, accuracy {row['accuracy']:.3f}"
                )
                rows = []
            if counters["step"] % config.checkpoint_every == 0:
                saved = _save(folder, model, optimizer, counters)
    if counters["step"] != saved:
        _save(folder, model, optimizer, counters)
    log.info(
        "saved %s at step %d (encoder version %d)", folder, counters["step"], counters["version"]
    )
    return counters
