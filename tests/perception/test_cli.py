"""`hamnet perception` start-up: the pre-trained encoder shipped in the package is the default,
random weights only by asking, and a checkpoint that cannot serve stops it with the reason."""

from __future__ import annotations

import json

import pytest

from hamnet.launcher.check import check
from hamnet.launcher.stack import parse
from hamnet.perception.checkpoint import SHIPPED_ENCODER, load_checkpoint
from hamnet.perception.cli import CONFIG, encoder_from, main


def unboxed(capfd) -> str:
    return " ".join("".join(capfd.readouterr()).replace("│", " ").split())


def test_the_shipped_encoder_is_the_default_and_trained() -> None:
    """The package ships trained weights (version >= 1) with their provenance, and a plain
    `hamnet perception` serves them."""
    provenance = json.loads(SHIPPED_ENCODER.with_suffix(".json").read_text())
    assert {"command", "seed", "commit", "encoder_version"} <= provenance.keys()
    encoder, version = encoder_from(CONFIG())
    assert version == provenance["encoder_version"] >= 1
    shipped, _ = load_checkpoint(SHIPPED_ENCODER)
    for (name, mine), (_, theirs) in zip(
        encoder.state_dict().items(), shipped.state_dict().items()
    ):
        assert mine.equal(theirs), name


def test_random_init_and_a_checkpoint_together_are_refused(capfd) -> None:
    with pytest.raises(SystemExit) as exited:
        main(["--random-init", "--checkpoint", "encoder.safetensors"])
    assert exited.value.code == 2
    assert "either --checkpoint PATH or --random-init, not both" in unboxed(capfd)


def test_a_missing_checkpoint_stops_with_its_path(tmp_path, capfd) -> None:
    missing = tmp_path / "none.safetensors"
    assert main(["--checkpoint", str(missing)]) == 2
    assert f"encoder checkpoint {missing} does not exist" in unboxed(capfd)


def test_stack_check_accepts_the_default_and_flags_both_sources() -> None:
    stack = parse({"services": {
        "perception": {},
        "both": {"command": "perception", "workers": [1],
                 "args": {"random-init": True, "checkpoint": "encoder.safetensors"}},
    }}, "t")  # fmt: skip
    verdicts = {v.service: v.status for v in check(stack, {})}
    assert verdicts["perception"] == "ok"
    assert "not both" in " ".join(verdicts["both"].split())
