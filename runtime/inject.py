"""``wncs inject``: put a network reconfiguration, an operating mode, a set point or a drift of a
plant's parameter into a running run.

The request goes to the clock on ``ops/inject``; the clock stamps it into its next round as
``events/<network>`` (``wncs inject DIR node_down node=r1``), ``ops/mode`` (``wncs inject DIR
mode steady_state``), ``ops/setpoint/<loop>`` (``wncs inject DIR setpoint level=0.72``) or
``plant/<p>/drift`` (``wncs inject DIR drift reactor U=0.13 over=40``: the true plant's ``U``
to 0.13 over 40 time units, in 20 steps unless ``steps=N``),
counted like any other message, so the history shows exactly when it took effect and a replay of
the history reproduces the run (DESIGN section 3, external inputs). A request is checked here
first: an unknown event type, a malformed field, a node the run's network does not have, an
unknown mode or loop is refused with a message naming it (exit code 2), and nothing is sent.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from agents.wncsca.config import MODES
from bus_schemas import Drift, InjectRequest, ModeRequest, NetworkEvent, Setpoint, codec, keys
from bus_schemas.errors import SchemaError
from core.errors import ConfigError
from core.time import to_ticks
from gateway.topology import Topology, parse_event
from kernel.bus import put_when_heard
from kernel.clock import INJECT_SOURCE, Interpreter
from runtime.artefacts import SCENARIO_FILE
from scenario import Scenario, load_scenario

__all__ = ["parse_fields", "build_request", "send", "interpreter"]


def parse_fields(words: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` words into a mapping; a VALUE that parses as JSON is taken as JSON."""
    fields: dict[str, Any] = {}
    for word in words:
        key, sep, value = word.partition("=")
        if not sep or not key:
            raise ConfigError(f"event field {word!r}: expected KEY=VALUE")
        try:
            fields[key] = json.loads(value)
        except ValueError:
            fields[key] = value
    return fields


def _known_nodes(run_dir: Path, network: str | None) -> tuple[str, set[str]]:

    scenario = load_scenario(run_dir / SCENARIO_FILE)
    gateways = scenario.gateways()
    if network is None:
        if len(gateways) != 1:
            raise ConfigError(f"--network: the run has gateways {gateways}; name one")
        network = gateways[0]
    if network not in gateways:
        raise ConfigError(f"--network: {network!r} is not a gateway of the run {gateways}")
    cfg = scenario.nodes[network]
    topology = Topology(cfg.topology)
    nodes = set(topology.nodes)
    for scheduled in cfg.events:  # relays the scenario adds on its own
        node = getattr(scheduled.event, "node", None)
        if node:
            nodes.add(node)
    return network, nodes


def _ops_request(kind: str, words: list[str], run_dir: Path | None) -> InjectRequest:
    """``mode MODE`` or ``setpoint LOOP=VALUE``, checked against the run's scenario if known."""

    scenario = load_scenario(run_dir / SCENARIO_FILE) if run_dir is not None else None
    if kind == "mode":
        if len(words) != 1:
            raise ConfigError("usage: wncs inject DIR mode MODE")
        mode = words[0].removeprefix("mode=")
        if mode not in MODES:
            raise ConfigError(f"mode: unknown mode {mode!r} (modes: {', '.join(MODES)})")
        if scenario is not None and scenario.agent_node() is None:
            raise ConfigError("mode: the run has no coordination agent to follow modes")
        return InjectRequest(mode=mode)
    fields = parse_fields(words)
    if len(fields) != 1:
        raise ConfigError("usage: wncs inject DIR setpoint LOOP=VALUE")
    [(loop, value)] = fields.items()
    if scenario is not None and loop not in scenario.loops:
        raise ConfigError(f"setpoint: unknown loop {loop!r} (loops: {sorted(scenario.loops)})")
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(f"setpoint: {loop}: not a finite number: {value!r}")
    if abs(value) > Setpoint.LIMIT:
        raise ConfigError(
            f"setpoint: {loop}: {value!r} is beyond a physical value (|value| <= "
            f"{Setpoint.LIMIT:g})"
        )
    return InjectRequest(setpoint={"loop": loop, "value": float(value)})


