"""Key expressions: `hamnet/<namespace>/<service>/<worker>/<topic>`.

The namespace lets two stacks share one Zenoh network; the worker lets several sim workers
(each with its own batch of environments) feed one trainer. Concrete keys come from the
topic contract (`hamnet.runtime.contract`); this module holds the scheme's rules.
"""

from __future__ import annotations

ROOT = "hamnet"
"""First segment of every key of the stack."""


def check_segment(name: str, value: str) -> str:
    """Return `value` if it is one key segment without wildcards, else raise ValueError."""
    if not value or "/" in value or any(c in value for c in "*$?#"):
        raise ValueError(f"{name} must be one key segment without wildcards, got {value!r}")
    return value


def namespace_pattern(namespace: str) -> str:
    """Every key of one stack."""
    return f"{ROOT}/{check_segment('namespace', namespace)}/**"


def parse_alive_key(key: str) -> tuple[str, str, str]:
    """Split a liveliness key into (namespace, service, worker)."""
    parts = key.split("/")
    if len(parts) != 5 or parts[0] != ROOT or parts[2] != "alive":
        raise ValueError(f"not a liveliness key: {key!r}")
    return parts[1], parts[3], parts[4]
