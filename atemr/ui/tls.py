"""HTTPS for the dashboard: the server's TLS context, and a self-signed certificate for a robot at home.

Browsers give a page the camera and the microphone only on a secure origin (``https://``, or ``localhost``).
The carer's laptop and the robot's tablet reach the robot by its address on the home network, so without
HTTPS neither could join a call. A home has no certificate authority and often no domain name: the robot
makes its own certificate (`make_certificate`, ``atemr tls make-cert``) for the names and addresses it is
reached by, and each device accepts it once (or installs it, which its SHA-256 fingerprint lets the carer
check). A certificate from a real authority (behind a domain name) works the same way: ``ui.tls_cert`` and
``ui.tls_key`` name any PEM pair.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import ssl
from collections.abc import Sequence
from pathlib import Path

from atemr.errors import ConfigError

#: Longest validity browsers accept for a server certificate they are asked to trust (Apple's limit).
MAX_DAYS = 825


def server_context(cert: Path, key: Path) -> ssl.SSLContext:
    """A TLS server context with the PEM certificate (chain) ``cert`` and its private key ``key``.

    Raises `ConfigError` naming the file and what is wrong with it (missing, not PEM, key not matching),
    at start-up, never on the first browser's connection."""
    for path, name in ((cert, "ui.tls_cert"), (key, "ui.tls_key")):
        if not path.is_file():
            raise ConfigError("file not found", file=str(path), path=name)
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        context.load_cert_chain(cert, key)
    except ssl.SSLError as exc:
        raise ConfigError(f"cannot use this certificate and key together: {exc.reason or exc}",
                          file=str(cert), path="ui.tls_cert") from None
    return context


def make_certificate(hosts: Sequence[str], *, days: int = MAX_DAYS,
                     now: dt.datetime | None = None) -> tuple[bytes, bytes]:
    """A self-signed certificate for ``hosts`` (DNS names or IP addresses, the first is its common name) and
    its private key, both PEM. An ECDSA P-256 key: small, fast, and accepted by every current browser."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    if not hosts:
        raise ConfigError("name at least one host the robot is reached by (its name or address)", path="--host")
    if not 1 <= days <= MAX_DAYS:
        raise ConfigError(f"must be within 1..{MAX_DAYS} days (browsers refuse longer), got {days}", path="--days")
    names: list[x509.GeneralName] = []
    for host in hosts:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            if not host or any(c.isspace() or c in "/:@" for c in host):
                raise ConfigError(f"{host!r} is neither a host name nor an IP address", path="--host") from None
            names.append(x509.DNSName(host))
    key = ec.generate_private_key(ec.SECP256R1())
    start = (now or dt.datetime.now(dt.UTC)) - dt.timedelta(minutes=5)  # a tablet's clock a little behind
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, hosts[0]),
                         x509.NameAttribute(NameOID.ORGANIZATION_NAME, "ATEMR robot")])
    cert = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(start + dt.timedelta(days=days))
        .add_extension(x509.SubjectAlternativeName(names), critical=False)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH]), critical=False)
        .sign(key, hashes.SHA256())
    )
    key_pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                serialization.NoEncryption())
    return cert.public_bytes(serialization.Encoding.PEM), key_pem


def fingerprint(cert_pem: bytes) -> str:
    """The certificate's SHA-256 fingerprint as browsers show it (``AB:CD:...``), to check on each device."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes

    digest = x509.load_pem_x509_certificate(cert_pem).fingerprint(hashes.SHA256())
    return ":".join(f"{b:02X}" for b in digest)
