"""Parse a built service's arguments with its command's own `CONFIG`, here or in a child.

Parsing imports the command's module, and the modules of `sim`, `policy`, `trainer`,
`perception` or `monitor` bring MuJoCo, PyTorch, Open3D, Pinocchio and Rerun with them:
about 600 MB that a supervisor would otherwise hold for the whole run while using none of
it (issue 29). `hamnet up` therefore validates in a child process that imports them,
answers and exits; `hamnet up --check`, which exits at once anyway, parses in its own
process.

`python -m hamnet.launcher.validate` reads `[[name, module, argv], ...]` as JSON on stdin
and writes the complaints ('' for none), one JSON list, as the last line of its stdout.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import json
import subprocess
import sys

from hamnet.cli import Subcommand
from hamnet.runtime.cli import check_remap, parse
from hamnet.runtime.errors import ConfigError


def validate_args(command: Subcommand, argv: list[str]) -> str:
    """Parse `argv` with the command's CONFIG, on the defaults its `default_config(argv)`
    gives where it has one (a stage's, a DAgger run's student), and check its `--remap`
    against the command's PORTS; returns the complaint or ''."""
    module = importlib.import_module(command.module)
    defaults = getattr(module, "default_config", None)
    output = io.StringIO()
    try:
        with contextlib.redirect_stdout(output), contextlib.redirect_stderr(output):
            default = None if defaults is None else defaults(argv)
            config = parse(module.CONFIG, argv, f"hamnet {command.name}", "", default)
        if hasattr(config, "common"):
            check_remap(config.common, getattr(module, "PORTS", None))
    except SystemExit:  # `parse` printed its one line: a bad flag, a nested config's refusal
        return output.getvalue().strip() or "invalid arguments"
    except (ValueError, ConfigError) as error:  # a remap `parse` does not see
        return str(error)
    return ""


def in_child(requests: list[tuple[Subcommand, list[str]]]) -> list[str]:
    """`validate_args` for each (command, argv) of `requests`, run in a child process so
    that this one never imports the commands' modules.

    A child that fails (a module that cannot be imported, say) makes every request's
    complaint its last line of error output: the stack is refused, in one line per service.
    """
    if not requests:
        return []
    question = json.dumps([[command.name, command.module, argv] for command, argv in requests])
    done = subprocess.run(
        [sys.executable, "-m", __name__],
        input=question,
        capture_output=True,
        text=True,
        check=False,
    )
    with contextlib.suppress(IndexError, ValueError):
        answer = json.loads(done.stdout.splitlines()[-1])
        if done.returncode == 0 and isinstance(answer, list) and len(answer) == len(requests):
            return [str(error) for error in answer]
    reason = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
    return [f"could not be validated: {reason}"] * len(requests)


def main() -> int:
    """The child's side of `in_child`."""
    requests = json.loads(sys.stdin.read())
    answer = [validate_args(Subcommand(name, "", module), argv) for name, module, argv in requests]
    print(json.dumps(answer), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
