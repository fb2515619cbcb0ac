"""Zenoh session configuration: the embedded router and the nodes' client sessions.

One function turns a :class:`BusConfig` into a ``zenoh.Config`` (zenoh-python's ``common.py``
recipe: JSON5 paths, plus raw ``KEY:VALUE`` overrides). Multicast scouting is off: every session
connects to an explicit endpoint, by default a router on the loopback interface.
"""

from __future__ import annotations

import json
import threading
from typing import Literal

import zenoh
from pydantic import BaseModel, ConfigDict

from bus_schemas import codec
from core.errors import ConfigError

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


class BusConfig(BaseModel):
    """How one session joins the bus."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    mode: Literal["router", "client", "peer"] = "client"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    multicast_scouting: bool = False
    overrides: tuple[str, ...] = ()  # raw "json5/path:VALUE" entries, applied last


def zenoh_config(cfg: BusConfig) -> zenoh.Config:
    """Build the ``zenoh.Config`` of ``cfg``."""
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(cfg.mode))
    if cfg.listen:
        conf.insert_json5("listen/endpoints", json.dumps(list(cfg.listen)))
    if cfg.connect:
        conf.insert_json5("connect/endpoints", json.dumps(list(cfg.connect)))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(cfg.multicast_scouting))
    if cfg.mode == "router":
        conf.insert_json5("adminspace/enabled", "true")
    for item in cfg.overrides:
        path, sep, value = item.partition(":")
        if not sep:
            raise ConfigError(f"bus override {item!r}: expected KEY:VALUE")
        conf.insert_json5(path, value)
    return conf


def open_router(listen: str = DEFAULT_LISTEN) -> tuple[zenoh.Session, list[str]]:
    """Open an embedded router listening on ``listen``; return it and its actual locators."""
    init_zenoh_log()
    session = zenoh.open(zenoh_config(BusConfig(mode="router", listen=(listen,))))
    locators: list[str] = []
    for reply in session.get(f"@/{session.info.zid()}/router"):
        if reply.ok is not None:
            locators = json.loads(reply.ok.payload.to_string()).get("locators", [])
    if not locators:
        session.close()
        raise ConfigError(f"router on {listen!r} reports no locator")
    return session, locators


def open_client(connect: str) -> zenoh.Session:
    """Open a client session connected to the router at ``connect``.

    Raises
    ------
    ConfigError
        If no router answers at ``connect`` (a run that has ended, a wrong endpoint).
    """
    init_zenoh_log()
    try:
        return zenoh.open(zenoh_config(BusConfig(mode="client", connect=(connect,))))
    except zenoh.ZError as err:
        raise ConfigError(f"no router answers at {connect} (has the run ended?): {err}") from err


def is_put(sample: zenoh.Sample) -> bool:
    """Whether a sample (a liveliness one included) announces a value rather than a deletion."""
    return bool(sample.kind == zenoh.SampleKind.PUT)


def put_when_heard(connect: str, key: str, payload: bytes, *, timeout: float) -> bool:
    """Publish ``payload`` once on ``key`` from a new client of the router at ``connect``, as
    soon as a subscriber matches; ``False`` (nothing sent) if none does within ``timeout`` s."""
    session = open_client(connect)
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
