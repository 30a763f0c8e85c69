"""HTTPS for the dashboard (issue 26: a call needs the camera and microphone, which browsers give only to a
secure origin): the self-signed certificate, the server's TLS context, the settings and the command."""

from __future__ import annotations

import datetime as dt
import ipaddress
import ssl
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from cryptography import x509

from atemr.cli.main import main
from atemr.config import Config, UiConfig, load_config
from atemr.errors import ConfigError
from atemr.ui.server import DashboardServer
from atemr.ui.tls import fingerprint, make_certificate, server_context

FAST_SCRYPT = "scrypt:1024:8:1"


def write_pair(tmp_path: Path, hosts: list[str]) -> tuple[Path, Path]:
    cert, key = make_certificate(hosts)
    (tmp_path / "cert.pem").write_bytes(cert)
    (tmp_path / "key.pem").write_bytes(key)
    return tmp_path / "cert.pem", tmp_path / "key.pem"


def test_a_certificate_names_every_host_and_serves(tmp_path: Path) -> None:
    now = dt.datetime(2026, 11, 25, 12, 0, tzinfo=dt.UTC)
    cert_pem, _ = make_certificate(["kay.local", "192.168.1.20", "::1"], days=30, now=now)
    cert = x509.load_pem_x509_certificate(cert_pem)
    names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert names.get_values_for_type(x509.DNSName) == ["kay.local"]
    assert names.get_values_for_type(x509.IPAddress) == [ipaddress.ip_address("192.168.1.20"),
                                                         ipaddress.ip_address("::1")]
    assert cert.not_valid_after_utc - cert.not_valid_before_utc == dt.timedelta(days=30)
    assert cert.not_valid_before_utc < now  # a tablet whose clock is a little behind still accepts it
    assert len(fingerprint(cert_pem).split(":")) == 32
    context = server_context(*write_pair(tmp_path, ["kay.local"]))
    assert context.minimum_version == ssl.TLSVersion.TLSv1_2


@pytest.mark.parametrize(("hosts", "days", "message"), [
    ([], 30, "at least one host"),
    (["kay local"], 30, "neither a host name nor an IP address"),
    (["http://kay"], 30, "neither a host name nor an IP address"),
    (["kay.local"], 826, "browsers refuse longer"),
])
def test_bad_certificate_requests_are_refused(hosts: list[str], days: int, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        make_certificate(hosts, days=days)


def test_a_missing_or_mismatched_pair_is_a_clear_error(tmp_path: Path) -> None:
    cert, key = write_pair(tmp_path, ["kay.local"])
    with pytest.raises(ConfigError, match=r"missing\.pem.*ui\.tls_key.*file not found|ui\.tls_key"):
        server_context(cert, tmp_path / "missing.pem")
    other = tmp_path / "other"
    other.mkdir()
    _, other_key = write_pair(other, ["kay.local"])
    with pytest.raises(ConfigError, match="cannot use this certificate and key together"):
        server_context(cert, other_key)
    key.write_text("not a key")
    with pytest.raises(ConfigError, match=r"ui\.tls_cert"):
        server_context(cert, key)
    with pytest.raises(ConfigError, match=r"both ui\.tls_cert and ui\.tls_key"):
        UiConfig(tls_cert=cert)
    with pytest.raises(ConfigError, match=r"ui\.tls_cert"):
        load_config(environ={}, overrides={"ui.tls_key": str(key)})


def test_the_dashboard_serves_https_only_with_a_secure_session_cookie(tmp_path: Path) -> None:
    cert, key = write_pair(tmp_path, ["127.0.0.1"])
    config = Config(data_dir=tmp_path / "data", ui=UiConfig(port=0, tls_cert=cert, tls_key=key))
    server = DashboardServer(config, None, hash_method=FAST_SCRYPT)
    server.start()
    try:
        assert server.url.startswith("https://127.0.0.1:")
        trusted = ssl.create_default_context(cafile=str(cert))
        server.app.extensions["atemr.users"].set_password("admin", "tls-admin-pass")
        with urllib.request.urlopen(f"{server.url}/auth/login", context=trusted, timeout=10) as reply:
            assert reply.status == 200 and b'name="csrf_token"' in reply.read()
            cookie = reply.headers["Set-Cookie"]  # the session holding the form's token: never sent in the clear
        assert "atemr_session=" in cookie and "Secure" in cookie and "HttpOnly" in cookie
        # a browser that does not trust the certificate is refused by TLS, not served in the clear
        with pytest.raises(urllib.error.URLError, match="CERTIFICATE_VERIFY_FAILED"):
            urllib.request.urlopen(f"{server.url}/login", context=ssl.create_default_context(), timeout=10)
        with pytest.raises((urllib.error.URLError, ConnectionError, OSError)):
            urllib.request.urlopen(f"http://127.0.0.1:{server.port}/login", timeout=10).read()
    finally:
        server.shutdown()


def test_make_cert_writes_a_pair_the_dashboard_starts_with(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "data"
    assert main(["tls", "make-cert", "--data-dir", str(data), "--host", "kay.local", "--host", "10.0.0.7"]) == 0
    out = capsys.readouterr().out
    cert, key = data / "tls" / "cert.pem", data / "tls" / "key.pem"
    assert f"tls_cert: {cert}" in out and f"tls_key: {key}" in out and "SHA-256 fingerprint" in out
    assert "https://kay.local:5000/" in out
    assert key.stat().st_mode & 0o077 == 0, "the private key is the robot's alone"
    server_context(cert, key)
    before = cert.read_bytes()
    assert main(["tls", "make-cert", "--data-dir", str(data), "--host", "kay.local"]) == 2
    assert "--force replaces it" in capsys.readouterr().err and cert.read_bytes() == before
    assert main(["tls", "make-cert", "--data-dir", str(data), "--host", "kay.local", "--force"]) == 0
    assert cert.read_bytes() != before
