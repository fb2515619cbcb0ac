"""A run's TLS material: its own certificate authority, the routers' certificate, one client
certificate per identity (``wncs run --tls``, ``wncs router --tls``).

Zenoh's ``tls/`` links (rustls, ring provider) encrypt the traffic between a node and a router,
and between routers; the user-password login of :mod:`kernel.security` still runs inside them.
With ``enable_mtls`` the router takes a TLS connection only from a client that shows a
certificate the run's CA signed, so a client needs both its certificate and its password; and
the access control of a TLS run (:func:`kernel.security.access_control`, ``by_certificate``)
names each identity by both, so they must be the same identity's.

What this module makes, with ``cryptography`` (keys EC P-256, signatures ECDSA-SHA256; zenoh
1.10's rustls takes Ed25519 too, measured, but P-256 is what every TLS tool reads):

- the run's CA: self-signed, ``CA:TRUE, pathlen 0``, signs certificates only;
- the routers' certificate: CN ``router``, subject alternative names for the loopback interface
  (``127.0.0.1``, ``::1``, ``localhost``) and for each name given (a DNS name or an IP address:
  the names by which nodes on other hosts reach the router), usable to serve (``serverAuth``)
  and to connect to another router (``clientAuth``);
- per identity a client certificate: CN the identity, ``clientAuth`` only, no alternative names.

A client verifies the router's name against the endpoint it connects to
(``verify_name_on_connect``, zenoh's default): ``tls/HOST:PORT`` must name a host the routers'
certificate lists. This module names no node kind: identities and names come from the caller.
"""

from __future__ import annotations

import base64
import datetime
import ipaddress
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from core.errors import ConfigError
from kernel.files import write_private

__all__ = [
    "LOOPBACK_NAMES",
    "CA_CERT",
    "CA_KEY",
    "ROUTER_CERT",
    "ROUTER_KEY",
    "Pair",
    "RunCa",
    "router_names",
    "new_ca",
    "issue",
    "covers",
    "alt_names",
    "write_tls",
    "read_ca",
    "is_tls",
    "name_of_endpoint",
    "ClientTls",
    "client_link",
    "router_link",
]

LOOPBACK_NAMES = ("127.0.0.1", "::1", "localhost")
"""Names every routers' certificate covers: a run on one host connects over the loopback."""

CA_CERT = "ca.pem"
CA_KEY = "ca.key"
ROUTER_CERT = "router.pem"
ROUTER_KEY = "router.key"

_VALID = datetime.timedelta(days=365)
_SKEW = datetime.timedelta(minutes=5)  # hosts whose clocks differ a little still agree


@dataclass(frozen=True)
class Pair:
    """A private key and its certificate, both PEM text."""

    key: str
    cert: str


@dataclass(frozen=True)
class RunCa(Pair):
    """The run's certificate authority: its key and its self-signed certificate (PEM)."""


def _pem_key(key: ec.EllipticCurvePrivateKey) -> str:
    return key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    ).decode()


def _pem_cert(cert: x509.Certificate) -> str:
    return cert.public_bytes(serialization.Encoding.PEM).decode()


def _general_name(name: str) -> x509.GeneralName:
    try:
        return x509.IPAddress(ipaddress.ip_address(name.strip("[]")))
    except ValueError:
        return x509.DNSName(name)


def router_names(names: Iterable[str] = ()) -> tuple[str, ...]:
    """The loopback names and ``names`` (in that order, each once): what a routers' certificate
    covers. A name is a DNS name or an IP address; anything else is refused (``ConfigError``)."""
    out: list[str] = []
    for name in (*LOOPBACK_NAMES, *names):
        name = name.strip().strip("[]")
        if not (_is_ip(name) or _DNS.fullmatch(name)):
            raise ConfigError(f"--tls-name {name!r}: not a host name or an IP address")
        key = _canonical(name)
        if key not in out:
            out.append(key)
    return tuple(out)


