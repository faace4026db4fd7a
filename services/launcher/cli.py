"""`hamnet up`: run a stack file: start its services, restart the ones that crash, stop
them all on Ctrl-C, SIGTERM, a time bound or when the stack's `until` service finishes,
and print a summary. `--check` only validates the file.

Transport and logging options are forwarded to every service when they differ from their
defaults; `--namespace` (unless `default`) replaces the stack file's namespace. With
`--tls-dir`, the launcher presents its own certificate (`up`, unless `--identity` names
another) and every service its own. A stack file's `secure:` section starts the stack's own
router first and places every process on it (`hamnet.launcher.secure`).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated

import tyro

from hamnet.launcher import check
from hamnet.launcher.argv import forwarded
from hamnet.launcher.run import run
from hamnet.launcher.secure import UP, RouterError, missing_certificates, secured, security
from hamnet.launcher.stack import StackError, load
from hamnet.launcher.summary import render
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.transport import TransportConfig


@dataclass(frozen=True)
class UpConfig:
    """Run a stack file of HAMnet services."""

    stack: tyro.conf.Positional[Path]
    """Stack file, e.g. compose/demo.yaml."""
    check: bool = False
    """Only validate the stack file (keys, commands, arguments) and start nothing."""
    duration_s: float | None = None
    """Stop the stack after this many seconds (default: the stack file's duration_s)."""
    summary_json: Path | None = None
    """Also write the end-of-run summary to this file as JSON."""
    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)

    def __post_init__(self) -> None:
        if self.duration_s is not None and not (
            self.duration_s > 0 and math.isfinite(self.duration_s)
        ):
            raise ConfigError(
                f"--duration-s must be a positive number of seconds, got {self.duration_s}"
            )


CONFIG = UpConfig
"""The config `hamnet up` parses."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet up` with command-line arguments `argv`; returns the exit status."""
    config, _ = parse_service(CONFIG, argv, "up", __doc__)
    common = config.common
    try:
        stack = load(config.stack)
        if common.transport.namespace != TransportConfig().namespace:
            stack = replace(stack, namespace=common.transport.namespace)
    except (StackError, ValueError) as error:
        print(f"hamnet up: {error}", file=sys.stderr)
        return 2
    stack, common = secured(stack, common)
    # A run parses the services' arguments in a child: the supervisor never imports their
    # modules (torch, mujoco, ...), which it would otherwise hold for the whole run.
    verdicts = check.check(stack, forwarded(common), isolated=not config.check)
    errors = [v for v in verdicts if v.error]
    tls_dir = common.transport.tls_dir
    missing = missing_certificates(stack, tls_dir) if stack.secure and tls_dir else []
    if config.check:
        print(
            check.render(
                str(config.stack), stack, verdicts, security(stack, common.transport), missing
            )
        )
        return 2 if errors else 0
    for verdict in errors:
        print(
            f"hamnet up: {config.stack}: service {verdict.service}: {verdict.error}",
            file=sys.stderr,
        )
    if errors:
        return 2
    if missing:
        print(
            f"hamnet up: {config.stack}: {check.missing_text(missing)}; make them with "
            f"`hamnet certs stack {config.stack}`",
            file=sys.stderr,
        )
        return 2
    if tls_dir is not None and not common.transport.identity:
        common = replace(common, transport=replace(common.transport, identity=UP))
    duration_s = stack.duration_s if config.duration_s is None else config.duration_s
    try:
        report = run(stack, verdicts, common, duration_s)
    except RouterError as error:
        print(f"hamnet up: {error}", file=sys.stderr)
        return 1
    print(render(report), flush=True)
    if config.summary_json is not None:
        config.summary_json.write_text(report.to_json() + "\n")
    return report.exit_code
