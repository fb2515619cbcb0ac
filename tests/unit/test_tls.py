"""A run's TLS material (kernel/tls.py): the chain verifies, the names are the ones asked for,
one client certificate per identity, private files, and the settings zenoh opens with.

The chain is checked with ``cryptography``'s own path validation (``x509.verification``), as a
TLS peer would, and each signature once more by hand with the CA's public key; the bus
behaviour (who gets through a live TLS router) is tested in ``tests/e2e/test_tls.py``.
"""

from __future__ import annotations

import base64
import datetime
import ipaddress
import json

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.hazmat.primitives.serialization import load_pem_private_key
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
from cryptography.x509.verification import (
    Criticality,
    ExtensionPolicy,
    PolicyBuilder,
    Store,
    VerificationError,
)

from core.errors import ConfigError
from kernel.bus import BusConfig, zenoh_config
from kernel.security import client_settings, credential_path, read_credential, router_settings
from kernel.tls import (
    CA_CERT,
    CA_KEY,
    ROUTER_CERT,
    ROUTER_KEY,
    alt_names,
    covers,
    issue,
    new_ca,
    read_ca,
    router_link,
    router_names,
    write_tls,
)
from runtime.router import router_at
from runtime.security import check_tls, listen_names, pick_endpoint, prepare
from scenario import load_scenario
from tests.conftest import BENCHMARK


def _cert(pem: str) -> x509.Certificate:
    return x509.load_pem_x509_certificate(pem.encode())


def _server_ok(ca_pem: str, cert_pem: str, name: str) -> bool:
    """Whether a TLS client trusting only ``ca_pem`` accepts ``cert_pem`` as server ``name``."""
    subject: x509.GeneralName
    try:
        subject = x509.IPAddress(ipaddress.ip_address(name))
    except ValueError:
        subject = x509.DNSName(name)
    verifier = PolicyBuilder().store(Store([_cert(ca_pem)])).build_server_verifier(subject)
    try:
        verifier.verify(_cert(cert_pem), [])
    except VerificationError:
        return False
    return True


def _client_ok(ca_pem: str, cert_pem: str) -> bool:
    """Whether a TLS server trusting only ``ca_pem`` takes ``cert_pem`` from a client, as
    rustls's client verifier does: the chain, the validity, ``clientAuth``; and no alternative
    name asked for (``cryptography``'s default client policy wants one; rustls does not)."""
    ee = ExtensionPolicy.webpki_defaults_ee().may_be_present(
        x509.SubjectAlternativeName, Criticality.AGNOSTIC, None
    )
    verifier = (
        PolicyBuilder()
        .store(Store([_cert(ca_pem)]))
        .extension_policies(ca_policy=ExtensionPolicy.webpki_defaults_ca(), ee_policy=ee)
        .build_client_verifier()
    )
    try:
        chain = verifier.verify(_cert(cert_pem), []).chain
    except VerificationError:
        return False
    return [c.subject for c in chain[1:]] == [_cert(ca_pem).subject]


def _signed_by(ca_pem: str, cert_pem: str) -> bool:
    """The signature checked by hand: ECDSA-SHA256 over the certificate's TBS bytes."""
    public = _cert(ca_pem).public_key()
    assert isinstance(public, ec.EllipticCurvePublicKey)
    cert = _cert(cert_pem)
    try:
        public.verify(cert.signature, cert.tbs_certificate_bytes, ec.ECDSA(hashes.SHA256()))
    except Exception:  # noqa: BLE001 - InvalidSignature: not signed by it
        return False
    return True


def _cn(cert_pem: str) -> str:
    return str(_cert(cert_pem).subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value)


def test_the_ca_is_a_ca_of_its_own_and_signs_only_certificates():
    ca = new_ca("wncs run r1")
    cert = _cert(ca.cert)
    assert cert.subject == cert.issuer and _cn(ca.cert) == "wncs run r1"
    assert _signed_by(ca.cert, ca.cert)
    basic = cert.extensions.get_extension_for_class(x509.BasicConstraints).value
    assert basic.ca and basic.path_length == 0
    usage = cert.extensions.get_extension_for_class(x509.KeyUsage).value
    assert usage.key_cert_sign and not usage.digital_signature
    public = cert.public_key()
    assert isinstance(public, ec.EllipticCurvePublicKey) and public.curve.name == "secp256r1"
    now = datetime.datetime.now(datetime.UTC)
    assert cert.not_valid_before_utc < now < cert.not_valid_after_utc


def test_the_routers_certificate_covers_the_loopback_and_the_names_asked_for(tmp_path):
    pairs = write_tls(tmp_path, ["reactor", "router"], names=("a.example.org", "10.1.2.3"))
    ca = (tmp_path / CA_CERT).read_text()
    router = (tmp_path / ROUTER_CERT).read_text()
    assert (
        pairs["router"].cert == router
        and pairs["router"].key == (tmp_path / ROUTER_KEY).read_text()
    )
    assert alt_names(router) == {"127.0.0.1", "::1", "localhost", "a.example.org", "10.1.2.3"}
    for name in ("127.0.0.1", "::1", "localhost", "a.example.org", "10.1.2.3"):
        assert _server_ok(ca, router, name), name
    for name in ("b.example.org", "10.1.2.4", "example.org"):
        assert not _server_ok(ca, router, name), name
    assert _signed_by(ca, router) and _cn(router) == "router"
    eku = _cert(router).extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
    assert set(eku) == {ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH}
    assert _client_ok(ca, router)  # it connects to other routers with it (mutual TLS)