_DNS = re.compile(
    r"(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?"
    r"(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*"
)


def _canonical(name: str) -> str:
    """A host name as a certificate's alternative names hold it: an IP address in its
    standard text, a DNS name in lower case."""
    return str(ipaddress.ip_address(name)) if _is_ip(name) else name.lower()


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def _builder(
    subject: str, issuer: x509.Name, public: ec.EllipticCurvePublicKey
) -> x509.CertificateBuilder:
    now = datetime.datetime.now(datetime.UTC)
    return (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, subject)]))
        .issuer_name(issuer)
        .public_key(public)
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - _SKEW)
        .not_valid_after(now + _VALID)
    )


_KEY_USAGES = (
    "digital_signature",
    "content_commitment",
    "key_encipherment",
    "data_encipherment",
    "key_agreement",
    "key_cert_sign",
    "crl_sign",
    "encipher_only",
    "decipher_only",
)


def _key_usage(*, signs_certificates: bool) -> x509.KeyUsage:
    """A CA's key signs certificates (and revocation lists) only; a router's or a node's
    signs its TLS handshakes only (every other usage of :data:`_KEY_USAGES` off)."""
    on = {"key_cert_sign", "crl_sign"} if signs_certificates else {"digital_signature"}
    return x509.KeyUsage(**{usage: usage in on for usage in _KEY_USAGES})


def new_ca(common_name: str) -> RunCa:
    """A fresh certificate authority named ``common_name`` (the run's: ``wncs run r1a2b3``)."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])
    usage = _key_usage(signs_certificates=True)
    cert = (
        _builder(common_name, name, key.public_key())
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(usage, critical=True)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return RunCa(_pem_key(key), _pem_cert(cert))


def issue(ca: RunCa, common_name: str, *, names: Iterable[str] = (), server: bool = False) -> Pair:
    """A key and a certificate for ``common_name`` signed by ``ca``: a server's (``server``:
    ``serverAuth`` and ``clientAuth``, alternative names ``names``) or a client's (``clientAuth``
    only)."""
    ca_key = serialization.load_pem_private_key(ca.key.encode(), password=None)
    ca_cert = x509.load_pem_x509_certificate(ca.cert.encode())
    if not isinstance(ca_key, ec.EllipticCurvePrivateKey):
        raise ConfigError("the run's CA key is not an EC key")
    key = ec.generate_private_key(ec.SECP256R1())
    usage = _key_usage(signs_certificates=False)
    purposes = [ExtendedKeyUsageOID.CLIENT_AUTH]
    if server:
        purposes.insert(0, ExtendedKeyUsageOID.SERVER_AUTH)
    builder = (
        _builder(common_name, ca_cert.subject, key.public_key())
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(usage, critical=True)
        .add_extension(x509.ExtendedKeyUsage(purposes), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False
        )
    )
    sans = [_general_name(n) for n in names]
    if sans:
        builder = builder.add_extension(x509.SubjectAlternativeName(sans), critical=False)
    return Pair(_pem_key(key), _pem_cert(builder.sign(ca_key, hashes.SHA256())))


def alt_names(cert_pem: str) -> set[str]:
    """The DNS names and IP addresses (as text) a certificate's alternative names list."""
    cert = x509.load_pem_x509_certificate(cert_pem.encode())
    try:
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except x509.ExtensionNotFound:
        return set()
    return {n.lower() for n in san.get_values_for_type(x509.DNSName)} | {
        str(ip) for ip in san.get_values_for_type(x509.IPAddress)
    }


def covers(cert_pem: str, names: Iterable[str]) -> bool:
    """Whether the certificate's alternative names include every one of ``names``."""
    have = alt_names(cert_pem)
    return all(_canonical(name.strip("[]")) in have for name in names)


