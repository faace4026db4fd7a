"""Command lines of a stack's processes.

Each worker of a service runs `hamnet <command> --namespace <ns> [forwarded options]
[args] --worker <id>`: the stack's namespace, the transport and logging options given to
`hamnet up` that differ from their defaults (unless the service's args set them), the
service's own args, then its worker id. The docker-compose file spells the same lines.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path

from hamnet.launcher.stack import ArgValue, ServiceSpec, expand
from hamnet.runtime.cli import CommonConfig


def flags(options: Mapping[str, ArgValue]) -> list[str]:
    """Options as tyro reads them: `{"num-envs": 4, "render": False}` -> `--num-envs 4 --no-render`.

    Lists become one flag followed by their items, booleans `--flag`/`--no-flag`, and null
    becomes `None` (how tyro spells it for optional options).
    """
    argv: list[str] = []
    for name, value in options.items():
        if isinstance(value, bool):
            argv.append(f"--{name}" if value else f"--no-{name}")
        elif isinstance(value, tuple | list):
            argv += [f"--{name}", *(_text(item) for item in value)]
        else:
            argv += [f"--{name}", _text(value)]
    return argv


def _text(value: object) -> str:
    return "None" if value is None else str(value)


OWN = ("namespace", "identity")
"""Transport options each process has its own value of (the worker is not a transport one)."""


def forwarded(common: CommonConfig) -> dict[str, ArgValue]:
    """Transport and logging options of `common` that differ from the defaults, by flag name.

    The namespace, worker and TLS identity are left out: every process gets the stack's
    namespace, its own worker id and presents its own certificate.
    """
    options: dict[str, ArgValue] = {}
    for config in (common.transport, common.logging):
        default = type(config)()
        for field in dataclasses.fields(config):
            value = getattr(config, field.name)
            if field.name not in OWN and value != getattr(default, field.name):
                options[_flag(field.name)] = str(value) if isinstance(value, Path) else value
    return options


def service_argv(
    spec: ServiceSpec, worker: str, namespace: str, forward: Mapping[str, ArgValue]
) -> list[str]:
    """Arguments after `hamnet` for one worker of `spec`: `["echo", "--namespace", ...]`."""
    own = {_flag(name) for name in spec.args}
    args = {name: _expand(value, namespace) for name, value in spec.args.items()}
    remap = tuple(f"{port}={expand(key, namespace)}" for port, key in spec.remap.items())
    options = {
        "namespace": namespace,
        **{name: value for name, value in forward.items() if name not in own},
        **args,
        **({"remap": remap} if remap else {}),
        "worker": worker,
    }
    return [spec.command, *flags(options)]


def _expand(value: ArgValue, namespace: str) -> ArgValue:
    if isinstance(value, str):
        return expand(value, namespace)
    if isinstance(value, tuple):
        return tuple(_expand(item, namespace) for item in value)  # type: ignore[misc]
    return value


def _flag(name: str) -> str:
    return name.replace("_", "-")
