"""A training stack a person stops (issue 28): `hamnet up compose/train-easy.yaml` stopped
with Ctrl-C in the middle of an iteration (HAMnet's take 40-60 s, the grace period 5 s)
ends with the trainer stopped, not killed, and its checkpoint, metrics and summary
written."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

from hamnet.launcher.stack import load
from hamnet.policy.weights import read_checkpoint
from tests.stack.test_demo import isolated
from tests.stack.up import up

TRAIN_EASY = Path(__file__).resolve().parents[2] / "compose" / "train-easy.yaml"


def test_ctrl_c_in_the_middle_of_an_iteration_saves_the_run(tmp_path: Path) -> None:
    transport = isolated()
    folder = tmp_path / load(TRAIN_EASY).outputs[0].replace("<namespace>", transport.namespace)
    metrics = folder.parent / "metrics.jsonl"
    with up(TRAIN_EASY, transport, cwd=tmp_path) as run:
        # The first iteration (the statistics) is in (its metrics row, not its progress line,
        # which comes only every 10 s); the worker now collects the second.
        deadline = time.monotonic() + 240
        while not (metrics.exists() and metrics.read_text().strip()):
            assert time.monotonic() < deadline and run.process.poll() is None, run.output
            time.sleep(0.2)
        run.process.send_signal(signal.SIGINT)
        assert run.wait(timeout=60) == 0, run.output
    processes = {p["service"]: p for p in run.summary()["processes"]}
    assert processes["trainer"]["outcome"] == "stopped", processes["trainer"]
    assert processes["rollout"]["outcome"] == "stopped", processes["rollout"]
    summary = json.loads(folder.read_text())
    assert summary["stopped_by_signal"] and summary["env_steps"] == 8192
    rows = metrics.read_text().splitlines()
    assert [json.loads(row)["iteration"] for row in rows] == [1]
    weights = read_checkpoint(folder.parent / "checkpoints" / "latest.safetensors")
    assert weights.version == 2 and weights.architecture == "hamnet"
