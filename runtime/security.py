"""A run's security from its scenario (issue 19): who may put, subscribe and show a token where.

:func:`grants` derives each identity's :class:`~kernel.security.Grant` from the scenario: a node
may publish only the keys it owns (:func:`runtime.ownership.publishers`), its own
``clock/done/<node>`` and its progress beats (``clock/working/<node>``), subscribe only to what
its role reads (:func:`runtime.ownership.readers`) and its ticks (``clock/tick/<node>``) and the
stop (the historian: the clock's log, ``clock/log``, instead), declare a liveliness token only
under its own name and watch only the clock's. The clock publishes the ticks, its log, the stop
and the requests it stamps, and listens to ``clock/done/*``, ``clock/working/*`` and
``ops/inject``. ``wncs inject`` may put exactly ``ops/inject``
(and learn that the clock listens there); ``dashboard`` may put exactly ``ops/inject`` too, and
read the run (it shows it); ``launcher`` (``wncs run``'s own session, for its progress line)
reads the clock's log and the stop and watches who is alive; ``threads``, the threads engine's
one session for all its nodes and its clock, may do what any of them may. The historian reads
everything and publishes nothing. Every publisher may learn of every subscription in the run
(``matches``): a zenoh 1.10 client's declared publisher sends nothing to a router that has not
told it of a matching subscriber.
:func:`prepare` writes the credentials and the access control under ``<run dir>/security``
(:mod:`kernel.security`).
"""

from __future__ import annotations

import ipaddress
import os
import sys
from pathlib import Path
from typing import Any, TextIO

from bus_schemas import keys
from core.errors import ConfigError
from kernel.bus import CREDENTIALS_ENV
from kernel.security import (
    SECURITY_DIR,
    Grant,
    client_settings,
    credential_path,
    read_credential,
    write_security,
)
from kernel.tls import name_of_endpoint, router_names
from runtime.ownership import CLOCK, OBSERVERS, publishers, readers
from scenario import Scenario

__all__ = [
    "SECURITY_ENV",
    "INJECT",
    "DASHBOARD",
    "LAUNCHER",
    "THREADS",
    "use_node_credentials",
    "grants",
    "prepare",
    "credentials_of",
    "warn_insecure",
    "is_loopback",
    "TLS_LISTEN",
    "check_tls",
    "listen_names",
    "pick_endpoint",
]

SECURITY_ENV = "WNCS_SECURITY"
"""The environment variable naming a run's security directory: ``wncs node NAME`` then
authenticates with ``NAME.json`` from it (the launcher sets it for its node processes)."""

INJECT = "inject"
DASHBOARD = "dashboard"
LAUNCHER = "launcher"
THREADS = "threads"
"""The threads engine's identity: its nodes and clock share one session (one process, one
interpreter: no node there is kept from another's memory, so separate identities would guard
nothing), allowed what any of them is (:meth:`kernel.security.Grant.union`)."""


def grants(scenario: Scenario, run_id: str) -> dict[str, Grant]:
    """Identity -> what it may do on the bus in run ``run_id`` of ``scenario``."""

    def full(*rels: str) -> tuple[str, ...]:
        return tuple(sorted({keys.full(run_id, r) for r in rels}))

    owned, reads = publishers(scenario), readers(scenario)
    out: dict[str, Grant] = {}
    for name in scenario.participants():
        out[name] = Grant(
            puts=full(*owned[name], keys.done(name), keys.working(name)),
            # the ticks addressed to it (clock/tick/<node>) and the stop; an observer (the
            # historian) the clock's log of every tick instead (clock/log, the stop last)
            subscribes=full(
                *reads[name],
                *((keys.tick_log(),) if name in OBSERVERS else (keys.tick_to(name), keys.stop())),
            ),
            tokens=full(keys.alive(name)),
            watches=full(keys.alive(CLOCK)),
            matches=full("**"),
        )
    out[CLOCK] = Grant(
        puts=full(*owned[CLOCK], keys.tick_log(), f"{keys.tick()}/*", keys.stop()),
        subscribes=full(keys.done_all(), keys.working_all(), keys.inject()),
        tokens=full(keys.alive(CLOCK)),
        watches=full(keys.alive_all()),
        matches=full("**"),
    )
    out[THREADS] = Grant.union(out.values())
    out[INJECT] = Grant(puts=full(keys.inject()), matches=full(keys.inject()))
    out[LAUNCHER] = Grant(  # wncs run's progress line: the clock's log, the stop, who is alive
        subscribes=full(keys.tick_log(), keys.stop()), watches=full(keys.alive_all())
    )
    out[DASHBOARD] = Grant(
        puts=full(keys.inject()),
        matches=full(keys.inject()),
        subscribes=full("**"),
        watches=full(keys.alive_all()),
    )
    return out


