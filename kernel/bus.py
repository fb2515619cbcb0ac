"""Zenoh session configuration: the embedded router and the nodes' client sessions.

One function turns a :class:`BusConfig` into a ``zenoh.Config`` (zenoh-python's ``common.py``
recipe: JSON5 paths, plus raw ``KEY:VALUE`` overrides). Multicast scouting is off: every session
connects to an explicit endpoint, by default a router on the loopback interface.

A base configuration file (``--zenoh-config FILE``, else the ``ZENOH_CONFIG`` environment
variable) is read first; what the run needs (mode, endpoints, its security settings from
:mod:`kernel.security`) is set on top of it.
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path
from typing import Any, Literal

import zenoh
from pydantic import BaseModel, ConfigDict

from bus_schemas import codec
from core.errors import ConfigError
from kernel.security import client_settings, read_credential

__all__ = [
    "BusConfig",
    "DEFAULT_LISTEN",
    "Session",
    "zenoh_config",
    "open_router",
    "open_client",
    "is_put",
    "put_when_heard",
    "init_zenoh_log",
    "zenoh_log_started",
    "base_config",
    "SHARED_MEMORY",
    "CONFIG_ENV",
    "CREDENTIALS_ENV",
    "RUNTIME_ENV",
]

Session = zenoh.Session
"""A zenoh session: layers above the kernel name the type through here, never import zenoh."""

DEFAULT_LISTEN = "tcp/127.0.0.1:0"
"""Loopback, port chosen by the OS (read back from the router's admin space)."""

_LOG_INIT = False


def init_zenoh_log(level: str = "error") -> bool:
    """Start zenoh's own logging, once per process: ``RUST_LOG`` if set, else ``level``.

    Zenoh logs from Rust (``zenoh.init_log_from_env_or``) straight to the process's standard
    output, past ``sys.stdout``, so only the first call in a process counts; ``open_router`` and
    ``open_client`` make it with the default, ``"error"``. ``wncs run`` calls it first with
    ``"off"``: its process holds the router and, in the threads engine, every node's session,
    and its standard output is the terminal with the progress line, which zenoh's own lines (an
    ``ERROR ... Unknown token`` when a liveliness subscriber goes as the clock leaves) would break.
    The processes engine's node processes keep ``"error"``: their output is ``logs/<node>.log``,
    so zenoh's errors land in the run's log files. ``RUST_LOG=warn`` (or ``debug``, or a filter
    such as ``zenoh::net=debug``) shows them in any process.

    Returns
    -------
    bool
        Whether this call started the logging (False: it had been started already).
    """
    global _LOG_INIT
    if _LOG_INIT:
        return False
    zenoh.init_log_from_env_or(level)
    _LOG_INIT = True
    return True


def zenoh_log_started() -> bool:
    """Whether zenoh's logging has started in this process (its filter is then fixed)."""
    return _LOG_INIT


class BusConfig(BaseModel):
    """How one session joins the bus."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    mode: Literal["router", "client", "peer"] = "client"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    multicast_scouting: bool = False
    overrides: tuple[str, ...] = ()  # raw "json5/path:VALUE" entries, applied last
    settings: dict[str, Any] = {}  # json5 path -> value (security: kernel.security)
    config_file: str | None = None  # a zenoh configuration file to start from


CREDENTIALS_ENV = "WNCS_CREDENTIALS"
"""The environment variable naming the credential file (:mod:`kernel.security`) a client
session authenticates with when it is given no settings (``wncs node`` sets it from
``--credentials FILE``, or from ``WNCS_SECURITY`` and the node's name)."""

CONFIG_ENV = "ZENOH_CONFIG"
"""The environment variable naming a zenoh configuration file, when ``--zenoh-config`` is not
given."""

RUNTIME_ENV = "ZENOH_RUNTIME"
"""zenoh's own environment variable for its threads (RON, e.g. ``(rx: (handover: app))``), read
when a process opens its first session; ``docs/benchmarks.md`` measures one setting. zenoh
panics on a value it cannot parse, an empty one too: :func:`_open` counts an empty value as
unset and turns the panic into a :class:`ConfigError` naming the variable."""


def _open(config: zenoh.Config) -> zenoh.Session:
    """``zenoh.open``, with a bad :data:`RUNTIME_ENV` reported as a :class:`ConfigError` (zenoh
    raises a ``PanicException``, which is no ``Exception``, and its threads stay unusable: the
    process can only stop)."""
    if RUNTIME_ENV in os.environ and not os.environ[RUNTIME_ENV].strip():
        del os.environ[RUNTIME_ENV]  # empty: zenoh's defaults, as when unset
    try:
        return zenoh.open(config)
    except BaseException as err:
        setting = os.environ.get(RUNTIME_ENV)
        if type(err).__name__ != "PanicException" or setting is None:
            raise
        raise ConfigError(
            f"{RUNTIME_ENV}={setting!r} is not a zenoh runtime setting (RON, e.g. "
            f"'(rx: (handover: app))'; unset it for zenoh's defaults). zenoh says: {err}"
        ) from None


def _config_path(path: str | None) -> str | None:
    return path or os.environ.get(CONFIG_ENV) or None


def base_config(path: str | None = None) -> zenoh.Config:
    """A zenoh configuration read from ``path``, else from ``$ZENOH_CONFIG``, else the default."""
    path = _config_path(path)
    if path is None:
        return zenoh.Config()
    if not Path(path).is_file():
        raise ConfigError(f"zenoh configuration {path}: no such file")
    try:
        return zenoh.Config.from_file(path)
    except zenoh.ZError as err:
        raise ConfigError(f"zenoh configuration {path}: {err}") from err


SHARED_MEMORY = "transport/shared_memory"
"""zenoh's shared-memory transport, which every session of a run turns off unless its zenoh
configuration file names it. zenoh's default moves a message of 3 KB or more (the clock's logs
of 64 ticks, 4-10 KB) through a shared-memory segment when both ends are on one host, and a
session's second such message stalls inside its ``put`` while zenoh creates the 1.3 MB segment,
locks it in memory and starts two watchdog threads: 5.5-8.3 ms in the clock's third log, inside
the ``Done`` callback that ticks the next round (``docs/benchmarks.md``). Without it the same
logs take 0.1-0.9 ms at most over loopback TCP, so the segment saves a run nothing."""


def _names_shared_memory(path: str | None) -> bool:
    """Whether the zenoh configuration file at ``path`` mentions the shared-memory transport
    (then its settings are the file's, zenoh's defaults included)."""
    return path is not None and "shared_memory" in Path(path).read_text(errors="replace")


def zenoh_config(cfg: BusConfig) -> zenoh.Config:
    """Build the ``zenoh.Config`` of ``cfg``."""
    path = _config_path(cfg.config_file)
    conf = base_config(path)
    if not _names_shared_memory(path):
        conf.insert_json5(f"{SHARED_MEMORY}/enabled", "false")
    conf.insert_json5("mode", json.dumps(cfg.mode))
    if cfg.listen:
        conf.insert_json5("listen/endpoints", json.dumps(list(cfg.listen)))
    if cfg.connect:
        conf.insert_json5("connect/endpoints", json.dumps(list(cfg.connect)))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(cfg.multicast_scouting))
    if cfg.mode == "router":
        conf.insert_json5("adminspace/enabled", "true")
    for path, value in cfg.settings.items():
        conf.insert_json5(path, json.dumps(value))
    for item in cfg.overrides:
        path, sep, value = item.partition(":")
        if not sep:
            raise ConfigError(f"bus override {item!r}: expected KEY:VALUE")
        conf.insert_json5(path, value)
    return conf


_NO_SCOUTING_WAIT = "scouting/delay:0"
"""zenoh's open waits ``scouting/delay`` (500 ms) for other nodes to answer its scouting; with
multicast scouting off and no router to join, none can, so a router that joins nothing does not
wait (it opens in milliseconds: half a second off every bus run's start-up)."""


def open_router(
    listen: str = DEFAULT_LISTEN,
    *,
    connect: tuple[str, ...] = (),
    settings: dict[str, Any] | None = None,
    config_file: str | None = None,
) -> tuple[zenoh.Session, list[str]]:
    """Open a router listening on ``listen`` (and joining the routers at ``connect``), with
    ``settings`` (its security: :func:`kernel.security.router_settings`); return it and its
    actual locators."""
    init_zenoh_log()
    cfg = BusConfig(
        mode="router",
        listen=(listen,),
        connect=connect,
        settings=settings or {},
        config_file=config_file,
        overrides=() if connect else (_NO_SCOUTING_WAIT,),
    )
    try:
        session = _open(zenoh_config(cfg))
    except zenoh.ZError as err:
        raise ConfigError(f"cannot open a router on {listen!r}: {err}") from err
    locators: list[str] = []
    for reply in session.get(f"@/{session.info.zid()}/router"):
        if reply.ok is not None:
            locators = json.loads(reply.ok.payload.to_string()).get("locators", [])
    if not locators:
        session.close()
        raise ConfigError(f"router on {listen!r} reports no locator")
    return session, locators


def open_client(
    connect: str, *, settings: dict[str, Any] | None = None, config_file: str | None = None
) -> zenoh.Session:
    """Open a client session connected to the router at ``connect``, with ``settings`` (its
    credentials: :func:`kernel.security.client_settings`).

    Raises
    ------
    ConfigError
        If no router answers at ``connect`` (a run that has ended, a wrong endpoint), or it
        refuses the credentials (none, or another run's), or the TLS link fails (a ``--tls``
        run: no certificate of the run, a host name the router's certificate does not cover).
    """
    init_zenoh_log()
    if settings is None and os.environ.get(CREDENTIALS_ENV):
        settings = client_settings(read_credential(Path(os.environ[CREDENTIALS_ENV])))
    cfg = BusConfig(
        mode="client", connect=(connect,), settings=settings or {}, config_file=config_file
    )
    try:
        return _open(zenoh_config(cfg))
    except zenoh.ZError as err:
        tls = (
            "; over tls/ the endpoint's host must be one the router's certificate names "
            "(--tls-name) and the credentials a TLS run's"
            if connect.startswith("tls/")
            else ""
        )
        raise ConfigError(
            f"no router answers at {connect}, or it refused this session's credentials "
            f"(has the run ended? is it a secure run? a TLS run takes tls/ only{tls}): {err}"
        ) from err


def is_put(sample: zenoh.Sample) -> bool:
    """Whether a sample (a liveliness one included) announces a value rather than a deletion."""
    return bool(sample.kind == zenoh.SampleKind.PUT)


def put_when_heard(
    connect: str,
    key: str,
    payload: bytes,
    *,
    timeout: float,
    settings: dict[str, Any] | None = None,
) -> bool:
    """Publish ``payload`` once on ``key`` from a new client of the router at ``connect`` (with
    ``settings``, its credentials), as soon as a subscriber matches; ``False`` (nothing sent)
    if none does within ``timeout`` s."""
    session = open_client(connect, settings=settings)
    try:
        publisher = session.declare_publisher(
            key,
            encoding=zenoh.Encoding(codec.ENCODING),
            congestion_control=zenoh.CongestionControl.BLOCK,
        )
        matched = threading.Event()
        listener = publisher.declare_matching_listener(
            lambda status: matched.set() if status.matching else None
        )
        try:
            status = publisher.matching_status  # the stubs say bool; it is a MatchingStatus
            if not status.matching and not matched.wait(timeout):  # type: ignore[attr-defined]
                return False
            publisher.put(payload)
            return True
        finally:
            listener.undeclare()
            publisher.undeclare()
    finally:
        session.close()
