"""Where an identity's TLS files are: `<dir>/ca.pem` (the CA every peer trusts) and
`<dir>/<name>.pem` / `<dir>/<name>.key` per identity. Services read these paths when they
join over TLS; `hamnet.security.certs` writes them. No cryptography here, so a service's
start does not pay for importing it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from hamnet.runtime.errors import ConfigError

CA_NAME = "ca"
"""File stem of the CA's certificate and key (not usable as an identity)."""

IDENTITY = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
"""An identity: a file stem and a common name (at most 64 characters, as X.509 allows)."""


@dataclass(frozen=True)
class Identity:
    """Where one identity's files are."""

    certificate: Path
    """PEM certificate, signed by the CA."""
    key: Path
    """PEM private key (PKCS#8), readable by its owner only."""


def ca_files(directory: Path) -> Identity:
    """The CA's certificate and key in `directory`."""
    return Identity(directory / f"{CA_NAME}.pem", directory / f"{CA_NAME}.key")


def identity_files(directory: Path, name: str) -> Identity:
    """The certificate and key of identity `name` in `directory`.

    Raises:
        ConfigError: `name` is not a usable identity.
    """
    if not IDENTITY.fullmatch(name) or name == CA_NAME:
        raise ConfigError(
            f"identity {name!r} must be 1-64 letters, digits, '.', '_' or '-', "
            f"start with a letter or digit, and not be {CA_NAME!r}"
        )
    return Identity(directory / f"{name}.pem", directory / f"{name}.key")
