"""The service chain as a rollout source: sim -> perception -> policy -> safety as processes
on real Zenoh, the policy assembling RolloutChunks (`--rollout-horizon`), and
`hamnet trainer` learning from them as from one rollout worker. The chain keeps stepping
while the trainer learns, so the trainer accepts lagging chunks (`--max-policy-lag`)."""

from __future__ import annotations

import json

from hamnet.runtime.transport import TransportConfig
from tests.conftest import transport_args
from tests.stack.test_trainer_stream import finish

B, T, UPDATES = 4, 4, 3


def test_the_trainer_learns_from_chunks_the_policy_service_assembles(
    spawn, transport: TransportConfig, tmp_path
) -> None:
    net = transport_args(transport)
    spawn("sim", "--num-envs", str(B), *net)
    spawn("perception", "--random-init", *net)
    spawn("policy", "--random-init", "hamnet", "--rollout-horizon", str(T), *net)
    spawn("safety", "--profile", "training", *net)
    trainer = spawn(
        "trainer", "--workers", "1", "--sim.num-envs", str(B), "--steps-per-rollout", str(T),
        "--max-policy-lag", "8", "--max-env-transitions", str(UPDATES * B * T),
        "--eval-episodes", "0", "--run-dir", str(tmp_path), *net,
    )  # fmt: skip
    finish(trainer, timeout=240)
    rows = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    assert [row["env_transitions"] for row in rows] == [B * T * (i + 1) for i in range(UPDATES)]
    assert all(0 <= row["policy_lag"] <= 8 for row in rows)
