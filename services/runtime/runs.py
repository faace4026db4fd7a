"""What a training run leaves behind, read back the same way by every trainer: the git commit
the code runs from (written into a run's summary) and the per-iteration metrics of a run
folder (`<run_dir>/metrics.jsonl`, one JSON object per line).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path


def commit() -> str:
    """The git commit of the working tree this runs from, '' outside a checkout."""
    result = subprocess.run(
        ["git", "rev-parse", "HEAD"],
        capture_output=True,
        text=True,
        cwd=Path(__file__).parent,
        check=False,
    )
    return result.stdout.strip()


def command_line(subcommand: str) -> str:
    """The command this process runs as a user typed it: `hamnet <subcommand> ...` when it
    runs as that `hamnet` command (whatever path the entry point has), else its argv."""
    if sys.argv[1:2] == [subcommand]:
        return " ".join(["hamnet", subcommand, *sys.argv[2:]])
    return " ".join(sys.argv)


def read_metrics(run_dir: Path) -> list[dict[str, float]]:
    """Every iteration's metrics of a run, in order.

    Raises:
        FileNotFoundError: `run_dir` has no metrics.jsonl.
    """
    path = run_dir / "metrics.jsonl"
    if not path.is_file():
        raise FileNotFoundError(
            f"{path} does not exist: is {run_dir} the run folder of a training run?"
        )
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
