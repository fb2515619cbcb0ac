"""A run's security configuration: per-identity zenoh credentials and the router's access control.

Secure by default (issue 19): every run gets a fresh user name and password per identity (each
node, ``inject``, ``dashboard``, and ``router`` for routers joining each other), written with mode
0600 under the run directory, and an access-control configuration for its router(s) that denies
everything not granted. A :class:`Grant` says what one identity may do, in absolute key
expressions; :func:`access_control` turns the grants into zenoh's ``access_control`` section
(rules, subjects by user name, policies; ``default_permission: deny``), and
:func:`router_settings` / :func:`client_settings` into the JSON5 settings a session opens with
(``transport/auth/usrpwd``: ``user``, ``password``, and the router's ``dictionary_file``).

What zenoh 1.10 checks, as measured on loopback with the wheel this project installs: a client
without credentials, or with a wrong password, cannot open a session; the router drops a ``put``,
a subscription or a liveliness token that no rule allows (ingress), and delivers a publication or
a token to a client only where a rule allows it (egress). Its own in-process session is not
filtered. What it does not check is *who* a message claims to be from (the envelope's ``src``)
or its run and round: the nodes do that (:mod:`kernel.node`).

A ``--tls`` run (``write_security(..., tls=True)``) adds its TLS material (:mod:`kernel.tls`): each
credential file then holds its identity's client certificate too, and the settings open the
session over mutual TLS (``transport/link/tls``).

This module names no node kind: the grants come from the layer above (``runtime.security``).
"""

from __future__ import annotations

import json
import os
import secrets
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from core.errors import ConfigError
from kernel.files import write_private
from kernel.tls import CA_CERT, ClientTls, client_link, is_tls, router_link, write_tls

__all__ = [
    "ROUTER",
    "SECURITY_DIR",
    "Grant",
    "Credential",
    "access_control",
    "write_security",
    "read_credential",
    "credential_path",
    "router_settings",
    "client_settings",
]

ROUTER = "router"
"""The identity routers authenticate with when they join each other."""

SECURITY_DIR = "security"
"""Where a run directory keeps its credentials and access control (mode 0700)."""

_DICTIONARY = "passwords.txt"
_ACL = "access_control.json"


@dataclass(frozen=True)
class Grant:
    """What one identity may do on the bus, as absolute key expressions.

    Attributes
    ----------
    puts : key expressions it may publish on.
    subscribes : key expressions it may subscribe to (and receive publications on).
    tokens : liveliness tokens it may declare (its own name only).
    watches : liveliness key expressions it may subscribe to and query.
    matches : key expressions whose subscribers it may learn of (a publisher's matching
        listener: ``wncs inject`` waits for the clock's subscription before it sends).
    """

    puts: tuple[str, ...] = ()
    subscribes: tuple[str, ...] = ()
    tokens: tuple[str, ...] = ()
    watches: tuple[str, ...] = ()
    matches: tuple[str, ...] = ()

    @staticmethod
    def union(grants: Iterable[Grant]) -> Grant:
        """What any of ``grants`` allows: for one session that several identities' code shares
        (the threads engine's nodes, one process)."""
        grants = list(grants)

        def joined(field: str) -> tuple[str, ...]:
            return tuple(sorted({k for g in grants for k in getattr(g, field)}))

        return Grant(**{f.name: joined(f.name) for f in fields(Grant)})


@dataclass(frozen=True)
class Credential:
    """A user name and password of ``transport/auth/usrpwd``."""

    user: str
    password: str
    tls: ClientTls | None = None  # a --tls run's: the CA, its certificate and key (PEM)


def _rule(rid: str, flow: str, messages: list[str], key_exprs: tuple[str, ...]) -> dict[str, Any]:
    return {
        "id": rid,
        "permission": "allow",
        "flows": [flow],
        "messages": messages,
        "key_exprs": sorted(set(key_exprs)),
    }


def access_control(
    grants: Mapping[str, Grant], *, everything: str, by_certificate: bool = False
) -> dict[str, Any]:
    """Zenoh's ``access_control`` section for ``grants`` (identity -> grant): default deny, one
    subject per identity (its user name), one rule per thing it may do; routers (identity
    :data:`ROUTER`) may do everything on ``everything`` (the run's ``wncs/<run>/**``).

    ``by_certificate`` (a ``--tls`` run) makes each subject the user name *and* the common name
    of the TLS client certificate (zenoh ands a subject's fields): an identity's grants then
    need its own certificate as well as its own password (measured on loopback: a client with
    one identity's password and another's certificate gets nothing through)."""

    def subject(name: str) -> dict[str, Any]:
        fields: dict[str, Any] = {"id": name, "usernames": [name]}
        if by_certificate:
            fields["cert_common_names"] = [name]
        return fields

    rules: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    for name, grant in sorted(grants.items()):
        mine: list[dict[str, Any]] = []
        if grant.puts:
            mine.append(_rule(f"{name}/put", "ingress", ["put"], grant.puts))
        if grant.subscribes:
            mine.append(_rule(f"{name}/sub", "ingress", ["declare_subscriber"], grant.subscribes))
            mine.append(_rule(f"{name}/recv", "egress", ["put"], grant.subscribes))
        if grant.tokens:
            mine.append(_rule(f"{name}/token", "ingress", ["liveliness_token"], grant.tokens))
        if grant.watches:
            watch = ["declare_liveliness_subscriber", "liveliness_query"]
            mine.append(_rule(f"{name}/watch", "ingress", watch, grant.watches))
            mine.append(_rule(f"{name}/seen", "egress", ["liveliness_token"], grant.watches))
        if grant.matches:
            mine.append(_rule(f"{name}/match", "egress", ["declare_subscriber"], grant.matches))
        if not mine:
            continue
        rules += mine
        subjects.append(subject(name))
        policies.append({"id": name, "rules": [r["id"] for r in mine], "subjects": [name]})
    every = [
        "put",
        "delete",
        "declare_subscriber",
        "query",
        "reply",
        "declare_queryable",
        "liveliness_token",
        "declare_liveliness_subscriber",
        "liveliness_query",
    ]
    for flow in ("ingress", "egress"):
        rules.append(_rule(f"{ROUTER}/{flow}", flow, every, (everything,)))
    subjects.append(subject(ROUTER))
    policies.append(
        {"id": ROUTER, "rules": [f"{ROUTER}/ingress", f"{ROUTER}/egress"], "subjects": [ROUTER]}
    )
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def credential_path(directory: Path, name: str) -> Path:
    """The credential file of identity ``name`` in security directory ``directory``."""
    return directory / f"{name}.json"


