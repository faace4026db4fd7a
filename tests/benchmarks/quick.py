"""Run a benchmark script with `--quick` and read the JSON line it ends with.

Only that a benchmark runs and what it reports are checked in tests: timings belong to the
benchmark, never to a test, on shared and noisy machines."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


def run_quick(script: str, timeout: float = 240, *args: str) -> dict:
    """Figures printed by `benchmarks/<script> --quick [args]` as its last stdout line."""
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), "--quick", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,  # the status is asserted below, with the script's stderr
    )
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])
