"""`hamnet certs`: a local CA and one certificate per service identity, for testing and
small labs (docs/security.md says how to use an organization's own CA instead).

    hamnet certs init [--dir certs]                          # ca.pem, ca.key
    hamnet certs issue router [--dir certs] [--host hub.lan 10.0.0.5]  # router.pem, router.key
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import tyro

from hamnet.runtime.cli import parse
from hamnet.runtime.errors import ConfigError
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


def main(argv: Sequence[str]) -> int:
    """Run `hamnet certs init|issue` with arguments `argv`; returns the exit status."""
    verb, rest = (argv[0], argv[1:]) if argv else ("", [])
    try:
        if verb == "init":
            config = parse(InitConfig, rest, "hamnet certs init", InitConfig.__doc__ or "")
            files = init_ca(config.dir, config.days, config.force)
        elif verb == "issue":
            issued = parse(IssueConfig, rest, "hamnet certs issue", IssueConfig.__doc__ or "")
            files = issue(issued.dir, issued.name, issued.days, issued.host, issued.force)
        elif verb in ("-h", "--help"):
            print(__doc__)
            return 0
        else:
            print(f"hamnet certs: expected init or issue, got {verb!r}\n{__doc__}", file=sys.stderr)
            return 2
    except ConfigError as error:
        print(f"hamnet certs {verb}: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"hamnet certs {verb}: {error.strerror}: {error.filename}", file=sys.stderr)
        return 2
    print(f"wrote {files.certificate} and {files.key}")
    return 0
