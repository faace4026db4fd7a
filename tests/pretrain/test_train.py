"""Training on a tiny dataset: the loss falls, checkpoints load into perception, resume
continues, and bad or mismatched checkpoints are refused with one clear line."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import torch

from hamnet.cli import main
from hamnet.perception.checkpoint import load_checkpoint
from hamnet.pretrain.batch import balance_weights
from hamnet.pretrain.config import AugmentConfig, GenerateConfig, OptimConfig, TrainConfig
from hamnet.pretrain.dataset import generate, load_pairs
from hamnet.pretrain.model import ContactModel, contact_loss
from hamnet.pretrain.state import ENCODER, MODEL, STATE, RunError, load_run, save_run
from hamnet.pretrain.train import METRICS, PairTensors, new_optimizer, train, train_step

STILL = AugmentConfig(rotation=0.0, translation=0.0, log_scale=0.0, noise=0.0)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("pretrain") / "data"
    generate(GenerateConfig(out=folder, pairs=300, chunk_size=100))
    return folder


def fixed_loss(model: ContactModel, data: PairTensors) -> float:
    """The balanced loss on the first 64 pairs, no augmentation."""
    model.train()
    a, b = data.points_a[:64], data.points_b[:64]
    labels = model.labels(a, b, data.labels_a[:64], data.labels_b[:64])
    with torch.no_grad():
        return float(contact_loss(model, a, b, labels, balance_weights(labels, 0.5)).loss)


def test_balance_weights_put_the_target_share_on_positives() -> None:
    labels = torch.tensor([True, False, False, False, True, False])
    weights = balance_weights(labels, 0.5)
    assert torch.isclose(weights.sum(), torch.tensor(1.0))
    assert torch.isclose(weights[labels].sum(), torch.tensor(0.5))
    assert torch.allclose(weights[labels], weights[labels][0])  # equal within a kind
    none = balance_weights(torch.zeros(4, dtype=torch.bool), 0.5)
    assert torch.allclose(none, torch.full((4,), 0.25))


def test_the_decoder_sees_every_patch_once(data) -> None:
    """Duplicated patches in the decoder's batch let its batch norm find the positives from the
    batch statistics (the paper's resampling drawn literally did that): each patch of both
    roles goes through once."""
    pairs = PairTensors(load_pairs(data))
    model = ContactModel("unicorn", TrainConfig().architecture, TrainConfig().decoder).train()
    a, b = pairs.points_a[:8], pairs.points_b[:8]
    labels = model.labels(a, b, pairs.labels_a[:8], pairs.labels_b[:8])
    seen = []
    model.decoder.register_forward_hook(lambda module, inputs, output: seen.append(inputs[0]))
    contact_loss(model, a, b, labels, balance_weights(labels, 0.5))
    (rows,) = seen
    assert len(rows) == len(labels) == 2 * 8 * model.architecture.num_patches
    assert len(torch.unique(rows, dim=0)) == len(rows)


def test_a_tiny_run_lowers_the_loss(data, tmp_path) -> None:
    config = TrainConfig(data=data, out=tmp_path / "run", steps=30, batch_size=16, augment=STILL,
                         optim=OptimConfig(lr=1e-3), log_every=5)  # fmt: skip
    pairs = PairTensors(load_pairs(data))
    torch.manual_seed(config.seed)
    before = fixed_loss(ContactModel("unicorn", config.architecture, config.decoder), pairs)
    state = train(config)
    after = fixed_loss(load_run(config.out)[0], pairs)
    assert after < before - 0.05, (before, after)
    assert state["step"] == 30
    rows = [json.loads(line) for line in (config.out / METRICS).read_text().splitlines()]
    assert [r["step"] for r in rows] == [5, 10, 15, 20, 25, 30]


def test_the_encoder_checkpoint_loads_into_perception_and_resume_continues(data, tmp_path) -> None:
    config = TrainConfig(data=data, out=tmp_path / "run", steps=2, batch_size=8, checkpoint_every=1)
    train(config)
    _, version = load_checkpoint(config.out / ENCODER, config.architecture)
    assert version == 2  # one per checkpoint, from 1 up
    state = train(dataclasses.replace(config, steps=3, resume=True))
    assert state["step"] == 3 and load_checkpoint(config.out / ENCODER)[1] == 3
    with pytest.raises(RunError, match="already holds a run"):
        train(config)


def test_the_encoder_waits_for_the_decoder_and_a_resume_is_exact(data, tmp_path) -> None:
    """With `encoder_warmup` 2 only the decoder learns for two steps, then both (the encoder
    at a quarter of the rate); a run saved after three steps and resumed takes the fourth
    exactly as the uninterrupted one (each parameter keeps its own Adam step count)."""
    config = TrainConfig(data=data, steps=4, batch_size=8, encoder_warmup=2, encoder_lr_scale=0.25)
    pairs = PairTensors(load_pairs(data))

    def fresh() -> tuple[ContactModel, torch.optim.Optimizer]:
        torch.manual_seed(config.seed)
        model = ContactModel("unicorn", config.architecture, config.decoder).train()
        return model, new_optimizer(model, config)

    def snapshot(module: torch.nn.Module) -> list[torch.Tensor]:
        return [p.detach().clone() for p in module.parameters()]

    model, optimizer = fresh()
    encoder, decoder = snapshot(model.encoder), snapshot(model.decoder)
    rows = [train_step(model, optimizer, pairs, step, config) for step in range(2)]
    assert all(torch.equal(p, q) for p, q in zip(encoder, model.encoder.parameters()))
    assert not all(torch.equal(p, q) for p, q in zip(decoder, model.decoder.parameters()))
    train_step(model, optimizer, pairs, 2, config)
    assert not all(torch.equal(p, q) for p, q in zip(encoder, model.encoder.parameters()))
    assert [g["lr_scale"] for g in optimizer.param_groups] == [1.0, 0.25]
    save_run(tmp_path / "run", model, optimizer, {"step": 3, "version": 1})
    train_step(model, optimizer, pairs, 3, config)

    resumed, resumed_optimizer = fresh()
    load_run(tmp_path / "run", resumed, resumed_optimizer)
    train_step(resumed, resumed_optimizer, pairs, 3, config)
    for (name, p), q in zip(model.named_parameters(), resumed.parameters()):
        assert torch.equal(p, q), name
    assert rows[0]["lr"] == config.optim.lr


@pytest.mark.parametrize("kind", ["random-frozen", "pointnet"])
def test_baselines_train_and_reload(kind, data, tmp_path) -> None:
    config = TrainConfig(data=data, out=tmp_path / kind, encoder=kind, steps=2, batch_size=8)
    train(config)
    model, state = load_run(config.out)
    assert state["encoder"] == kind and model.kind == kind
    assert (config.out / ENCODER).is_file() == (kind == "random-frozen")
    if kind == "random-frozen":
        torch.manual_seed(config.seed)
        fresh = ContactModel(kind, config.architecture, config.decoder)
        assert all(
            torch.equal(p, q)
            for p, q in zip(fresh.encoder.parameters(), model.encoder.parameters())
        )
        assert load_checkpoint(config.out / ENCODER)[1] == 0  # never trained: random version


def test_corrupt_cut_short_and_mismatched_checkpoints_are_refused(data, tmp_path) -> None:
    config = TrainConfig(data=data, out=tmp_path / "run", steps=1, batch_size=8)
    train(config)
    with pytest.raises(RunError, match="another model"):
        load_run(config.out, ContactModel("pointnet", config.architecture, config.decoder))
    state = json.loads((config.out / STATE).read_text())
    (config.out / STATE).write_text(json.dumps({**state, "step": 7}))
    with pytest.raises(RunError, match="cut short"):
        load_run(config.out)
    (config.out / MODEL).write_bytes(b"not a safetensors file")
    with pytest.raises(RunError, match="not a readable safetensors"):
        load_run(config.out)


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys) -> None:
    assert main(["pretrain", "train", "--data", str(tmp_path / "missing")]) == 2
    assert (
        main(["pretrain", "eval", "--data", str(tmp_path), "--runs", str(tmp_path / "none")]) == 2
    )
    assert main(["pretrain", "fit"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 3 and all("hamnet pretrain" in line for line in lines), lines
