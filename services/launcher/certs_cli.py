"""`hamnet certs`: a local CA and one certificate per service identity, for testing and
small labs (docs/security.md says how to use an organization's own CA instead).

    hamnet certs init [--dir certs]                          # ca.pem, ca.key
    hamnet certs issue router [--dir certs] [--host hub.lan 10.0.0.5]  # router.pem, router.key
    hamnet certs stack compose/secure/stack.yaml [--host hub.lan]  # all a stack needs
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import tyro

from hamnet.launcher.secure import OPERATOR, identities
from hamnet.launcher.stack import ROUTER, StackError, load
from hamnet.runtime.cli import parse
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.tls_files import ca_files, identity_files
from hamnet.security.certs import init_ca, issue

DEFAULT_DIR = Path("certs")
"""Where certificates go unless --dir says otherwise (ignored by git: it holds keys)."""


@dataclass(frozen=True)
class InitConfig:
    """Create a local certificate authority: ca.pem (give it to every service) and ca.key
    (keep it where certificates are issued, nowhere else)."""

    dir: Path = DEFAULT_DIR
    """Folder of the CA and the certificates it issues."""
    days: int = 3650
    """How long the CA is valid, days."""
    force: bool = False
    """Replace an existing CA (every certificate it issued stops being trusted)."""


@dataclass(frozen=True)
class IssueConfig:
    """Issue NAME.pem and NAME.key, signed by the CA in --dir; NAME is the identity access
    control sees (the certificate's common name), e.g. safety, trainer, operator."""

    name: Annotated[str, tyro.conf.Positional]
    """Identity: 1-64 letters, digits, '.', '_' or '-'."""
    dir: Path = DEFAULT_DIR
    """Folder holding the CA (from `hamnet certs init`); the certificate is written there."""
    host: tuple[str, ...] = ()
    """Host names or IP addresses this identity is reached at besides localhost and
    127.0.0.1, space-separated (a router's address: clients check it against the
    certificate)."""
    days: int = 365
    """How long the certificate is valid, days."""
    force: bool = False
    """Replace an existing certificate and key of this identity."""


@dataclass(frozen=True)
class StackConfig:
    """Make every certificate a stack file needs, in its `secure.tls_dir`: the CA if there
    is none yet, then one certificate per identity without one (the router, `up`, each
    service's command, and `operator` for the e-stop); existing ones are kept."""

    stack: Annotated[Path, tyro.conf.Positional]
    """Stack file, e.g. compose/secure/stack.yaml."""
    dir: Path | None = None
    """Folder of the CA and certificates (default: the stack's secure.tls_dir, else certs)."""
    host: tuple[str, ...] = ()
    """Host names or IP addresses the router is reached at besides loopback (written into
    the router's certificate only)."""
    days: int = 365
    """How long each new certificate is valid, days (a new CA: 3650)."""
    force: bool = False
    """Issue every identity's certificate again (the CA is kept)."""


def stack_certificates(config: StackConfig) -> list[str]:
    """Create what `config.stack` needs; returns one line per identity (written or kept)."""
    try:
        stack = load(config.stack)
    except StackError as error:
        raise ConfigError(str(error)) from None
    directory = config.dir or Path(stack.secure.tls_dir if stack.secure else DEFAULT_DIR)
    lines = []
    if not ca_files(directory).certificate.exists():
        files = init_ca(directory, days=3650)
        lines.append(f"wrote {files.certificate} and {files.key}")
    for name in sorted({*identities(stack), ROUTER, OPERATOR}):
        own = identity_files(directory, name)
        if own.certificate.exists() and not config.force:
            lines.append(f"kept {own.certificate}")
            continue
        hosts = config.host if name == ROUTER else ()
        files = issue(directory, name, config.days, hosts, force=config.force)
        lines.append(f"wrote {files.certificate} and {files.key}")
    return lines


def main(argv: Sequence[str]) -> int:
    """Run `hamnet certs init|issue|stack` with arguments `argv`; returns the exit status."""
    verb, rest = (argv[0], argv[1:]) if argv else ("", [])
    try:
        if verb == "init":
            config = parse(InitConfig, rest, "hamnet certs init", InitConfig.__doc__ or "")
            files = init_ca(config.dir, config.days, config.force)
        elif verb == "issue":
            issued = parse(IssueConfig, rest, "hamnet certs issue", IssueConfig.__doc__ or "")
            files = issue(issued.dir, issued.name, issued.days, issued.host, issued.force)
        elif verb == "stack":
            made = parse(StackConfig, rest, "hamnet certs stack", StackConfig.__doc__ or "")
            print("\n".join(stack_certificates(made)))
            return 0
        elif verb in ("-h", "--help"):
            print(__doc__)
            return 0
        else:
            print(
                f"hamnet certs: expected init, issue or stack, got {verb!r}\n{__doc__}",
                file=sys.stderr,
            )
            return 2
    except ConfigError as error:
        print(f"hamnet certs {verb}: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"hamnet certs {verb}: {error.strerror}: {error.filename}", file=sys.stderr)
        return 2
    print(f"wrote {files.certificate} and {files.key}")
    return 0
