"""Zenoh session configuration shared by every service, tool and the launcher.

The default is Zenoh peer mode on loopback with multicast scouting off: every peer listens
on a random loopback port, tries to also listen on one well-known loopback endpoint (the
rendezvous) and connects to it. Whichever process holds the rendezvous introduces the
others through gossip, so peers form a full mesh with no router and nothing leaves the
machine; when it exits, the others stay connected and the next process to start takes the
endpoint over. Routers and remote peers are added with `connect`/`listen`.

Bad settings fail before any session opens, as one-line `ConfigError`s: an endpoint that is
not a locator `<protocol>/<address>`, a Zenoh config file that is missing or unreadable;
a session Zenoh then refuses to open is one too, without Zenoh's source locations.
"""

from __future__ import annotations

import json
import re
import socket
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import zenoh

from hamnet.runtime.errors import ConfigError
from hamnet.runtime.keys import check_segment
from hamnet.runtime.tls_files import Identity, ca_files, identity_files

DEFAULT_RENDEZVOUS = "tcp/127.0.0.1:7448"
"""Loopback endpoint where local peers meet (7447 is left to Zenoh routers)."""

DEFAULT_ROUTER_LISTEN = "tcp/127.0.0.1:7447"
"""Where a router listens unless told otherwise: loopback, so that starting one exposes
nothing; other machines are let in by naming an interface with `--listen`."""

LOCATOR = re.compile(r"[A-Za-z][A-Za-z0-9_-]*/[^\s?#]+(\?[^\s#]*)?(#\S*)?")
"""A Zenoh endpoint: `<protocol>/<address>[?<metadata>][#<config>]`, e.g. tcp/127.0.0.1:7447."""

SECURE_PROTOCOLS = ("tls", "quic")
"""Link protocols allowed with --tls-dir: both authenticate with the certificates."""

SOURCE_LOCATION = re.compile(r" at /\S+\.rs:\d+\.?")
"""Where in Zenoh's Rust sources an error was raised: noise on a command line."""


@dataclass(frozen=True)
class TransportConfig:
    """How a process joins the Zenoh network."""

    namespace: str = "default"
    """Stack namespace: the second segment of every key, so two stacks can share a network."""
    mode: Literal["peer", "client", "router"] = "peer"
    """Zenoh mode: peer (default, no router needed), client (through a router), router."""
    rendezvous: str = DEFAULT_RENDEZVOUS
    """Loopback endpoint local peers listen on if free and connect to; '' disables it."""
    connect: tuple[str, ...] = ()
    """Extra endpoints to connect to, e.g. a router: tcp/192.168.1.10:7447."""
    listen: tuple[str, ...] = ()
    """Extra endpoints to listen on, e.g. tcp/0.0.0.0:7450 to accept remote peers."""
    zenoh_config: Path | None = None
    """Zenoh JSON5 config file used as the base; the options above are applied on top."""
    shared_memory: bool = True
    """Move payloads above `shm_threshold` through shared memory when the peer is local."""
    shm_pool_mb: int = 64
    """Size of this process's shared-memory pool, MiB."""
    shm_threshold: int = 3072
    """Payload size in bytes from which shared memory is used."""
    tls_dir: Path | None = None
    """Join over mutual TLS with the certificates in this folder (ca.pem, <identity>.pem,
    <identity>.key; `hamnet certs`): links are tls/ only, the rendezvous and a router's
    default port too, and every --connect/--listen endpoint must be tls/ or quic/."""
    identity: str = ""
    """Identity whose certificate this process presents with --tls-dir ('' means the
    command's name: safety, trainer...); access rules name it (docs/security.md)."""

    def __post_init__(self) -> None:
        try:
            check_segment("namespace", self.namespace)
        except ValueError as error:
            raise ConfigError(str(error)) from None
        endpoints = {
            "rendezvous": (self.rendezvous,) if self.rendezvous else (),
            "connect": self.connect,
            "listen": self.listen,
        }
        for name, values in endpoints.items():
            for endpoint in values:
                if not LOCATOR.fullmatch(endpoint):
                    raise ConfigError(
                        f"{name} endpoint {endpoint!r} is not a Zenoh locator "
                        "<protocol>/<address>, e.g. tcp/127.0.0.1:7447"
                    )
        if self.zenoh_config is not None and not self.zenoh_config.is_file():
            raise ConfigError(f"Zenoh config file not found: {self.zenoh_config}")
        if self.shm_pool_mb <= 0 or self.shm_threshold < 0:
            raise ConfigError("shm_pool_mb must be > 0 and shm_threshold >= 0")
        if self.tls_dir is not None:
            for name in ("connect", "listen"):
                for endpoint in getattr(self, name):
                    if endpoint.split("/", 1)[0] not in SECURE_PROTOCOLS:
                        raise ConfigError(
                            f"with --tls-dir, {name} endpoint {endpoint!r} must be tls/ or quic/"
                        )
            if self.identity:
                tls_files(self.tls_dir, self.identity)


