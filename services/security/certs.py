"""A local certificate authority for testing and small labs: one CA, one key and
certificate per service identity (the identity is the certificate's common name, which
Zenoh's access control matches with `cert_common_names`).

Files in one folder: `ca.pem` / `ca.key` for the CA, `<name>.pem` / `<name>.key` per
identity, PEM encoded; private keys are written with permissions 0600. Keys are ECDSA
P-256. An organization's own CA replaces all of this: Zenoh only reads the PEM files.
"""

from __future__ import annotations

import datetime
import ipaddress
import os
import re
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from hamnet.runtime.errors import ConfigError
from hamnet.runtime.tls_files import Identity, ca_files, identity_files

DEFAULT_HOSTS = ("localhost", "127.0.0.1")
"""Subject alternative names every certificate gets, so loopback endpoints verify."""


def init_ca(directory: Path, days: int, force: bool = False) -> Identity:
    """Create a CA (self-signed, may sign end-entity certificates only) in `directory`.

    Raises:
        ConfigError: its files exist and `force` is False.
    """
    files = ca_files(directory)
    _check_free(files, force, "hamnet certs init")
    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "hamnet local CA")])
    builder = _builder(subject, subject, key.public_key(), days)
    builder = builder.add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
    builder = builder.add_extension(_key_usage(ca=True), critical=True)
    builder = builder.add_extension(
        x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False
    )
    _write(files, builder.sign(key, hashes.SHA256()), key)
    return files


def issue(
    directory: Path, name: str, days: int, hosts: tuple[str, ...] = (), force: bool = False
) -> Identity:
    """Issue a key and certificate for identity `name`, signed by the CA in `directory`.

    Args:
        hosts: host names or IP addresses the identity is reached at (a router's
            address), added to localhost and 127.0.0.1 as subject alternative names.

    Raises:
        ConfigError: no CA in `directory`, a bad name or host, or the files exist and
            `force` is False.
    """
    files = identity_files(directory, name)
    ca = ca_files(directory)
    if not (ca.certificate.is_file() and ca.key.is_file()):
        raise ConfigError(f"no CA in {directory}: run `hamnet certs init --dir {directory}` first")
    _check_free(files, force, f"hamnet certs issue {name}")
    ca_certificate = x509.load_pem_x509_certificate(ca.certificate.read_bytes())
    ca_key = serialization.load_pem_private_key(ca.key.read_bytes(), password=None)
    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    builder = _builder(subject, ca_certificate.subject, key.public_key(), days)
    builder = builder.add_extension(x509.BasicConstraints(ca=False, path_length=None), True)
    builder = builder.add_extension(_key_usage(ca=False), critical=True)
    # Every identity both accepts and opens TLS links (a router listens, a client connects).
    usages = [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
    builder = builder.add_extension(x509.ExtendedKeyUsage(usages), critical=False)
    builder = builder.add_extension(_alternative_names((*DEFAULT_HOSTS, *hosts)), False)
    builder = builder.add_extension(
        x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_certificate.public_key()), False
    )
    _write(files, builder.sign(ca_key, hashes.SHA256()), key)
    return files


def common_name(certificate: Path) -> str:
    """The common name of a PEM certificate (the identity Zenoh's access control sees)."""
    loaded = x509.load_pem_x509_certificate(certificate.read_bytes())
    return str(loaded.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value)


def _builder(
    subject: x509.Name, issuer: x509.Name, public_key: ec.EllipticCurvePublicKey, days: int
) -> x509.CertificateBuilder:
    if days < 1:
        raise ConfigError(f"days must be >= 1, got {days}")
    # Back-dated a little so a peer whose clock lags does not see "not yet valid".
    now = datetime.datetime.now(datetime.timezone.utc) - datetime.timedelta(minutes=5)
    return (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(issuer)
        .public_key(public_key)
        .serial_number(x509.random_serial_number())
        .not_valid_before(now)
        .not_valid_after(now + datetime.timedelta(days=days))
    )


def _key_usage(ca: bool) -> x509.KeyUsage:
    return x509.KeyUsage(
        digital_signature=not ca,
        content_commitment=False,
        key_encipherment=False,
        data_encipherment=False,
        key_agreement=False,
        key_cert_sign=ca,
        crl_sign=ca,
        encipher_only=False,
        decipher_only=False,
    )


def _alternative_names(hosts: tuple[str, ...]) -> x509.SubjectAlternativeName:
    names: list[x509.GeneralName] = []
    for host in dict.fromkeys(hosts):
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            if not re.fullmatch(r"[A-Za-z0-9*]([A-Za-z0-9.-]*[A-Za-z0-9])?", host):
                raise ConfigError(
                    f"host {host!r} is neither a host name nor an IP address"
                ) from None
            names.append(x509.DNSName(host))
    return x509.SubjectAlternativeName(names)


def _check_free(files: Identity, force: bool, command: str) -> None:
    existing = [p for p in (files.certificate, files.key) if p.exists()]
    if existing and not force:
        raise ConfigError(f"{existing[0]} exists: pass --force to replace it ({command})")


def _write(files: Identity, certificate: x509.Certificate, key: ec.EllipticCurvePrivateKey) -> None:
    files.key.parent.mkdir(parents=True, exist_ok=True)
    pem = key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )
    # Created 0600 from the start: the key is never readable by others, not even briefly.
    files.key.unlink(missing_ok=True)
    descriptor = os.open(files.key, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(descriptor, "wb") as out:
        out.write(pem)
    files.certificate.write_bytes(certificate.public_bytes(serialization.Encoding.PEM))
