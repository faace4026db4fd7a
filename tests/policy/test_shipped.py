"""Policies shipped in the package: served by name, checked against their cards, stored in
half precision where it is safe."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from hamnet.policy import shipped
from hamnet.policy.registry import build
from hamnet.policy.weights import WeightsError, from_bytes, policy_from, sha256, to_bytes


def ship(folder: Path, name: str, architecture: str, **card: object) -> bytes:
    """A randomly initialised policy shipped under `folder` as `name` (half network)."""
    data = to_bytes(build(architecture, seed=0), version=7, half=True)
    (folder / f"{name}.safetensors").write_bytes(data)
    fields = {"architecture": architecture, "weights_sha256": sha256(data),
              "encoder_sha256": shipped.encoder_sha256(), **card}  # fmt: skip
    (folder / f"{name}.json").write_text(json.dumps(fields))
    return data


@pytest.fixture
def shelf(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr(shipped, "SHIPPED_DIR", tmp_path)
    return tmp_path


def test_a_half_precision_file_serves_float32_close_to_the_original() -> None:
    """Network tensors travel as float16 and come back float32 (what the model holds);
    input statistics and log std stay exact."""
    policy = build("state-mlp", seed=0)
    weights = from_bytes(to_bytes(policy, 3, half=True))
    for name, tensor in policy.state_dict().items():
        got = weights.tensors[name]
        assert got.dtype == tensor.dtype, name
        if name.startswith("network."):
            torch.testing.assert_close(got, tensor, rtol=1e-3, atol=1e-4)
        else:
            assert torch.equal(got, tensor), name
    policy_from(weights)  # passes every checkpoint check


def test_a_shipped_policy_is_read_by_name_and_a_path_still_works(shelf: Path) -> None:
    ship(shelf, "pusher", "state-mlp")
    assert shipped.shipped_names() == ["pusher"]
    assert shipped.read_weights("pusher").architecture == "state-mlp"
    assert shipped.read_weights(shelf / "pusher.safetensors").version == 7
    assert shipped.resolve("pusher") == shelf / "pusher.safetensors"


def test_an_unknown_name_lists_the_shipped_ones(shelf: Path) -> None:
    ship(shelf, "pusher", "state-mlp")
    with pytest.raises(WeightsError, match="shipped: pusher"):
        shipped.read_weights("nope")


def test_a_file_that_is_not_its_cards_is_refused(shelf: Path) -> None:
    data = ship(shelf, "pusher", "state-mlp")
    (shelf / "pusher.safetensors").write_bytes(to_bytes(build("state-mlp", seed=1), 7, half=True))
    with pytest.raises(WeightsError, match="not the file its card describes"):
        shipped.read_weights("pusher")
    (shelf / "pusher.safetensors").write_bytes(data)
    card = json.loads((shelf / "pusher.json").read_text())
    (shelf / "pusher.json").write_text(json.dumps({**card, "architecture": "hamnet"}))
    with pytest.raises(WeightsError, match="its card says 'hamnet'"):
        shipped.read_weights("pusher")
    (shelf / "pusher.json").write_text(json.dumps({**card, "action_space": "paddle"}))
    with pytest.raises(WeightsError, match="'joint' action space, its card says 'paddle'"):
        shipped.read_weights("pusher")


def test_a_policy_of_another_encoder_is_refused_where_it_reads_tokens(shelf: Path) -> None:
    """Tokens of another encoder mean nothing to a HAMnet trained on the package's; the
    state baseline reads no tokens, so its encoder does not matter."""
    ship(shelf, "hamnet-other", "hamnet", encoder_sha256="0" * 64)
    ship(shelf, "mlp-other", "state-mlp", encoder_sha256="0" * 64)
    with pytest.raises(WeightsError, match="another UniCORN encoder"):
        shipped.read_weights("hamnet-other")
    assert shipped.read_weights("mlp-other").architecture == "state-mlp"


@pytest.mark.parametrize("name", shipped.shipped_names())
def test_every_policy_shipped_in_the_package_loads_and_matches_its_card(name: str) -> None:
    card = shipped.read_card(name)
    policy = policy_from(shipped.read_shipped(name))
    assert policy.architecture == card["architecture"]
    assert policy.config.action_space == card.get("action_space", "joint")
    for key in ("stage", "commit", "result", "trained_by", "shipped_success_rate"):
        assert card.get(key) is not None, key
    assert not Path(card["result"]).is_absolute()
    assert (Path(__file__).resolve().parents[2] / card["result"]).exists()
