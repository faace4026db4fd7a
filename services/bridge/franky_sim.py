"""`franky-sim` (the libfranka network protocol served by a MuJoCo FR3 that no one here
wrote; PyPI `franky-sim`, the `dev` extra) as a robot on a loopback address of its own, so
tests and `hamnet bridge gap` can run side by side. Its arm starts at franky-sim's own
posture, (0, 0, 0, -1.57, 0, 1.57, 0.785) rad."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from hamnet.runtime.errors import ConfigError

STARTUP_S = 60.0
"""Longest wait for the server to listen (it imports MuJoCo and builds its model)."""


@contextmanager
def franky_sim() -> Iterator[tuple[str, subprocess.Popen]]:
    """A running franky-sim on a random 127.x.y.z; yields its address and process.

    Raises:
        ConfigError: franky-sim is not installed next to this Python.
    """
    host = f"127.{random.randint(1, 254)}.{random.randint(1, 254)}.{random.randint(2, 254)}"
    executable = Path(sys.executable).with_name("franky-sim")
    if not executable.exists():
        raise ConfigError(f"{executable} not found: pip install 'hamnet[dev]' (franky-sim)")
    with tempfile.NamedTemporaryFile("w+", suffix=".log") as log:
        process = subprocess.Popen(
            [str(executable), "--simulator", "mujoco", "--hostname", host],
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        try:
            deadline = time.monotonic() + STARTUP_S
            while "Connect to the server" not in Path(log.name).read_text():
                if process.poll() is not None:
                    raise RuntimeError(f"franky-sim exited: {Path(log.name).read_text()}")
                if time.monotonic() > deadline:
                    raise TimeoutError(f"franky-sim did not start within {STARTUP_S} s")
                time.sleep(0.1)
            yield host, process
        finally:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
            process.wait()