def _drift_request(words: list[str], run_dir: Path | None) -> InjectRequest:
    """``drift PLANT PARAM=VALUE [over=T] [steps=N]``, checked against the run's scenario (the
    plant, a numeric parameter, a value its model accepts) if known."""
    if not words or "=" in words[0]:
        raise ConfigError("usage: wncs inject DIR drift PLANT PARAM=VALUE [over=T] [steps=N]")
    plant, fields = words[0], parse_fields(words[1:])
    over, steps = fields.pop("over", 0.0), fields.pop("steps", 20)
    if len(fields) != 1:
        raise ConfigError("usage: wncs inject DIR drift PLANT PARAM=VALUE [over=T] [steps=N]")
    [(param, value)] = fields.items()
    for name, v in (("value", value), ("over", over)):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise ConfigError(f"drift: {name}: not a finite number: {v!r}")
    if over < 0 or isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ConfigError(
            f"drift: over must be >= 0 and steps a whole number >= 1 ({over}, {steps})"
        )
    if run_dir is not None:
        scenario = load_scenario(run_dir / SCENARIO_FILE)
        data = scenario.model_dump()
        data["drifts"] = [{"t": 0.0, "plant": plant, "param": param, "value": value}]
        try:  # the scenario's own checks of a drift (plant, parameter, value)
            Scenario.model_validate(data)
        except ValidationError as err:
            msg = err.errors()[0]["msg"].removeprefix("Value error, ")
            raise ConfigError(f"drift: {msg}") from err
    drift = {"param": param, "value": float(value), "over": to_ticks(float(over)), "steps": steps}
    try:
        Drift.model_validate(drift)
    except ValidationError as err:
        raise ConfigError(f"drift: {err.errors()[0]['msg']}") from err
    return InjectRequest(drift={"plant": plant, **drift})


def build_request(
    event_type: str, words: list[str], *, run_dir: Path | None, network: str | None
) -> InjectRequest:
    """Validate a request given on the command line; raise ``ConfigError`` naming the problem."""
    if event_type in ("mode", "setpoint"):
        return _ops_request(event_type, words, run_dir)
    if event_type == "drift":
        return _drift_request(words, run_dir)

    data = {"type": event_type, **parse_fields(words)}
    try:
        event = parse_event(data)
    except ValidationError as err:
        e = err.errors()[0]
        loc = ".".join(str(p) for p in e["loc"])
        raise ConfigError(f"event {event_type!r}: {loc}: {e['msg']}") from err
    if run_dir is not None:
        network, nodes = _known_nodes(run_dir, network)
        named = [
            ("node", getattr(event, "node", None)),
            ("a", getattr(event, "a", None)),
            ("b", getattr(event, "b", None)),
        ]
        new = event.node if event.type == "relay_added" else None
        for link in getattr(event, "links", []) or []:
            named += [("links.a", link.a), ("links.b", link.b)]
        named += [("receivers", r) for r in getattr(event, "receivers", None) or ()]
        if event.type == "interference":
            cfg = load_scenario(run_dir / SCENARIO_FILE).nodes[network]
            if cfg.mac != "tsch":
                raise ConfigError(
                    f"event 'interference': network {network!r} has no channels (per-hop "
                    "model); interference needs a TSCH network (mac: tsch)"
                )
        for field, name in named:
            if name is not None and name != new and name not in nodes:
                raise ConfigError(
                    f"event {event_type!r}: {field}: unknown node {name!r} "
                    f"(network {network!r} has {sorted(nodes)})"
                )
    return InjectRequest(network=network, event=event.model_dump(mode="json"))


def send(
    endpoint: str,
    run_id: str,
    request: InjectRequest,
    *,
    timeout: float = 10.0,
    settings: dict[str, Any] | None = None,
) -> None:
    """Publish the request to the run's clock once the clock is listening (with ``settings``,
    the ``inject`` identity's credentials of a secure run: :mod:`runtime.security`)."""
    payload = codec.encode(run=run_id, src=INJECT_SOURCE, seq=0, round=0, t=0, body=request)
    key = keys.full(run_id, keys.inject())
    if not put_when_heard(endpoint, key, payload, timeout=timeout, settings=settings):
        raise ConfigError(f"no clock of run {run_id!r} is listening at {endpoint}")


def interpreter(scenario: Scenario) -> Interpreter:
    """How the clock of a run of ``scenario`` turns an external request into the message it
    stamps: a network event for its gateway (``events/<network>``), a mode or a set-point
    request as operations would send it (``ops/mode``, ``ops/setpoint/<loop>``), a drift for
    its plant (``plant/<p>/drift``)."""
    gateways = scenario.gateways()
    has_agent = scenario.agent_node() is not None

    def interpret(request: InjectRequest) -> tuple[str, BaseModel]:
        if request.mode is not None:
            if not has_agent or request.mode not in MODES:
                raise SchemaError(f"mode {request.mode!r}: needs an agent and one of {MODES}")
            return keys.ops_mode(), ModeRequest(mode=request.mode)
        if request.setpoint is not None:
            loop = request.setpoint.get("loop")
            if loop not in scenario.loops:
                raise SchemaError(f"setpoint: unknown loop {loop!r}")
            return keys.setpoint(loop), Setpoint(value=request.setpoint.get("value"))
        if request.drift is not None:
            fields = dict(request.drift)
            plant = fields.pop("plant", None)
            if plant not in scenario.plants():
                raise SchemaError(f"drift: unknown plant {plant!r}")
            return keys.drift(plant), Drift.model_validate(fields)  # the plant checks the rest
        network = request.network or (gateways[0] if len(gateways) == 1 else None)
        if network not in gateways:
            raise SchemaError(f"network {request.network!r} is not one gateway of {gateways}")
        parse_event(request.event)
        return keys.network_events(network), NetworkEvent(event=request.event)

    return interpret
