"""``wncs router``: a standalone zenoh router for a run whose nodes live on several hosts.

The first router of a run makes it: a run id, and (unless ``--insecure``) the run's credentials
and access control under ``DIR/security`` (:mod:`runtime.security`), and ``DIR/run.json``
naming the run id and the router's endpoint. A router started with ``--connect`` joins another
router of the same run: it reads the run id and the security of ``DIR`` (copy ``DIR/security``
and ``DIR/run.json`` to the host that runs it), authenticates to the other router as identity
``router`` (and lets it in by its zenoh id, recorded in ``run.json``: see
:func:`kernel.security.router_settings`), and enforces the same access control on the nodes
that connect to it. Each node then runs as::

    WNCS_SECURITY=DIR/security wncs node SCENARIO NAME --connect ENDPOINT --run-id ID

(or ``--credentials DIR/security/NAME.json``), the historian with ``--out DIR``. The router
serves until SIGINT or SIGTERM.
"""

from __future__ import annotations

import json
import math
import secrets
import signal
import socket
import sys
import threading
from pathlib import Path
from typing import Any, TextIO

from bus_schemas import keys
from core.errors import ConfigError
from kernel.audit import LogCapture, Refused
from kernel.bus import open_router
from kernel.security import SECURITY_DIR, router_settings
from runtime.artefacts import REFUSED_LOG, RUN_FILE, write_json
from runtime.security import check_tls, listen_names, pick_endpoint, prepare, warn_insecure
from scenario import load_scenario

__all__ = ["serve_router", "router_run", "router_at"]


def router_run(
    scenario_path: str,
    out: Path,
    *,
    insecure: bool = False,
    overrides: tuple[str, ...] = (),
    run_id: str | None = None,
    tls: bool = False,
    tls_names: tuple[str, ...] = (),
) -> tuple[dict[str, Any], Path | None]:
    """The run a router serves: ``out/run.json`` if another router of it wrote one (with its
    security), else a new run written there, with id ``run_id`` (default: a random one), and
    with ``tls`` its TLS material (the routers' certificate covering ``tls_names``).
    Returns the run's information and its security directory (``None``: insecure)."""
    run_file = out / RUN_FILE
    if run_id is not None:
        try:
            keys.check_name(run_id, "--run-id")
        except ValueError as err:
            raise ConfigError(str(err)) from err
    if run_file.exists():
        try:
            info: dict[str, Any] = json.loads(run_file.read_text())
            info["run_id"]
        except (OSError, ValueError, KeyError) as err:
            raise ConfigError(f"{run_file}: not a run's file ({err})") from err
        if run_id is not None and info["run_id"] != run_id:
            raise ConfigError(
                f"--run-id {run_id}: {run_file} is run {info['run_id']}'s (a router joins the "
                "run its directory holds; give another --out for a new run)"
            )
        security = out / SECURITY_DIR
        if info.get("secure", True) and not security.is_dir():
            raise ConfigError(f"{security}: the run is secure, and its security is not here")
        if tls and not info.get("tls", False):
            raise ConfigError(
                f"--tls: run {info['run_id']} ({run_file}) is not a TLS run; its routers "
                "listen on tcp/"
            )
        return info, (security if info.get("secure", True) else None)
    scenario = load_scenario(scenario_path, overrides=list(overrides))
    out.mkdir(parents=True, exist_ok=True)
    run_id = run_id or "r" + secrets.token_hex(5)
    security = None if insecure else prepare(out, scenario, run_id, tls=tls, tls_names=tls_names)
    info = {
        "run_id": run_id,
        "engine": "routers",
        "scenario": str(Path(scenario_path).resolve()),
        "seed": scenario.seed,
        "secure": security is not None,
        "tls": tls,
        "endpoint": None,
        "routers": [],
    }
    return info, security


def _split(endpoint: str) -> tuple[str, str, str]:
    """``tls/host:7447`` -> (``tls``, ``host``, ``7447``); brackets off an IPv6 address."""
    proto, _, rest = endpoint.partition("/")
    host, _, port = rest.rpartition(":")
    return proto, host.strip("[]"), port.partition("#")[0]


def router_at(endpoint: str, routers: list[dict[str, Any]]) -> str | None:
    """The zenoh id of the run's router that ``endpoint`` (a ``--connect``) reaches, from
    ``run.json``'s ``routers``: one whose endpoint or locators it names, else one whose
    locators have an address ``endpoint``'s host resolves to, on the same protocol and port (a
    router listening on ``0.0.0.0`` records the host's addresses; another host names it by
    its DNS name); ``None`` if none does."""
    for r in routers:
        if endpoint == r["endpoint"] or endpoint in r.get("locators", []):
            return str(r["zid"])
    proto, host, port = _split(endpoint)
    try:
        addresses = {str(ai[4][0]) for ai in socket.getaddrinfo(host, port or None)}
    except (OSError, UnicodeError):
        return None
    for r in routers:
        for loc in (r["endpoint"], *r.get("locators", [])):
            p2, h2, port2 = _split(loc)
            if p2 == proto and port2 == port and h2 in addresses:
                return str(r["zid"])
    return None


