"""`hamnet up --check`: can every service of a stack run as written?

Each service's command must be a `hamnet` command; a built command's arguments are parsed
with that command's own `CONFIG` (exactly the line the launcher would start), so a
misspelt flag or a bad value fails here instead of in a crash loop. Commands not built
yet cannot be validated: they are reported as missing, which is not an error. Parsing
imports each command's module, so `hamnet up` parses in a child process
(`hamnet.launcher.validate`) and stays free of the learning stack.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from hamnet.cli import COMMANDS, Subcommand
from hamnet.launcher.argv import service_argv
from hamnet.launcher.secure import Security
from hamnet.launcher.stack import ArgValue, Stack
from hamnet.launcher.validate import in_child, validate_args


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


def check(stack: Stack, forward: Mapping[str, ArgValue], isolated: bool = False) -> list[Verdict]:
    """A verdict for every service of `stack`, in file order.

    `isolated` parses the built services' arguments in a child process (`hamnet up`, which
    then supervises for the whole run without the commands' modules); otherwise here.
    """
    commands = {command.name: command for command in COMMANDS}
    verdicts = []
    to_parse: list[tuple[int, Subcommand, list[str]]] = []
    for name, spec in stack.services.items():
        command = commands.get(spec.command)
        error = ""
        if command is None:
            known = ", ".join(commands)
            error = f"unknown command {spec.command!r} (hamnet commands: {known})"
        elif command.name == "up":
            error = "a stack cannot run `hamnet up`"
        elif command.module is not None:
            argv = service_argv(spec, spec.workers[0], stack.namespace, forward)
            to_parse.append((len(verdicts), command, argv[1:]))
        verdicts.append(Verdict(name, command, error))
    requests = [(command, argv) for _, command, argv in to_parse]
    errors = in_child(requests) if isolated else [validate_args(c, a) for c, a in requests]
    for (index, _, _), error in zip(to_parse, errors, strict=True):
        verdicts[index] = replace(verdicts[index], error=error)
    return verdicts


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