def test_one_client_certificate_per_identity_named_by_it(tmp_path):
    names = ["clock", "historian", "level_controller", "reactor", "router"]
    pairs = write_tls(tmp_path, names)
    ca = (tmp_path / CA_CERT).read_text()
    assert sorted(pairs) == names
    for name in names:
        assert _cn(pairs[name].cert) == name
        assert _client_ok(ca, pairs[name].cert) and _signed_by(ca, pairs[name].cert)
        key = x509.load_pem_x509_certificate(pairs[name].cert.encode()).public_key()
        private = pairs[name].key.encode()
        loaded = _load_key(private)  # the pair's key is its certificate's
        assert loaded.public_key().public_numbers() == key.public_numbers()  # type: ignore[union-attr]
    clients = [pairs[n].cert for n in names if n != "router"]
    for cert in clients:  # a client's certificate serves nobody
        assert not _server_ok(ca, cert, "localhost")
        eku = _cert(cert).extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
        assert list(eku) == [ExtendedKeyUsageOID.CLIENT_AUTH]
    assert len({_cert(c).public_key().public_numbers() for c in clients}) == len(clients)  # type: ignore[union-attr]
    stranger = new_ca("another run")  # another run's CA: its certificates are not this run's
    other = issue(stranger, "reactor")
    assert not _client_ok(ca, other.cert) and not _signed_by(ca, other.cert)


def _load_key(pem: bytes) -> ec.EllipticCurvePrivateKey:
    key = load_pem_private_key(pem, password=None)
    assert isinstance(key, ec.EllipticCurvePrivateKey)
    return key


def test_a_tls_runs_security_files_are_private_and_credentials_carry_the_certificates(tmp_path):
    directory = prepare(tmp_path, load_scenario(BENCHMARK), "rtls", tls=True)
    assert directory.stat().st_mode & 0o777 == 0o700
    files = {p.name for p in directory.iterdir()}
    assert {CA_CERT, CA_KEY, ROUTER_CERT, ROUTER_KEY, "reactor.json", "inject.json"} <= files
    for p in directory.iterdir():
        assert p.stat().st_mode & 0o777 == 0o600, p
    ca = (directory / CA_CERT).read_text()
    assert _cn(ca) == "wncs run rtls"
    cred = read_credential(credential_path(directory, "reactor"))
    assert cred.user == "reactor" and cred.tls is not None and cred.tls.ca == ca
    assert _cn(cred.tls.cert) == "reactor" and _client_ok(ca, cred.tls.cert)
    link = client_settings(cred)["transport/link/tls"]
    assert link["enable_mtls"] is True
    assert base64.b64decode(link["root_ca_certificate_base64"]).decode() == ca
    assert base64.b64decode(link["connect_certificate_base64"]).decode() == cred.tls.cert
    assert base64.b64decode(link["connect_private_key_base64"]).decode() == cred.tls.key
    zenoh_config(
        BusConfig(mode="client", connect=("tls/127.0.0.1:7447",), settings=client_settings(cred))
    )
    settings = router_settings(directory)
    rlink = settings["transport/link/tls"]
    assert rlink["enable_mtls"] is True
    assert (
        base64.b64decode(rlink["listen_certificate_base64"]).decode()
        == (directory / ROUTER_CERT).read_text()
    )
    zenoh_config(BusConfig(mode="router", listen=("tls/127.0.0.1:0",), settings=settings))


def test_a_tls_runs_access_control_names_each_identity_by_password_and_certificate(tmp_path):
    directory = prepare(tmp_path, load_scenario(BENCHMARK), "rtls", tls=True)
    acl = json.loads((directory / "access_control.json").read_text())
    subjects = {s["id"]: s for s in acl["subjects"]}
    assert "reactor" in subjects and "router" in subjects
    for name, subject in subjects.items():
        assert subject["usernames"] == [name] and subject["cert_common_names"] == [name]
    plain = prepare(tmp_path / "plain", load_scenario(BENCHMARK), "rplain")
    acl = json.loads((plain / "access_control.json").read_text())
    assert all("cert_common_names" not in s for s in acl["subjects"])


def test_a_plain_secure_run_is_unchanged(tmp_path):
    directory = prepare(tmp_path, load_scenario(BENCHMARK), "rplain")
    assert not (directory / CA_CERT).exists() and not (directory / ROUTER_KEY).exists()
    data = json.loads(credential_path(directory, "reactor").read_text())
    assert set(data) == {"user", "password"}
    cred = read_credential(credential_path(directory, "reactor"))
    assert cred.tls is None and set(client_settings(cred)) == {"transport/auth/usrpwd"}
    assert "transport/link/tls" not in router_settings(directory)


