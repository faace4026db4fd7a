"""A soak of the demo stack (issue 13): `hamnet up compose/demo.yaml` runs for
`HAMNET_SOAK_S` seconds (30 minutes by default) while this test samples the resident memory
of every process it started, once a minute. After a warm-up (imports, first allocations,
the demo's short training run), no service may keep growing: a leak the size of the
monitor's old one (23 MB a minute) or a tenth of it fails. On demand only (`slow`):
`bash scripts/test.sh -m slow -k soak`, or shorter with `HAMNET_SOAK_S=300`.
"""

from __future__ import annotations

import os
import time

import pytest

from tests.stack.test_demo import DEMO, isolated
from tests.stack.up import alive, rss_mb, up

SOAK_S = float(os.environ.get("HAMNET_SOAK_S", "1800"))
WARM_UP_S = 120.0
"""Not judged: start-up, first allocations and the demo's 10-update training run."""
SAMPLE_S = 60.0
LEAK_MB_PER_MIN = 2.0
"""Growth rate (after warm-up) that counts as a leak; below the noise of torch's allocator
over a few minutes, a tenth of the monitor's old leak."""
SLACK_MB = 20.0
"""Allocator noise allowed on top of the rate, however short the soak."""


@pytest.mark.slow
@pytest.mark.timeout(int(SOAK_S) + 600)
def test_every_service_keeps_its_memory_flat_over_a_soak(tmp_path) -> None:
    samples: dict[str, list[float]] = {}
    with up(DEMO, isolated(), "--duration-s", str(SOAK_S), cwd=tmp_path) as run:
        run.wait_for(r"sim/0 ready", timeout=120)
        started = time.monotonic()
        while time.monotonic() - started < SOAK_S - SAMPLE_S:
            time.sleep(SAMPLE_S)
            assert run.process.poll() is None, run.output[-3000:]
            for label, pids in run.started().items():
                if time.monotonic() - started > WARM_UP_S and alive(pids[-1]):
                    memory = rss_mb(pids[-1])
                    if memory is not None:
                        samples.setdefault(label, []).append(memory)
        assert run.wait(timeout=300) == 0, run.output[-3000:]
    minutes = (SOAK_S - WARM_UP_S) / 60
    limit = SLACK_MB + LEAK_MB_PER_MIN * minutes
    grown = {label: round(values[-1] - min(values), 1) for label, values in samples.items()}
    print(f"growth after warm-up over {minutes:.0f} min, MB (limit {limit:.0f}): {grown}")
    assert {"sim/0", "perception/0", "policy/0", "safety/0", "monitor/0", "record/0"} <= set(grown)
    assert all(growth < limit for growth in grown.values()), (limit, grown, samples)