def write_security(
    directory: Path,
    grants: Mapping[str, Grant],
    *,
    everything: str,
    tls: bool = False,
    tls_names: tuple[str, ...] = (),
    ca_name: str = "wncs",
) -> dict[str, Credential]:
    """Create ``directory`` (mode 0700) with a fresh credential per identity of ``grants`` and
    for :data:`ROUTER` (``<name>.json``), the router's password dictionary and its access
    control (all mode 0600); return the credentials by identity.

    With ``tls``, also the run's TLS material (:func:`kernel.tls.write_tls`: its CA, named
    ``ca_name``, and the routers' certificate for the loopback and ``tls_names``), and each
    credential file holds its identity's client certificate and key and the CA's certificate:
    it is all a node needs to connect."""
    directory.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(directory, 0o700)
    names = sorted({*grants, ROUTER})
    pairs = write_tls(directory, names, names=tls_names, ca_name=ca_name) if tls else {}
    ca = (directory / CA_CERT).read_text() if tls else ""
    creds = {
        name: Credential(
            name,
            secrets.token_urlsafe(24),
            ClientTls(ca, pairs[name].cert, pairs[name].key) if tls else None,
        )
        for name in names
    }
    for name, cred in creds.items():
        data: dict[str, Any] = {"user": cred.user, "password": cred.password}
        if cred.tls is not None:
            data["tls"] = {"ca": cred.tls.ca, "cert": cred.tls.cert, "key": cred.tls.key}
        write_private(
            credential_path(directory, name), json.dumps(data, indent=1 if tls else None) + "\n"
        )
    write_private(
        directory / _DICTIONARY, "".join(f"{c.user}:{c.password}\n" for c in creds.values())
    )
    acl = access_control(grants, everything=everything, by_certificate=tls)
    write_private(directory / _ACL, json.dumps(acl, indent=1) + "\n")
    return creds


def read_credential(path: Path) -> Credential:
    """The credential in ``path`` (``ConfigError`` naming the file when it cannot be read)."""
    try:
        data = json.loads(path.read_text())
        tls = data.get("tls")
        return Credential(
            str(data["user"]),
            str(data["password"]),
            None if tls is None else ClientTls(str(tls["ca"]), str(tls["cert"]), str(tls["key"])),
        )
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as err:
        raise ConfigError(f"credentials {path}: cannot read them: {err}") from err


def router_settings(
    directory: Path,
    *,
    zid: str | None = None,
    peers: tuple[str, ...] = (),
    tls_names: tuple[str, ...] = (),
) -> dict[str, Any]:
    """The JSON5 settings of a router of the run whose security lives in ``directory``: its
    access control, the password dictionary it checks clients against, and its own credential
    (which it shows other routers it connects to).

    A router that joins others (``peers``: their zenoh ids) grants them what routers may do by
    their zenoh id: zenoh 1.10's user-password authentication is one-way (the router that
    connects shows its credential; the one it connects to shows none), so to the joining router
    the other one has no user name (measured: a subject by user name alone passes nothing from
    one router to the next). ``zid`` sets this router's own zenoh id (hex).

    A ``--tls`` run's router (its directory holds TLS material) also gets its
    ``transport/link/tls`` section (:func:`kernel.tls.router_link`: mutual TLS, a certificate
    covering the loopback and ``tls_names``)."""
    try:
        acl = json.loads((directory / _ACL).read_text())
    except (OSError, ValueError) as err:
        raise ConfigError(f"security {directory}: no access control to read: {err}") from err
    own = read_credential(credential_path(directory, ROUTER))
    if peers:
        acl["subjects"].append({"id": "router-peers", "zids": list(peers)})
        rules = [f"{ROUTER}/ingress", f"{ROUTER}/egress"]
        acl["policies"].append({"id": "router-peers", "rules": rules, "subjects": ["router-peers"]})
    settings: dict[str, Any] = {} if zid is None else {"id": zid}
    if is_tls(directory):
        settings["transport/link/tls"] = router_link(directory, tls_names)
    return {
        **settings,
        "access_control": acl,
        "transport/auth/usrpwd": {
            "user": own.user,
            "password": own.password,
            "dictionary_file": str((directory / _DICTIONARY).resolve()),
        },
    }


def client_settings(cred: Credential) -> dict[str, Any]:
    """The JSON5 settings of a client session that authenticates as ``cred`` (and, a ``--tls``
    run's credential, opens its TLS link with the certificate it holds)."""
    settings: dict[str, Any] = {
        "transport/auth/usrpwd": {"user": cred.user, "password": cred.password}
    }
    if cred.tls is not None:
        settings["transport/link/tls"] = client_link(cred.tls)
    return settings