def tls_files(directory: Path, identity: str) -> tuple[Path, Identity]:
    """The CA certificate and `identity`'s files in `directory`.

    Raises:
        ConfigError: a bad identity or a missing file, named with how to make it.
    """
    ca, own = ca_files(directory).certificate, identity_files(directory, identity)
    for path in (ca, own.certificate, own.key):
        if not path.is_file():
            raise ConfigError(
                f"TLS file not found: {path} (`hamnet certs` makes it; docs/security.md)"
            )
    return ca, own


def zenoh_config(transport: TransportConfig) -> zenoh.Config:
    """Build the Zenoh config of `transport` (pure: opens nothing).

    Raises:
        ConfigError: Zenoh refuses the config file or a setting.
    """
    try:
        return _zenoh_config(transport)
    except zenoh.ZError as error:
        raise ConfigError(f"Zenoh config: {zenoh_message(error)}") from None


def _zenoh_config(transport: TransportConfig) -> zenoh.Config:
    if transport.zenoh_config is not None:
        config = zenoh.Config.from_file(str(transport.zenoh_config))
    else:
        config = zenoh.Config()
    listen = list(transport.listen)
    connect = list(transport.connect)
    secure = _over_tls if transport.tls_dir is not None else str
    if transport.mode == "peer" and transport.rendezvous:
        listen += [secure(transport.rendezvous), secure("tcp/127.0.0.1:0")]
        connect.append(secure(transport.rendezvous))
    if transport.mode == "router" and not listen:
        listen.append(secure(DEFAULT_ROUTER_LISTEN))
    settings: dict[str, object] = {
        "mode": transport.mode,
        "scouting/multicast/enabled": False,
        # The rendezvous is taken by another peer most of the time: keep going without it.
        "listen/exit_on_failure": not (transport.mode == "peer" and transport.rendezvous),
        "connect/exit_on_failure": False,
        # Never give up on an endpoint: a client waits for its router (one started later is
        # fine); peers and routers open at once and retry in the background, so a peer whose
        # first try found the rendezvous or a router not up yet still joins (with 0, Zenoh
        # tries once: that peer stayed alone for good).
        "connect/timeout_ms": -1,
        "transport/shared_memory/enabled": transport.shared_memory,
        # Zenoh creates the pool lazily by default, sending the first large messages over
        # the network; create it at start instead.
        "transport/shared_memory/mode": "init",
        "transport/shared_memory/transport_optimization/enabled": transport.shared_memory,
        "transport/shared_memory/transport_optimization/pool_size": transport.shm_pool_mb << 20,
        "transport/shared_memory/transport_optimization/message_size_threshold": (
            transport.shm_threshold
        ),
    }
    # Without a config file, empty lists are written too: Zenoh's own default would listen
    # on every interface. With a file, its endpoints stand unless the flags name some.
    if listen or transport.zenoh_config is None:
        settings["listen/endpoints"] = listen
    if connect or transport.zenoh_config is None:
        settings["connect/endpoints"] = connect
    if transport.tls_dir is not None:
        settings.update(_tls_settings(transport.tls_dir, transport.identity))
    for key, value in settings.items():
        config.insert_json5(key, json.dumps(value))
    return config


def _over_tls(endpoint: str) -> str:
    """A loopback default endpoint on TLS instead of TCP (same address and port)."""
    protocol, address = endpoint.split("/", 1)
    return f"tls/{address}" if protocol == "tcp" else endpoint


def _tls_settings(directory: Path, identity: str) -> dict[str, object]:
    """Mutual TLS with `identity`'s certificate: both sides of every link present a
    certificate signed by the CA, and nothing else is accepted (Zenoh's `transport/link`).
    """
    if not identity:
        raise ConfigError("--tls-dir needs --identity NAME (the certificate to present)")
    ca, own = tls_files(directory, identity)
    tls = {
        "root_ca_certificate": str(ca),
        "listen_certificate": str(own.certificate),
        "listen_private_key": str(own.key),
        "connect_certificate": str(own.certificate),
        "connect_private_key": str(own.key),
        "enable_mtls": True,
    }
    # Only TLS and QUIC links: a tcp/ endpoint would bypass the certificates.
    return {"transport/link/protocols": list(SECURE_PROTOCOLS)} | {
        f"transport/link/tls/{key}": value for key, value in tls.items()
    }


def open_session(transport: TransportConfig) -> zenoh.Session:
    """Open a Zenoh session as `transport` describes.

    Raises:
        ConfigError: Zenoh cannot open it (for example an endpoint it cannot listen on).
    """
    config = zenoh_config(transport)
    try:
        return zenoh.open(config)
    except zenoh.ZError as error:
        raise ConfigError(f"cannot open the Zenoh session: {zenoh_message(error)}") from None


def zenoh_message(error: zenoh.ZError) -> str:
    """Zenoh's error message on one line, without its Rust source locations."""
    return " ".join(SOURCE_LOCATION.sub("", str(error)).split())


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago (for a rendezvous of its own)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]