def prepare(
    out: Path,
    scenario: Scenario,
    run_id: str,
    *,
    tls: bool = False,
    tls_names: tuple[str, ...] = (),
) -> Path:
    """Write run ``run_id``'s credentials and access control under ``out/security``; return
    that directory. With ``tls``, its TLS material too (:mod:`kernel.tls`: a CA of the run, the
    routers' certificate for the loopback and ``tls_names``, a client certificate per
    identity)."""
    directory = out / SECURITY_DIR
    write_security(
        directory,
        grants(scenario, run_id),
        everything=keys.full(run_id, "**"),
        tls=tls,
        tls_names=tls_names,
        ca_name=f"wncs run {run_id}",
    )
    return directory


TLS_LISTEN = "tls/127.0.0.1:0"
"""``--tls``'s default endpoint: loopback, port chosen by the OS."""


def check_tls(listen: str, *, tls: bool, insecure: bool) -> None:
    """Refuse (``ConfigError``) ``--tls`` with ``--insecure`` (TLS here rides on the run's
    credentials) or with a listen endpoint that is not ``tls/``."""
    if not tls:
        return
    if insecure:
        raise ConfigError(
            "--tls with --insecure: a TLS run is a secure run (its certificates are made with its "
            "credentials); drop --insecure"
        )
    if not listen.startswith("tls/"):
        raise ConfigError(f"--tls: --listen {listen} is not a tls/ endpoint (e.g. {TLS_LISTEN})")


def listen_names(listen: str) -> tuple[str, ...]:
    """The host a listen endpoint names, for the routers' certificate: none for a wildcard
    (``0.0.0.0``, ``[::]``: give the host's names with ``--tls-name``)."""
    host = name_of_endpoint(listen)
    if not host or host in ("0.0.0.0", "::"):
        return ()
    return (host,)


def pick_endpoint(locators: list[str], listen: str, names: tuple[str, ...] = ()) -> str:
    """The endpoint a run's nodes connect to: the first locator of the listen endpoint's
    protocol (``tcp/``, ``tls/``).

    A TLS client checks the router's name, so for ``tls/`` the endpoint must name a host the
    routers' certificate covers (:func:`kernel.tls.router_names` of ``names``): the first such
    locator; else (a router on ``0.0.0.0`` reports the host's addresses, which the certificate
    need not list) the first of ``names`` with the router's port, or the loopback address."""
    proto = listen.partition("/")[0] + "/"
    first = next((loc for loc in locators if loc.startswith(proto)), locators[0])
    if proto != "tls/":
        return first
    covered = router_names(names)
    for loc in locators:
        if loc.startswith(proto) and name_of_endpoint(loc) in covered:
            return loc
    port = first.rpartition(":")[2]
    host = names[0].strip("[]") if names else "127.0.0.1"
    return f"tls/{'[' + host + ']' if ':' in host else host}:{port}"


def use_node_credentials(name: str, credentials: str | None = None) -> None:
    """Point this process's sessions (:data:`kernel.bus.CREDENTIALS_ENV`) at node ``name``'s
    credentials: the file ``credentials`` if given, else ``NAME.json`` in the security directory
    ``$WNCS_SECURITY`` names; nothing when neither is there (an insecure run). What ``wncs node``
    and each process of the fork server do before they open their session."""
    security = os.environ.get(SECURITY_ENV)
    if credentials:
        os.environ[CREDENTIALS_ENV] = credentials
    elif security:
        os.environ[CREDENTIALS_ENV] = str(credential_path(Path(security), name))


def credentials_of(directory: Path, name: str) -> dict[str, Any]:
    """The session settings of identity ``name`` from security directory ``directory``."""
    return client_settings(read_credential(credential_path(directory, name)))


def login_of(run_dir: Path, name: str) -> dict[str, Any] | None:
    """The session settings of identity ``name`` for the run in ``run_dir``: its credentials if
    the run is secure (it has ``security/``), ``None`` for an ``--insecure`` run."""
    directory = run_dir / SECURITY_DIR
    return credentials_of(directory, name) if directory.is_dir() else None


def is_loopback(endpoint: str) -> bool:
    """Whether a zenoh endpoint (``tcp/127.0.0.1:7447``) binds the loopback interface only."""
    return is_loopback_host(endpoint.partition("/")[2].rpartition(":")[0].strip("[]"))


def is_loopback_host(host: str) -> bool:
    """Whether ``host`` (an address, or ``localhost``) is the loopback interface."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name or an interface: not provably loopback


def warn_insecure(listen: str, *, secure: bool, stream: TextIO | None = None) -> None:
    """Say on ``stream`` (standard error) what an insecure run or a wide listener exposes."""
    stream = stream or sys.stderr
    if not secure:
        stream.write(
            "wncs: WARNING: --insecure: no authentication and no access control; anyone who "
            "reaches the router can read the run and publish on any of its keys\n"
        )
        if not is_loopback(listen):
            stream.write(
                f"wncs: WARNING: listening on {listen}, beyond the loopback interface, "
                "with security off\n"
            )