def serve_router(
    scenario_path: str,
    out: Path,
    listen: str,
    *,
    connect: tuple[str, ...] = (),
    insecure: bool = False,
    zenoh_config: str | None = None,
    overrides: tuple[str, ...] = (),
    stream: TextIO | None = None,
    stop: threading.Event | None = None,
    run_id: str | None = None,
    tls: bool = False,
    tls_names: tuple[str, ...] = (),
) -> int:
    """Open the router, record it in ``out/run.json``, and serve until ``stop`` is set or a
    SIGINT/SIGTERM arrives; return the exit code (0).

    A secure router audits (:mod:`kernel.audit`): it appends each attempt it refuses to
    ``out/refused.log``, says the first of each kind (and the 10th, 100th, ...) on ``stream``,
    and the total when it stops. It can only if zenoh's logging has not started yet in this
    process (``wncs router`` is a process of its own); otherwise it says it does not count.

    A TLS run's router (``tls``, or a run whose ``run.json`` says ``"tls": true``) listens on a
    ``tls/`` endpoint with mutual TLS (:mod:`kernel.tls`); its certificate covers the loopback,
    the host ``listen`` names and ``tls_names`` (``--tls-name``: the names nodes on other hosts
    reach it by)."""
    check_tls(listen, tls=tls, insecure=insecure)
    names = (*listen_names(listen), *tls_names)
    info, security = router_run(
        scenario_path,
        out,
        insecure=insecure,
        overrides=overrides,
        run_id=run_id,
        tls=tls,
        tls_names=names,
    )
    tls = bool(info.get("tls", False))
    check_tls(listen, tls=tls, insecure=security is None)
    said: list[TextIO] = []  # where refusals are said, once known

    def say_refused(attempt: Refused, count: int) -> None:
        if said and (count == 1 or math.log10(count).is_integer()):
            said[0].write(f"wncs router: refused {attempt} ({count} so far)\n")
            said[0].flush()

    capture = None
    if security is not None:
        capture = LogCapture(out / REFUSED_LOG, on_refused=say_refused)
        if not capture.start():
            capture = None
    stream = stream or sys.stdout  # (after the capture: sys.stdout is then a copy of fd 1)
    said.append(stream)
    warn_insecure(listen, secure=security is not None)
    zid = "%x" % (secrets.randbits(124) | 1 << 124)  # 32 hex digits, no leading 0 (zenoh)
    routers = info.get("routers", [])
    found = {c: router_at(c, routers) for c in connect}
    unknown = [c for c, z in found.items() if z is None]
    if security is not None and unknown:
        known = sorted(r["endpoint"] for r in routers)
        raise ConfigError(
            f"--connect {', '.join(unknown)}: not a router of run {info['run_id']} "
            f"(its routers: {known or 'none yet'})"
        )
    peers = tuple(z for z in found.values() if z is not None)
    router, locators = open_router(
        listen,
        connect=connect,
        settings=(
            None
            if security is None
            else router_settings(security, zid=zid, peers=peers, tls_names=names)
        ),
        config_file=zenoh_config,
    )
    endpoint = pick_endpoint(locators, listen, names)
    info["endpoint"] = info.get("endpoint") or endpoint
    info.setdefault("routers", []).append(
        {"endpoint": endpoint, "zid": zid, "locators": list(locators)}
    )
    write_json(out / RUN_FILE, info)
    audit = (
        f"; refused attempts go to {out / REFUSED_LOG}"
        if capture
        else (
            "; refused attempts not counted (zenoh's log was started already)" if security else ""
        )
    )
    stream.write(
        f"wncs router: run {info['run_id']} "
        f"({('secure, TLS' if tls else 'secure') if security else 'INSECURE'}) on "
        f"{endpoint}{' joined to ' + ', '.join(connect) if connect else ''}{audit}\n"
    )
    stream.flush()
    stop = stop or threading.Event()

    def _stop(signum: int, frame: object) -> None:
        stop.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _stop)
        signal.signal(signal.SIGINT, _stop)
    try:
        while not stop.wait(0.2):
            pass
    finally:
        router.close()
        if capture is not None:
            refused = capture.close()["refused"]
            stream.write(f"wncs router: stopped; it refused {refused} attempts\n")
            stream.flush()
    return 0