def write_tls(
    directory: Path, identities: Iterable[str], *, names: Iterable[str] = (), ca_name: str = "wncs"
) -> dict[str, Pair]:
    """Make a run's TLS material in ``directory`` (which exists): the CA (``ca.pem``,
    ``ca.key``) and the routers' certificate for :func:`router_names` of ``names``
    (``router.pem``, ``router.key``), each mode 0600; return a client pair per identity (CN the
    identity), for the caller to hand to each (:mod:`kernel.security` puts it in the identity's
    credential file). The identity ``router`` gets the routers' pair."""
    ca = new_ca(ca_name)
    router = issue(ca, "router", names=router_names(names), server=True)
    write_private(directory / CA_CERT, ca.cert)
    write_private(directory / CA_KEY, ca.key)
    write_private(directory / ROUTER_CERT, router.cert)
    write_private(directory / ROUTER_KEY, router.key)
    return {
        name: router if name == "router" else issue(ca, name) for name in sorted(set(identities))
    }


def read_ca(directory: Path) -> RunCa:
    """The run's CA from ``directory`` (``ConfigError`` if it cannot be read)."""
    try:
        return RunCa((directory / CA_KEY).read_text(), (directory / CA_CERT).read_text())
    except OSError as err:
        raise ConfigError(f"security {directory}: no TLS authority to read: {err}") from err


def is_tls(directory: Path) -> bool:
    """Whether the security directory holds TLS material (the run is a ``--tls`` run)."""
    return (directory / CA_CERT).is_file()


def name_of_endpoint(endpoint: str) -> str:
    """The host of a zenoh endpoint (``tls/host:7447`` -> ``host``; ``[::1]`` -> ``::1``)."""
    return endpoint.partition("/")[2].rpartition(":")[0].strip("[]")


@dataclass(frozen=True)
class ClientTls:
    """What a client needs to open a TLS link to a router of the run: the run's CA certificate
    (to trust the router), its own certificate and key (to be let in: mutual TLS), PEM text."""

    ca: str
    cert: str
    key: str


def _b64(text: str) -> str:
    return base64.b64encode(text.encode()).decode()


def client_link(tls: ClientTls) -> dict[str, Any]:
    """Zenoh's ``transport/link/tls`` section of a client: trust the run's CA, show its own
    certificate (given inline, base64: the credential file is all a node needs)."""
    return {
        "root_ca_certificate_base64": _b64(tls.ca),
        "enable_mtls": True,
        "connect_private_key_base64": _b64(tls.key),
        "connect_certificate_base64": _b64(tls.cert),
    }


def router_link(directory: Path, names: Iterable[str] = ()) -> dict[str, Any]:
    """Zenoh's ``transport/link/tls`` section of a router of the run whose material is in
    ``directory``: serve with the routers' certificate, take only clients whose certificate the
    run's CA signed (mutual TLS), and show the same certificate to the routers it joins.

    If the routers' certificate does not cover every one of ``names`` (a router on another host,
    ``wncs router --tls-name B``), this router gets a certificate of its own for
    :func:`router_names` of ``names``, signed by the run's CA, held in memory only."""
    try:
        cert = (directory / ROUTER_CERT).read_text()
        key = (directory / ROUTER_KEY).read_text()
    except OSError as err:
        raise ConfigError(f"security {directory}: no routers' certificate to read: {err}") from err
    try:
        ca_cert = (directory / CA_CERT).read_text()
    except OSError as err:
        raise ConfigError(f"security {directory}: no TLS authority to read: {err}") from err
    wanted = router_names(names)
    if not covers(cert, wanted):
        pair = issue(read_ca(directory), "router", names=wanted, server=True)
        cert, key = pair.cert, pair.key
    return {
        "root_ca_certificate_base64": _b64(ca_cert),
        "listen_private_key_base64": _b64(key),
        "listen_certificate_base64": _b64(cert),
        "enable_mtls": True,
        "connect_private_key_base64": _b64(key),
        "connect_certificate_base64": _b64(cert),
    }
