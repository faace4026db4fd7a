"""`hamnet`: one command for every service and tool of the stack.

`hamnet <command> [options]` runs one command; `hamnet <command> --help` documents its
options. Commands whose service is not built yet say so and exit with status 2, as do
commands given a value they cannot run with (`hamnet.runtime.errors`): one line, no traceback.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Sequence
from dataclasses import dataclass

from hamnet import __version__
from hamnet.runtime.allocator import keep_large_buffers
from hamnet.runtime.errors import ConfigError


@dataclass(frozen=True)
class Subcommand:
    """One entry of `hamnet --help`."""

    name: str
    summary: str
    module: str | None
    """Module with `main(argv) -> int`; None while the command is not built."""
    issue: int | None = None
    """Issue that builds it, for commands not built yet."""


COMMANDS: tuple[Subcommand, ...] = (
    Subcommand(
        "sim", "vectorized MuJoCo FR3 with procedural scenes (publishes state)", "hamnet.sim.cli", 3
    ),
    Subcommand(
        "bridge",
        "real FR3 in place of the sim (same contract; `hamnet bridge check`)",
        "hamnet.bridge.cli",
        17,
    ),
    Subcommand(
        "camera",
        "depth frames of the robot's cameras (realsense, sim render or replay)",
        "hamnet.camera.cli",
        17,
    ),
    Subcommand("perception", "point clouds and UniCORN tokens", "hamnet.perception.cli", 6),
    Subcommand(
        "policy", "HAMnet and baseline inference with hot-reloaded weights", "hamnet.policy.cli", 5
    ),
    Subcommand(
        "safety",
        "clipping, Ruckig smoothing and watchdog between policy and robot",
        "hamnet.safety.cli",
        4,
    ),
    Subcommand(
        "trainer",
        "PPO from streamed rollouts (or --inprocess: one process, no Zenoh)",
        "hamnet.trainer.cli",
        12,
    ),
    Subcommand(
        "eval",
        "a policy on held-out scenes and the nine benchmark domains (success with intervals)",
        "hamnet.evaluation.cli",
        31,
    ),
    Subcommand(
        "rollout",
        "rollout worker: in-process cores acting with the trainer's weights",
        "hamnet.trainer.rollout_cli",
        12,
    ),
    Subcommand(
        "pretrain",
        "UniCORN pre-training: contact pairs, training, held-out evaluation",
        "hamnet.pretrain.cli",
        14,
    ),
    Subcommand("monitor", "live Rerun view of the whole stack", "hamnet.monitor.cli", 7),
    Subcommand(
        "record",
        "record topics to MCAP (`hamnet record info FILE` summarises one)",
        "hamnet.recorder.cli",
        7,
    ),
    Subcommand("replay", "replay an MCAP recording onto Zenoh", "hamnet.recorder.replay_cli", 7),
    Subcommand(
        "up", "run a stack file: start, supervise and stop its services", "hamnet.launcher.cli"
    ),
    Subcommand("router", "Zenoh router for multi-machine deployments", "hamnet.tools.router"),
    Subcommand(
        "certs",
        "local CA and one TLS certificate per service identity",
        "hamnet.launcher.certs_cli",
    ),
    Subcommand(
        "topics",
        "list every key expression with its message type and publisher",
        "hamnet.tools.topics",
    ),
    Subcommand(
        "echo", "print, count or reflect what is published on the stack", "hamnet.tools.echo"
    ),
)
"""Every command of `hamnet`, in the order `--help` lists them."""


def usage() -> str:
    """Text of `hamnet --help`."""
    width = max(len(c.name) for c in COMMANDS)
    lines = [
        f"hamnet {__version__}: HAMnet non-prehensile manipulation stack",
        "",
        "usage: hamnet <command> [options]      hamnet <command> --help",
        "",
        "commands:",
    ]
    for command in COMMANDS:
        status = "" if command.module else "  [not built yet]"
        lines.append(f"  {command.name:<{width}}  {command.summary}{status}")
    lines += ["", "Start with: hamnet up compose/demo.yaml"]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Dispatch `hamnet <command> ...`; returns the process exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        print(usage())
        return 0 if args else 2
    if args[0] == "--version":
        print(__version__)
        return 0
    command = next((c for c in COMMANDS if c.name == args[0]), None)
    if command is None:
        print(f"hamnet: unknown command {args[0]!r}\n\n{usage()}", file=sys.stderr)
        return 2
    if command.module is None:
        issue = f" (issue #{command.issue})" if command.issue else ""
        print(f"hamnet {command.name}: not built yet{issue}. {command.summary}.", file=sys.stderr)
        return 2
    keep_large_buffers()
    try:
        return importlib.import_module(command.module).main(args[1:])
    except ConfigError as error:
        print(f"hamnet {command.name}: {error}", file=sys.stderr)
        return 2
