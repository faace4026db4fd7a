"""The one-page training loop (`examples/train_loop.py`) a newcomer reads runs on today's
cores: if a core's interface changes, the example breaks here, not in a reader's hands."""

from __future__ import annotations

import math

from tests.script_modules import load


def test_the_one_page_loop_collects_and_updates() -> None:
    rows = load("examples/train_loop.py").train(iterations=2, num_envs=4, steps=8)
    assert [row["env_transitions"] for row in rows] == [32, 64]
    assert all(math.isfinite(row["value_loss"]) for row in rows)
    assert all(row["approx_kl"] > 0.0 for row in rows), "each update moved the policy"
