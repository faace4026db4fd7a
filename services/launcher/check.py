"""`hamnet up --check`: can every service of a stack run as written?

Each service's command must be a `hamnet` command; a built command's arguments are parsed
with that command's own `CONFIG` (exactly the line the launcher would start), so a
misspelt flag or a bad value fails here instead of in a crash loop. Commands not built
yet cannot be validated: they are reported as missing, which is not an error.
"""

from __future__ import annotations

import contextlib
import importlib
import io
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from hamnet.cli import COMMANDS, Subcommand
from hamnet.launcher.argv import service_argv
from hamnet.launcher.secure import Security
from hamnet.launcher.stack import ArgValue, Stack
from hamnet.runtime.cli import check_remap, parse
from hamnet.runtime.errors import ConfigError


@dataclass(frozen=True)
class Verdict:
    """Whether one service of a stack can run."""

    service: str
    """Service name in the stack file."""
    command: Subcommand | None
    """Its `hamnet` command; None when no command has that name."""
    error: str = ""
    """Why it cannot run as written; '' when it can (or is not built yet)."""

    @property
    def built(self) -> bool:
        """Whether its command exists and is built, so the launcher can start it."""
        return self.command is not None and self.command.module is not None

    @property
    def status(self) -> str:
        """One-line verdict for `--check`."""
        if self.error:
            return f"error: {self.error}"
        return "ok" if self.built else f"not validated: not built yet{issue_text(self.command)}"


def issue_text(command: Subcommand | None) -> str:
    """` (issue #3)` for a command built by a known issue, else ''."""
    return f" (issue #{command.issue})" if command and command.issue else ""


def check(stack: Stack, forward: Mapping[str, ArgValue]) -> list[Verdict]:
    """A verdict for every service of `stack`, in file order."""
    commands = {command.name: command for command in COMMANDS}
    verdicts = []
    for name, spec in stack.services.items():
        command = commands.get(spec.command)
        if command is None:
            known = ", ".join(commands)
            error = f"unknown command {spec.command!r} (hamnet commands: {known})"
        elif command.name == "up":
            error = "a stack cannot run `hamnet up`"
        elif command.module is None:
            error = ""
        else:
            argv = service_argv(spec, spec.workers[0], stack.namespace, forward)
            error = validate_args(command, argv[1:])
        verdicts.append(Verdict(name, command, error))
    return verdicts


def validate_args(command: Subcommand, argv: list[str]) -> str:
    """Parse `argv` with the command's CONFIG and check its `--remap` against the command's
    PORTS; returns the complaint or ''."""
    module = importlib.import_module(command.module)
    output = io.StringIO()
    try:
        with contextlib.redirect_stdout(output), contextlib.redirect_stderr(output):
            config = parse(module.CONFIG, argv, f"hamnet {command.name}", "")
        if hasattr(config, "common"):
            check_remap(config.common, getattr(module, "PORTS", None))
    except SystemExit:  # tyro reports bad flags and nested `__post_init__` errors this way
        return _first_lines(output.getvalue()) or "invalid arguments"
    except (ValueError, ConfigError) as error:  # a top-level config's `__post_init__`, a remap
        return str(error)
    return ""


def _first_lines(text: str) -> str:
    """The gist of tyro's boxed error text: its message lines, without help text."""
    lines = []
    for line in text.splitlines():
        line = line.strip(" │")
        if line.startswith(("Argument helptext", "For full helptext", "usage:")):
            break
        if line and not set(line) <= set("-─╭╮╰╯"):
            lines.append(line)
    return "; ".join(lines[1:] or lines)


def not_built(verdicts: list[Verdict]) -> str:
    """`sim (issue #3), perception (issue #6)`: the services not built yet, or ''."""
    return ", ".join(
        (v.service if v.service == v.command.name else f"{v.service}: hamnet {v.command.name}")
        + issue_text(v.command)
        for v in verdicts
        if not v.built and not v.error
    )


def render(
    path: str, stack: Stack, verdicts: list[Verdict], security: Security, missing: list[Path]
) -> str:
    """The `--check` report: how its processes meet (TLS, access control), then one line
    per service with its command line, whether it is critical or auxiliary, and its
    verdict. Missing certificates are noted, not errors: they are made on the machine
    that runs the stack (`hamnet certs stack`)."""
    commands = [f"hamnet {s.command} [{','.join(s.workers)}]" for s in stack.services.values()]
    name_width = max(len(name) for name in stack.services)
    command_width = max(len(command) for command in commands)
    lines = [f"{path}: stack {stack.name}, namespace {stack.namespace}", f"  {security.text()}"]
    if missing:
        lines.append(f"  {missing_text(missing)} (`hamnet certs stack {path}` makes them)")
    for v, command in zip(verdicts, commands, strict=True):
        role = "critical" if stack.services[v.service].is_critical else "auxiliary"
        lines.append(
            f"  {v.service:<{name_width}}  {command:<{command_width}}  {role:<9}  {v.status}"
        )
    errors = sum(1 for v in verdicts if v.error)
    missing = not_built(verdicts)
    if errors:
        lines.append(f"{errors} of {len(verdicts)} services cannot run as written")
    else:
        lines.append("valid" + (f"; not built yet: {missing}" if missing else ""))
    return "\n".join(lines)


def missing_text(missing: list[Path]) -> str:
    """`certificates missing in certs: ca, router, up` (identities, from file stems)."""
    return f"certificates missing in {missing[0].parent}: {', '.join(dict.fromkeys(p.stem for p in missing))}"
