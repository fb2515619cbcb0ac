"""Requests from the page: checked, then turned into the request ``wncs inject`` would send.

The page sends JSON objects over its WebSocket::

    {"id": 7, "type": "event", "event": "node_down", "fields": {"node": "r1"}}
    {"id": 8, "type": "event", "event": "link_degraded",
     "fields": {"a": "r1", "b": "r2", "prr": 0.6}}
    {"id": 9, "type": "mode", "mode": "steady_state"}
    {"id": 10, "type": "setpoint", "loop": "level", "value": 0.72}

:func:`parse` refuses anything else with a :class:`CommandError` naming what is wrong (not JSON,
not an object, an unknown type, a missing or unknown field, an unknown loop, node or mode): the
checks of :func:`runtime.inject.build_request`, against the run's own scenario, so the page and
``wncs inject`` accept and refuse the same requests.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from bus_schemas import InjectRequest
from core.errors import ConfigError
from runtime.inject import build_request

__all__ = ["CommandError", "Command", "parse"]

MAX_TEXT = 64 * 1024
"""The longest request the page may send, in characters."""


class CommandError(ValueError):
    """A request the dashboard refuses; ``id`` is the request's own, if it had one."""

    def __init__(self, reason: str, id_: Any = None) -> None:
        super().__init__(reason)
        self.reason = reason
        self.id = id_


class Command:
    """A checked request: its id (echoed in the answer), what it asks, the inject request."""

    def __init__(self, id_: Any, summary: str, request: InjectRequest) -> None:
        self.id = id_
        self.summary = summary
        self.request = request


_FIELDS = {
    "event": {"id", "type", "event", "fields", "network"},
    "mode": {"id", "type", "mode"},
    "setpoint": {"id", "type", "loop", "value"},
}


def parse(text: str, run_dir: Path) -> Command:
    """Check one message from the page against the run in ``run_dir``."""
    if len(text) > MAX_TEXT:
        raise CommandError(f"request too long ({len(text)} characters; at most {MAX_TEXT})")
    try:
        data = json.loads(text)
    except ValueError as err:
        raise CommandError(f"not JSON: {err}") from err
    if not isinstance(data, dict):
        raise CommandError(f"expected a JSON object, got {type(data).__name__}")
    id_ = data.get("id")
    if id_ is not None and (isinstance(id_, bool) or not isinstance(id_, int | str)):
        raise CommandError("id: must be a number or a string")
    kind = data.get("type")
    if kind not in _FIELDS:
        raise CommandError(
            f"type: unknown request {kind!r} (requests: {', '.join(sorted(_FIELDS))})", id_
        )
    unknown = sorted(set(data) - _FIELDS[kind])
    if unknown:
        raise CommandError(f"{kind}: unknown field(s) {', '.join(unknown)}", id_)
    try:
        if kind == "event":
            event = data.get("event")
            fields = data.get("fields") or {}
            network = data.get("network")
            if not isinstance(event, str) or not isinstance(fields, dict):
                raise ConfigError("event: needs 'event' (a name) and 'fields' (an object)")
            if network is not None and not isinstance(network, str):
                raise ConfigError("network: must be a gateway's name")
            words = [f"{k}={json.dumps(v)}" for k, v in fields.items()]
            request = build_request(event, words, run_dir=run_dir, network=network)
            detail = " ".join(f"{k}={v}" for k, v in fields.items())
            summary = f"{event} {detail}".strip()
        elif kind == "mode":
            mode = data.get("mode")
            if not isinstance(mode, str):
                raise ConfigError("mode: needs 'mode' (a name)")
            request = build_request("mode", [mode], run_dir=run_dir, network=None)
            summary = f"mode {mode}"
        else:
            loop, value = data.get("loop"), data.get("value")
            if not isinstance(loop, str):
                raise ConfigError("setpoint: needs 'loop' (a name)")
            request = build_request(
                "setpoint", [f"{loop}={json.dumps(value)}"], run_dir=run_dir, network=None
            )
            summary = f"setpoint {loop}={value}"
    except ConfigError as err:
        raise CommandError(str(err), id_) from err
    except ValueError as err:  # json.dumps of a non-finite number, say
        raise CommandError(f"{kind}: {err}", id_) from err
    return Command(id_, summary, request)
