"""`hamnet trainer --ranks N` on one machine: this process becomes rank 0 and starts ranks
1..N-1 as `python -m hamnet trainer` with the same arguments and torchrun's variables
(`RANK`, `WORLD_SIZE`, `MASTER_ADDR`, `MASTER_PORT` on loopback), so a launch by hand and one
by torchrun (`torchrun --nproc-per-node N -m hamnet trainer ...`, or across machines with
its own rendezvous) run the same code. The other ranks stop when rank 0 is gone
(`HAMNET_SUPERVISOR_PID`, as under `hamnet up`).
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence

from hamnet.runtime.service import SUPERVISOR_PID_ENV
from hamnet.runtime.transport import free_port

STOP_TIMEOUT_S = 30.0
"""How long rank 0 waits for the other ranks to finish before it kills them."""


def start_other_ranks(argv: Sequence[str], size: int) -> list[subprocess.Popen]:
    """Make this process rank 0 of `size` (torchrun's variables in its environment) and start
    the others with `argv` (the trainer's arguments)."""
    port = str(free_port())
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=port, WORLD_SIZE=str(size), RANK="0")
    command = [sys.executable, "-m", "hamnet", "trainer", *argv]
    children = []
    for rank in range(1, size):
        env = {**os.environ, "RANK": str(rank), SUPERVISOR_PID_ENV: str(os.getpid())}
        children.append(subprocess.Popen(command, env=env))
    return children


def wait_for(children: list[subprocess.Popen]) -> int:
    """Wait for the other ranks (they stop with rank 0's loop); kill those that hang.
    Returns the first non-zero exit status, else 0."""
    codes = []
    for child in children:
        try:
            codes.append(child.wait(STOP_TIMEOUT_S))
        except subprocess.TimeoutExpired:
            child.kill()
            codes.append(child.wait())
    return next((code for code in codes if code), 0)
