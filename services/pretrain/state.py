"""Checkpoints of a pre-training run, no pickle: in the run folder

- `encoder.safetensors`: the UniCORN encoder alone (`perception.checkpoint.save_checkpoint`,
  loadable by `hamnet perception --checkpoint`), version 1, 2, ... one per save (0 for the
  random-frozen baseline, whose weights are never trained); no file for pointnet;
- `model.safetensors`: every tensor of encoder and decoder (`model.*`) and AdamW's moments
  (`optim.<parameter>.exp_avg`, `.exp_avg_sq`), its metadata naming the step;
- `state.json`: the run's identity (encoder kind, architecture, decoder), counters (step,
  version, training seconds, AdamW's step) and how it was made (data, seed, commit).

`state.json` is written last, and its step must equal the one in `model.safetensors`: a save
cut short is refused on loading rather than mixed with the previous one.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any

import torch
from safetensors.torch import save_file

from hamnet.perception.checkpoint import (
    RANDOM_VERSION,
    CheckpointError,
    read_tensors,
    save_checkpoint,
)
from hamnet.perception.config import EncoderConfig
from hamnet.pretrain.config import DecoderConfig
from hamnet.pretrain.model import ContactModel
from hamnet.runtime.errors import ConfigError

MODEL = "model.safetensors"
STATE = "state.json"
ENCODER = "encoder.safetensors"
STEP_KEY = "hamnet.pretrain.step"
ADAM_STATE = ("step", "exp_avg", "exp_avg_sq")


class RunError(ConfigError):
    """A run folder that cannot be loaded or continued: missing, corrupt or another model."""


def identity(model: ContactModel) -> dict[str, Any]:
    """What a checkpoint must share with the model it is loaded into."""
    decoder = model.decoder
    config = DecoderConfig(width=decoder.out.in_features, blocks=len(decoder.blocks))
    return {
        "encoder": model.kind,
        "architecture": json.loads(model.architecture.to_json()),
        "decoder": dataclasses.asdict(config),
    }


def save_run(
    folder: Path, model: ContactModel, optimizer: torch.optim.Optimizer, counters: dict
) -> None:
    """Write the three files of a checkpoint; `counters` must hold `step` and `version`."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if model.kind != "pointnet":
        version = RANDOM_VERSION if model.kind == "random-frozen" else counters["version"]
        save_checkpoint(folder / ENCODER, model.encoder, version)
    tensors = {f"model.{k}": v.detach().contiguous() for k, v in model.state_dict().items()}
    for name, param in model.named_parameters():
        state = optimizer.state.get(param, {})
        for moment in ADAM_STATE:
            if moment in state:
                tensors[f"optim.{name}.{moment}"] = state[moment].contiguous()
    partial = folder / f"{MODEL}.partial"
    save_file(tensors, str(partial), metadata={STEP_KEY: str(counters["step"])})
    os.replace(partial, folder / MODEL)
    state = {**identity(model), **counters}
    (folder / f"{STATE}.partial").write_text(json.dumps(state, indent=1))
    os.replace(folder / f"{STATE}.partial", folder / STATE)


def read_state(folder: Path) -> dict[str, Any]:
    """The run's `state.json`.

    Raises:
        RunError: no checkpoint in `folder`, or an unreadable one.
    """
    path = Path(folder) / STATE
    if not path.is_file():
        raise RunError(f"{folder} holds no pre-training checkpoint ({STATE} missing)")
    try:
        state = json.loads(path.read_text())
        EncoderConfig.from_json(json.dumps(state["architecture"]))
        DecoderConfig(**state["decoder"])
        int(state["step"])
    except (ValueError, TypeError, KeyError) as error:
        raise RunError(f"{path} is not a valid pre-training state: {error!r}") from None
    return state


def build_model(state: dict[str, Any]) -> ContactModel:
    """An untrained model of the architecture `state` records."""
    architecture = EncoderConfig.from_json(json.dumps(state["architecture"]))
    return ContactModel(state["encoder"], architecture, DecoderConfig(**state["decoder"]))


def load_run(
    folder: Path, model: ContactModel | None = None, optimizer: torch.optim.Optimizer | None = None
) -> tuple[ContactModel, dict[str, Any]]:
    """Load a checkpoint into `model` (None: build the one it records) and `optimizer`.

    Returns:
        The model and the state (counters and identity).
    Raises:
        RunError: missing, corrupt or cut-short files, or a model of another kind,
            architecture or decoder than `model`.
    """
    folder = Path(folder)
    state = read_state(folder)
    if model is None:
        model = build_model(state)
    wanted = identity(model)
    differs = {k: (state.get(k), v) for k, v in wanted.items() if state.get(k) != v}
    if differs:
        raise RunError(f"{folder} was trained with another model (checkpoint, asked): {differs}")
    try:
        tensors, metadata = read_tensors(folder / MODEL)
    except CheckpointError as error:
        raise RunError(str(error)) from None
    step = metadata.get(STEP_KEY)
    if step != str(state["step"]):
        raise RunError(
            f"{folder}: {MODEL} is of step {step}, {STATE} of step {state['step']} (a save cut short)"
        )
    weights = {k[len("model.") :]: v for k, v in tensors.items() if k.startswith("model.")}
    try:
        model.load_state_dict(weights)
    except RuntimeError as error:
        first = str(error).strip().splitlines()
        raise RunError(f"{folder / MODEL} does not fit the model: {' '.join(first[:3])}") from None
    if optimizer is not None:
        for name, param in model.named_parameters():
            moments = {
                m: tensors[f"optim.{name}.{m}"]
                for m in ADAM_STATE
                if f"optim.{name}.{m}" in tensors
            }
            if moments:
                optimizer.state[param] = moments
    return model, state
