"""Policies shipped in the package, served by name on a fresh clone.

Each is two files under `hamnet/policy/shipped/`: `<name>.safetensors`, a checkpoint like
any other (`hamnet.policy.weights`; its network stored in float16 to keep the package small)
and `<name>.json`, its card: architecture, action space (absent: "joint", the cards written
before it), stage, the sha256 of the weights file and of the
UniCORN encoder whose tokens it was trained on, the commit and command that trained it, and
the result file that reports it. `read_weights(NAME_OR_PATH)` takes either a checkpoint path
or a shipped name (`hamnet policy --checkpoint easy-teacher`); a shipped policy is checked
against its card as well as like every checkpoint: a file that is not the one its card
describes, or a package encoder other than the one it learned from, is refused.
`scripts/ship_policy.py` writes both files from a finished run.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hamnet.perception.checkpoint import SHIPPED_ENCODER
from hamnet.policy.weights import Weights, WeightsError, from_bytes, read_checkpoint, sha256

SHIPPED_DIR = Path(__file__).resolve().parent / "shipped"
"""Where the package's trained policies are."""


def shipped_names() -> list[str]:
    """Names of the policies shipped in the package."""
    return sorted(path.stem for path in SHIPPED_DIR.glob("*.safetensors"))


def card_path(name: str) -> Path:
    """The card (JSON) of shipped policy `name`."""
    return SHIPPED_DIR / f"{name}.json"


def weights_path(name: str) -> Path:
    """The weights (safetensors) of shipped policy `name`."""
    return SHIPPED_DIR / f"{name}.safetensors"


def resolve(value: str | Path) -> Path:
    """The checkpoint file `value` names: a path as given, or a shipped policy's weights
    when `value` is a shipped name and no such file exists."""
    path = Path(value)
    if not path.exists() and str(value) in shipped_names():
        return weights_path(str(value))
    return path


def read_card(name: str) -> dict[str, Any]:
    """The card of shipped policy `name` (WeightsError when missing or unreadable)."""
    try:
        return json.loads(card_path(name).read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise WeightsError(
            f"shipped policy {name!r}: no readable card {card_path(name)}: {error}"
        ) from None


def encoder_sha256() -> str:
    """sha256 of the package's pre-trained UniCORN encoder file."""
    return sha256(SHIPPED_ENCODER.read_bytes())


def read_shipped(name: str) -> Weights:
    """The weights of shipped policy `name`, checked against its card.

    Raises:
        WeightsError: unknown name, unusable file, a file or encoder other than the card's.
    """
    if name not in shipped_names():
        raise WeightsError(
            f"no shipped policy {name!r}; shipped: {', '.join(shipped_names()) or 'none'}"
        )
    card, data = read_card(name), weights_path(name).read_bytes()
    if sha256(data) != card.get("weights_sha256"):
        raise WeightsError(
            f"shipped policy {name!r}: {weights_path(name).name} is not the file its card describes"
        )
    weights = from_bytes(data)
    if weights.architecture != card.get("architecture"):
        raise WeightsError(
            f"shipped policy {name!r}: weights of {weights.architecture!r}, its card says {card.get('architecture')!r}"
        )
    if weights.config.action_space != card.get("action_space", "joint"):
        raise WeightsError(
            f"shipped policy {name!r}: weights of the {weights.config.action_space!r} action "
            f"space, its card says {card.get('action_space', 'joint')!r}"
        )
    if weights.config.clouds and card.get("encoder_sha256") != encoder_sha256():
        raise WeightsError(
            f"shipped policy {name!r} learned on the tokens of another UniCORN encoder than "
            f"the package's ({SHIPPED_ENCODER.name}): retrain or ship it again"
        )
    return weights


def read_weights(value: str | Path) -> Weights:
    """The weights of a checkpoint path or of a shipped policy's name (WeightsError when
    neither fits)."""
    path = Path(value)
    if path.exists():
        return read_checkpoint(path)
    if str(value) in shipped_names():
        return read_shipped(str(value))
    raise WeightsError(
        f"no checkpoint {value} (a file), nor a shipped policy of that name; "
        f"shipped: {', '.join(shipped_names()) or 'none'}"
    )
