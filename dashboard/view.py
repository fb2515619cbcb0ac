"""What the dashboard shows, made from a run's history rows: time-stamped records by stream.

Every record carries its simulated time (in time units), so the page can draw a live run up to
its latest round and a replay up to the slider's time with the same code; a record is never
changed once sent, only new ones appended. Streams (``<name>/<loop>`` etc.):

``y/<loop>``         ``[t, value]`` the plant's true output (its state on the monitoring grid)
``meas/<loop>``      ``[t, value]`` the samples delivered to the controller, at delivery time
``u/<loop>``         ``[t, value]`` the controller's moves, when computed
``sp/<loop>``        ``[t, value]`` the set point the controller follows (a step at ``t``)
``period/<loop>``    ``[t, tau_s, closed]`` the sampling period in force and whether the loop is
                     closed (the agent's ``wncsca/rates``; without an agent, the sensor's period)
``delay/<path>``     ``[t, delay]`` each packet's path delay, ``<loop>.sensor``/``<loop>.actuator``
``pathstats/<path>`` ``{t, last, mean, p95, n, lost, reasons}`` after each batch that changed it
``timeline``         ``{t, kind, ...}`` requests stamped by the clock, proposals, the agent's
                     decisions with their reasons, configurations applied
``topology/<net>``   ``{t, nodes: {name: {kind, up, battery}}, links: [{a, b, prr}]}`` on change
``routes/<net>``     ``{t, routes: {path: [node, ...]}}`` the routes in force
``schedule/<net>``   ``{t, length, channel_offsets, cells}`` the TSCH schedule accepted
``invalid``          ``{t, key, src, reason}`` a message whose body failed its key's schema

Server-side decimation: a batch that brings more than ``max_points`` points to one series keeps
the first, last, minimum and maximum of each of ``max_points / 2`` buckets (in time order), so
peaks survive and the page never receives more than it can draw.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from agents.wncsca.config import MODES
from bus_schemas import keys
from core.time import to_units
from dashboard.feed import Row
from gateway.topology import Topology
from scenario import GatewayNodeConfig, Scenario

__all__ = ["RunView", "EVENT_TYPES", "decimate"]

EVENT_TYPES = ("node_down", "node_up", "link_degraded", "interference")
"""The network events the page offers as buttons and forms (``wncs inject`` takes them all)."""

Handler = Callable[["_Ctx"], None]


def decimate(points: list[list[Any]], cap: int) -> list[list[Any]]:
    """At most about ``cap`` of ``points`` (``[t, value, ...]``, in time order): per bucket
    the first, the minimum, the maximum and the last point, in time order."""
    if len(points) <= cap:
        return points
    buckets = max(1, cap // 4)
    size = math.ceil(len(points) / buckets)
    kept: list[list[Any]] = []
    for start in range(0, len(points), size):
        chunk = points[start : start + size]
        values = [p[1] for p in chunk]
        picks = {0, len(chunk) - 1, int(np.argmin(values)), int(np.argmax(values))}
        kept.extend(chunk[i] for i in sorted(picks))
    return kept


class _Path:
    """Delays and losses of one path, for its statistics."""

    def __init__(self) -> None:
        self.delays: list[float] = []
        self.lost = 0
        self.reasons: dict[str, int] = {}

    def stats(self, t: float) -> dict[str, Any]:
        d = np.asarray(self.delays)
        return {
            "t": t,
            "last": self.delays[-1] if self.delays else None,
            "mean": float(d.mean()) if d.size else None,
            "p95": float(np.percentile(d, 95)) if d.size else None,
            "n": int(d.size),
            "lost": self.lost,
            "reasons": dict(self.reasons),
        }


class _Network:
    """A gateway's WSN as the dashboard tracks it: the scenario's topology, its scheduled
    events at their times, the injected ones as the clock stamped them, batteries from
    ``net/stats``."""

    def __init__(self, cfg: GatewayNodeConfig) -> None:
        self.topology = Topology(cfg.topology)
        self.tsch = cfg.mac == "tsch"
        self.scheduled = sorted(
            ((e.t, e.event.model_dump(mode="json")) for e in cfg.events), key=lambda te: te[0]
        )
        self.battery: dict[str, float] = {}
        self.proposals: dict[int, dict[str, Any]] = {}

    def apply(self, event: dict[str, Any]) -> bool:
        try:
            self.topology.apply(event)
        except ValueError:  # the gateway refused it too
            return False
        return True

    def catch_up(self, t_units: float) -> bool:
        """Apply the scheduled events due by ``t_units``; whether any was."""
        changed = False
        while self.scheduled and self.scheduled[0][0] <= t_units:
            changed |= self.apply(self.scheduled.pop(0)[1])
        return changed

    def record(self, t: float) -> dict[str, Any]:
        topo = self.topology
        return {
            "t": t,
            "nodes": {
                n: {"kind": s.kind, "up": s.up, "battery": self.battery.get(n)}
                for n, s in sorted(topo.nodes.items())
            },
            "links": [{"a": lk.a, "b": lk.b, "prr": lk.prr} for lk in topo.links],
        }


class RunView:
    """The records of a run of ``scenario`` (see the module docstring), fed history rows."""

    def __init__(self, scenario: Scenario, *, max_points: int = 2000) -> None:
        self.scenario = scenario
        self.max_points = max_points
        self.streams: dict[str, list[Any]] = {}
        self.t = 0.0
        self.round = 0
        self.rows = 0
        self.networks = {
            g: _Network(cfg) for g, cfg in sorted(scenario.nodes_of(GatewayNodeConfig).items())
        }
        self._paths: dict[str, _Path] = {}
        self._handlers: dict[str, Handler | None] = {}
        self._sp_keys = {scenario.setpoint_key(n): n for n in scenario.loops}
        self._actuators = {
            keys.actuator(lp.plant, lp.actuator): n
            for n, lp in scenario.loops.items()
            if lp.actuator is not None
        }
        self._sampling = {
            keys.sampling(lp.plant, lp.sensor): n
            for n, lp in scenario.loops.items()
            if lp.sensor is not None
        }
        self._governed = scenario.agent_node() is not None
        batch: dict[str, list[Any]] = {}
        for name, lp in sorted(scenario.loops.items()):
            if lp.setpoint is not None:
                batch[f"sp/{name}"] = [[0.0, lp.setpoint]]
            if lp.tau_s is not None and not self._governed:
                batch[f"period/{name}"] = [[0.0, lp.tau_s, True]]
        for name, net in self.networks.items():
            batch[f"topology/{name}"] = [net.record(0.0)]
        self._merge(batch)

    # -- what the page is told once ---------------------------------------------------------------
    def static(self) -> dict[str, Any]:
        sc = self.scenario
        return {
            "name": sc.name,
            "time_unit": sc.time_unit,
            "end": sc.end_time,
            "agent": sc.agent_node(),
            "modes": list(MODES),
            "event_types": list(EVENT_TYPES),
            "loops": {
                n: {
                    "plant": lp.plant,
                    "sensor": lp.sensor,
                    "actuator": lp.actuator,
                    "network": lp.network,
                    "setpoint": lp.setpoint,
                }
                for n, lp in sorted(sc.loops.items())
            },
            "networks": {
                n: {
                    "tsch": net.tsch,
                    "positions": {
                        k: list(s.position) if s.position else None
                        for k, s in net.topology.nodes.items()
                    },
                }
                for n, net in self.networks.items()
            },
        }

    def snapshot(self) -> dict[str, list[Any]]:
        """Every record so far, by stream (what a page that connects now is sent first)."""
        return {name: list(records) for name, records in self.streams.items()}

    # -- rows in, records out ---------------------------------------------------------------------
    def ingest(self, rows: Iterable[Row]) -> dict[str, list[Any]]:
        """Take rows in history order; return the records they add, by stream."""
        batch: dict[str, list[Any]] = {}
        touched: set[str] = set()
        changed_nets: set[str] = set()
        for row in rows:
            self.rows += 1
            t = to_units(row.t)
            self.t = max(self.t, t)
            self.round = max(self.round, row.round)
            for name, net in self.networks.items():
                if net.catch_up(t):
                    changed_nets.add(name)
            if row.body is None:
                batch.setdefault("invalid", []).append(
                    {"t": t, "key": row.key, "src": row.src, "reason": row.invalid}
                )
                continue
            handler = self._handler(row.key)
            if handler is None:
                continue
            try:
                handler(_Ctx(t, row.key, row.src, row.body, batch, touched, changed_nets))
            except (KeyError, TypeError, ValueError, IndexError) as err:
                batch.setdefault("invalid", []).append(
                    {"t": t, "key": row.key, "src": row.src, "reason": f"unreadable: {err}"}
                )
        for path in sorted(touched):
            batch.setdefault(f"pathstats/{path}", []).append(self._paths[path].stats(self.t))
        for name in sorted(changed_nets):
            batch.setdefault(f"topology/{name}", []).append(self.networks[name].record(self.t))
        for name, records in batch.items():
            if records and isinstance(records[0], list) and not name.startswith(("sp/", "period/")):
                batch[name] = decimate(records, self.max_points)
        self._merge(batch)
        return batch

    def _merge(self, batch: dict[str, list[Any]]) -> None:
        for name, records in batch.items():
            self.streams.setdefault(name, []).extend(records)

    # -- one handler per key, worked out once -----------------------------------------------------
    def _handler(self, key: str) -> Handler | None:
        if key not in self._handlers:
            self._handlers[key] = self._make_handler(key)
        return self._handlers[key]

    def _make_handler(self, key: str) -> Handler | None:
        parts = key.split("/")
        loops = self.scenario.loops
        if key in self._sp_keys:
            loop = self._sp_keys[key]
            return lambda c: c.add(f"sp/{loop}", [c.t, float(c.body["value"])])
        if len(parts) == 3 and parts[0] == "loop" and parts[1] in loops:
            loop = parts[1]
            if parts[2] == "meas":
                return lambda c: self._meas(loop, c)
            if parts[2] == "u":
                return lambda c: c.add(f"u/{loop}", [c.t, float(c.body["value"])])
            return None
        if key in self._actuators:
            path = f"{self._actuators[key]}.actuator"
            return lambda c: self._delay(path, c, c.t - to_units(c.body["t_computed"]))
        if len(parts) == 3 and parts[0] == "plant" and parts[2] == "state":
            outputs = {
                n: lp.sensor for n, lp in loops.items() if lp.plant == parts[1] and lp.sensor
            }
            return lambda c: self._state(outputs, c)
        if key in self._sampling and not self._governed:
            loop = self._sampling[key]
            return lambda c: c.add(f"period/{loop}", [c.t, to_units(c.body["period"]), True])
        if key == keys.wncsca_rates():
            return self._rates
        if key == keys.wncsca_decision():
            return self._decision
        if key == keys.net_proposal():
            return self._proposal
        if key == keys.net_applied():
            return self._applied
        if key == keys.net_stats():
            return self._stats
        if key == keys.net_lost():
            return self._lost
        if parts[0] == "events" and len(parts) == 2:
            return lambda c: self._event(parts[1], c)
        if parts[0] == "ops":
            return lambda c: c.add(
                "timeline", {"t": c.t, "kind": "request", "key": key, "body": c.body}
            )
        return None

    def _meas(self, loop: str, c: _Ctx) -> None:
        body = c.body
        c.add(f"meas/{loop}", [c.t, float(body["value"])])
        self._delay(f"{loop}.sensor", c, c.t - to_units(body["t_sampled"]))

    def _delay(self, path: str, c: _Ctx, delay: float) -> None:
        self._paths.setdefault(path, _Path()).delays.append(delay)
        c.touched.add(path)
        c.add(f"delay/{path}", [c.t, delay])

    def _state(self, outputs: dict[str, str], c: _Ctx) -> None:
        body = c.body
        times = [to_units(t) for t in body["t"]]
        for loop, signal in outputs.items():
            values = body["values"].get(signal)
            if values is not None:
                c.extend(f"y/{loop}", [[t, float(v)] for t, v in zip(times, values, strict=True)])

    def _rates(self, c: _Ctx) -> None:
        body = c.body
        for loop, period in sorted(body["periods"].items()):
            closed = bool(body["closed"].get(loop, True))
            c.add(f"period/{loop}", [c.t, to_units(period), closed])
        c.add(
            "timeline",
            {
                "t": c.t,
                "kind": "rates",
                "mode": body["mode"],
                "method": body.get("method"),
                "periods": {n: to_units(p) for n, p in body["periods"].items()},
                "closed": body["closed"],
            },
        )

    def _decision(self, c: _Ctx) -> None:
        body = c.body
        c.add(
            "timeline",
            {
                "t": c.t,
                "kind": "decision",
                "subject": body["subject"],
                "verdict": body["verdict"],
                "reasons": list(body["reasons"]),
                "proposal": body.get("proposal"),
                "network": body.get("network"),
                "offending": list(body.get("offending", ())),
            },
        )
        name = body.get("network") or (
            next(iter(self.networks)) if len(self.networks) == 1 else None
        )
        net = self.networks.get(name or "")
        if net is None or body["subject"] != "proposal" or body["verdict"] != "accept":
            return
        proposal = net.proposals.get(body["proposal"]) if body.get("proposal") is not None else None
        tsch = proposal.get("tsch") if proposal else None
        if tsch:
            c.add(f"schedule/{name}", {"t": c.t, **tsch})

    def _proposal(self, c: _Ctx) -> None:
        body = c.body
        net = self.networks.get(c.src)
        if net is not None:
            net.proposals[int(body["id"])] = body
            if body.get("tsch") and not self._governed:
                c.add(f"schedule/{c.src}", {"t": c.t, **body["tsch"]})
        c.add(
            "timeline",
            {
                "t": c.t,
                "kind": "proposal",
                "id": body["id"],
                "event": body["event"],
                "source": body["source"],
                "routes": _routes(body["paths"]),
            },
        )

    def _applied(self, c: _Ctx) -> None:
        body = c.body
        routes = _routes(body["paths"])
        if c.src in self.networks:
            c.add(f"routes/{c.src}", {"t": c.t, "routes": routes})
        if body["event"] != "rates":
            c.add(
                "timeline",
                {
                    "t": c.t,
                    "kind": "applied",
                    "event": body["event"],
                    "source": body["source"],
                    "routes": routes,
                    "reason": body.get("reason"),
                },
            )

    def _stats(self, c: _Ctx) -> None:
        body = c.body
        net = self.networks.get(c.src)
        if net is None:
            return
        for node, stats in body["nodes"].items():
            net.battery[node] = float(stats["battery_pct"])
        c.changed_nets.add(c.src)

    def _lost(self, c: _Ctx) -> None:
        body = c.body
        if body["direction"] == "link":
            return
        path = f"{body['loop']}.{body['direction']}"
        stats = self._paths.setdefault(path, _Path())
        stats.lost += 1
        reason = body.get("reason") or "lost"
        stats.reasons[reason] = stats.reasons.get(reason, 0) + 1
        c.touched.add(path)

    def _event(self, network: str, c: _Ctx) -> None:
        body = c.body
        c.add("timeline", {"t": c.t, "kind": "request", "key": c.key, "body": body})
        net = self.networks.get(network)
        if net is not None and net.apply(body["event"]):
            c.changed_nets.add(network)


class _Ctx:
    """One valid row (its time in units, key, source and body) and the batch its records go
    into."""

    __slots__ = ("t", "key", "src", "body", "batch", "touched", "changed_nets")

    def __init__(
        self,
        t: float,
        key: str,
        src: str,
        body: dict[str, Any],
        batch: dict[str, list[Any]],
        touched: set[str],
        changed_nets: set[str],
    ) -> None:
        self.t = t
        self.key = key
        self.src = src
        self.body = body
        self.batch = batch
        self.touched = touched
        self.changed_nets = changed_nets

    def add(self, stream: str, record: Any) -> None:
        self.batch.setdefault(stream, []).append(record)

    def extend(self, stream: str, records: list[Any]) -> None:
        self.batch.setdefault(stream, []).extend(records)


def _routes(paths: dict[str, Any]) -> dict[str, list[str]]:
    return {name: list(p["route"]) for name, p in sorted(paths.items())}
