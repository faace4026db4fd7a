"""The supervisor and the rate printer stay light (issue 29): `hamnet up` held about 650 MB
because checking a stack imported every service's module (and with it torch, mujoco,
open3d, pinocchio and rerun) into the launcher, which then kept them for the whole run.

The real commands run in a subprocess under a hook that, as the process exits, writes which
of those modules it had imported; the services they start are ordinary processes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from hamnet.cli import COMMANDS, Subcommand
from hamnet.launcher.validate import in_child, validate_args
from hamnet.runtime.transport import TransportConfig
from tests.conftest import transport_args

HEAVY = ("torch", "mujoco", "open3d", "pinocchio", "rerun")
"""The learning stack and its viewers: what neither command may import."""

HOOK = f"""
import atexit, json, os, sys
atexit.register(lambda: open(os.environ["HEAVY_OUT"], "w").write(
    json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules))))
from hamnet.cli import main
sys.exit(main(sys.argv[1:]))
"""
"""`hamnet <args>` that writes the heavy modules it imported to $HEAVY_OUT at exit."""


def heavy_modules_of(tmp_path: Path, *args: str) -> list[str]:
    """Run `hamnet <args>` under HOOK; the heavy modules it imported."""
    out = tmp_path / "heavy.json"
    done = subprocess.run(
        [sys.executable, "-c", HOOK, *args],
        capture_output=True,
        text=True,
        timeout=180,
        env={**os.environ, "HEAVY_OUT": str(out)},
        check=False,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return json.loads(out.read_text())


def test_a_running_launcher_imports_none_of_the_learning_stack(
    tmp_path: Path, transport: TransportConfig
) -> None:
    """A sim in the stack: checking its arguments needs its module (mujoco), started it
    runs in its own process; the launcher itself must hold neither."""
    stack = tmp_path / "light.yaml"
    stack.write_text(
        "until: watch\n"
        "services:\n"
        "  sim: {args: {num-envs: 1}}\n"
        "  watch: {command: echo, args: {duration-s: 1}}\n"
    )
    assert heavy_modules_of(tmp_path, "up", str(stack), *transport_args(transport)) == []


def test_echo_imports_none_of_the_learning_stack(
    tmp_path: Path, transport: TransportConfig
) -> None:
    args = ("echo", "--duration-s", "0.5", *transport_args(transport))
    assert heavy_modules_of(tmp_path, *args) == []


def test_the_child_finds_what_parsing_here_finds() -> None:
    commands = {command.name: command for command in COMMANDS}
    requests = [
        (commands["echo"], ["--period-s", "5"]),
        (commands["echo"], ["--perod-s", "5"]),
        (commands["sim"], ["--num-envs", "-1"]),
    ]
    found = in_child(requests)
    assert found == [validate_args(command, argv) for command, argv in requests]
    assert found[0] == "" and "--perod-s" in found[1] and "num_envs" in found[2]


def test_a_child_that_cannot_validate_refuses_every_service_in_one_line() -> None:
    ghost = Subcommand("ghost", "", "hamnet.no_such_module")
    found = in_child([(ghost, []), (ghost, ["--x"])])
    reason = "ModuleNotFoundError: No module named 'hamnet.no_such_module'"
    assert found == [f"could not be validated: {reason}"] * 2
