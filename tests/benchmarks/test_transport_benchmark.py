"""`benchmarks/transport.py --quick` runs to the end and reports the figures its issue names.

Only that it runs and what it reports are checked: timings belong to the benchmark, never to
a test, on shared and noisy machines."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "transport.py"


def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    result = subprocess.run(
        [sys.executable, str(SCRIPT), "--quick"], capture_output=True, text=True, timeout=240
    )
    assert result.returncode == 0, result.stderr[-3000:]
    figures = json.loads(result.stdout.strip().splitlines()[-1])
    assert figures["overhead_vs_raw_400k"] > -1 and figures["shm_speedup_4m"] > 0
    for setting in ("shm_on", "shm_off"):
        for path in ("runtime", "raw"):
            for size in ("1k", "400k", "4m"):
                measured = figures["results"][setting][path][size]
                assert measured["round_trip_median_us"] > 0 and measured["round_trip_p99_us"] > 0
    assert figures["results"]["shm_on"]["runtime"]["4m"]["via_shm"] > 0.5
