"""scripts/student_inputs.py measures a shipped student (its full run, four evaluations of
the card's 256 episodes, is docs/trainer.md's DAgger diagnosis): a teacher is refused."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "student_inputs.py"


def test_a_teacher_is_refused_with_the_reason() -> None:
    command = [sys.executable, str(SCRIPT), "easy-paddle"]
    done = subprocess.run(command, check=False, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "easy-paddle reads privileged inputs: it is not a student" in done.stderr