def test_a_router_on_another_host_gets_a_certificate_of_its_own_for_its_names(tmp_path):
    write_tls(tmp_path, ["router"], names=("a.example.org",))
    ca = (tmp_path / CA_CERT).read_text()
    same = router_link(tmp_path, ("a.example.org",))
    assert (
        base64.b64decode(same["listen_certificate_base64"]).decode()
        == (tmp_path / ROUTER_CERT).read_text()
    )
    other = router_link(tmp_path, ("b.example.org",))
    cert = base64.b64decode(other["listen_certificate_base64"]).decode()
    assert cert != (tmp_path / ROUTER_CERT).read_text()
    assert _server_ok(ca, cert, "b.example.org") and _server_ok(ca, cert, "127.0.0.1")
    assert not _server_ok(ca, cert, "a.example.org")
    assert _cn(cert) == "router" and _signed_by(read_ca(tmp_path).cert, cert)
    assert covers(cert, ["b.example.org", "[::1]"]) and not covers(cert, ["c.example.org"])


@pytest.mark.parametrize("bad", ["tls/a:1", "a b", "", "-a.org", "a_b.org"])
def test_a_name_that_is_no_host_is_refused(bad):
    with pytest.raises(ConfigError, match="--tls-name"):
        router_names([bad])


def test_router_names_put_the_loopback_first_and_each_once():
    assert router_names(["LocalHost", "h.example.org", "[::1]", "10.0.0.1", "H.example.org"]) == (
        "127.0.0.1",
        "::1",
        "localhost",
        "h.example.org",
        "10.0.0.1",
    )


def test_tls_options_are_checked():
    check_tls("tls/127.0.0.1:0", tls=True, insecure=False)
    check_tls("tcp/127.0.0.1:0", tls=False, insecure=True)
    with pytest.raises(ConfigError, match="--insecure"):
        check_tls("tls/127.0.0.1:0", tls=True, insecure=True)
    with pytest.raises(ConfigError, match="not a tls/ endpoint"):
        check_tls("tcp/127.0.0.1:0", tls=True, insecure=False)
    assert listen_names("tls/0.0.0.0:7447") == () and listen_names("tls/[::]:7447") == ()
    assert listen_names("tls/a.example.org:7447") == ("a.example.org",)
    assert listen_names("tls/[fe80::1]:7447") == ("fe80::1",)
    locators = ["tcp/127.0.0.1:1", "tls/127.0.0.1:2"]
    assert pick_endpoint(locators, "tls/127.0.0.1:0") == "tls/127.0.0.1:2"
    assert pick_endpoint(locators, "tcp/127.0.0.1:0") == "tcp/127.0.0.1:1"
    # a router on 0.0.0.0 reports the host's addresses: a TLS endpoint names what its certificate
    # covers (the loopback, or the first name given); plain tcp keeps the first locator
    wide = ["tls/192.0.2.2:7447", "tls/198.51.100.7:7447"]
    assert pick_endpoint(wide, "tls/0.0.0.0:7447") == "tls/127.0.0.1:7447"
    assert pick_endpoint(wide, "tls/0.0.0.0:7447", ("a.example.org",)) == "tls/a.example.org:7447"
    assert pick_endpoint(wide, "tls/0.0.0.0:7447", ("198.51.100.7",)) == "tls/198.51.100.7:7447"
    assert pick_endpoint(wide, "tls/[::]:7447", ("fe80::1",)) == "tls/[fe80::1]:7447"
    assert pick_endpoint(["tcp/192.0.2.2:1"], "tcp/0.0.0.0:1") == "tcp/192.0.2.2:1"


def test_a_router_of_the_run_is_found_by_any_name_of_its_host():
    """``wncs router --connect tls/A:7447`` finds the run's router that listens there, whether
    ``run.json`` recorded it by that endpoint, by one of its locators, or by an address ``A``
    resolves to (``localhost`` resolves to the loopback on every host)."""
    routers = [
        {"endpoint": "tls/127.0.0.1:7447", "zid": "a1", "locators": ["tls/127.0.0.1:7447"]},
        {"endpoint": "tls/10.9.8.7:7448", "zid": "b2", "locators": ["tls/10.9.8.7:7448"]},
        {"endpoint": "tcp/10.9.8.6:7449", "zid": "c3"},  # written before routers had locators
    ]
    assert router_at("tls/127.0.0.1:7447", routers) == "a1"
    assert router_at("tls/localhost:7447", routers) == "a1"
    assert router_at("tls/10.9.8.7:7448", routers) == "b2"
    assert router_at("tcp/10.9.8.6:7449", routers) == "c3"
    assert router_at("tls/localhost:7448", routers) is None  # no router of the run there
    assert router_at("tcp/localhost:7447", routers) is None  # another protocol
    assert router_at("tls/no-such-host.invalid:7447", routers) is None
