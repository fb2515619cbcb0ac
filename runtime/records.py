"""A run's record from its messages: what every engine's :class:`~core.record.RunRecord` is
made of.

The bus engines feed it the historian's table (:func:`runtime.history.load_record`), the direct
engine the messages it passed in memory, in the same order (round, then key, source, sequence):
so the records of two engines are equal exactly when their messages are.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from bus_schemas import keys
from core.record import LinkRecord, LoopRecord, PlantRecord, RunRecord
from core.time import to_ticks
from gateway.carrier import path_hops
from runtime.scenario import Scenario

__all__ = ["RecordBuilder"]

Body = Callable[[], Mapping[str, Any]]
"""The body of a message as a mapping, computed only when the record needs it."""

_MONITOR = keys.monitor_assessment("x").removesuffix("x")

_WNCSCA = {
    keys.wncsca_decision(): "decisions",
    keys.wncsca_rates(): "rates",
    keys.wncsca_timing(): "timing",
}


class RecordBuilder:
    """Builds the record of a run of ``scenario`` from its messages (see the module docstring)."""

    def __init__(self, scenario: Scenario, *, engine: str) -> None:
        self.scenario = scenario
        self._order = 0
        self._moves: dict[str, dict[int, list[float]]] = {}
        # the set points the controllers followed (from operations, or passed on by the agent)
        self._sp_keys = {scenario.setpoint_key(name): name for name in scenario.loops}
        self._governed = scenario.agent_node() is not None
        self.unreadable: dict[str, int] = {}
        rec = RunRecord(
            scenario=scenario.name,
            seed=scenario.seed,
            engine=engine,
            end_time=to_ticks(scenario.end_time),
            time_unit=scenario.time_unit,
            disturbances=scenario.disturbance_times(),
            hops=path_hops(scenario),
        )
        for name, lp in sorted(scenario.loops.items()):
            rec.loops[name] = LoopRecord(
                plant=lp.plant,
                sensor=lp.sensor,
                setpoints=[(0, lp.setpoint)],
                settling_band=lp.settling_band,
            )
        for name in sorted(scenario.links):
            rec.links[name] = LinkRecord()
        for name, cfg in sorted(scenario.nodes.items()):
            if cfg.kind == "plant":
                rec.plants[name] = PlantRecord(tuple(cfg.build().state_names))
        self.rec = rec

    def keeps(self, key: str) -> bool:
        """Whether the record keeps the body of messages on ``key`` whole (then it must be the
        mapping a bus subscriber gets); of the others it reads scalar fields only."""
        return (
            key in _WNCSCA
            or key in (keys.net_applied(), keys.net_proposal(), keys.net_stats())
            or key.startswith(_MONITOR)
        )

    def add(self, t: int, key: str, body: Body) -> None:
        """One message on run-relative ``key`` stamped ``t`` (ticks). A body the record cannot
        read (a hostile or malformed message the nodes dropped) is counted in
        :attr:`unreadable` and leaves the record as it was."""
        try:
            self._add(t, key, body)
        except (KeyError, TypeError, ValueError):
            self.unreadable[key] = self.unreadable.get(key, 0) + 1

    def _add(self, t: int, key: str, body: Body) -> None:
        rec = self.rec
        order = self._order
        self._order += 1
        rec.published[key] = rec.published.get(key, 0) + 1
        parts = key.split("/")
        if key in self._sp_keys:
            rec.loops[self._sp_keys[key]].setpoints.append((t, float(body()["value"])))
        elif len(parts) == 3 and parts[0] == "loop" and parts[1] in rec.loops:
            loop = rec.loops[parts[1]]
            if parts[2] == "meas":
                value = body()
                loop.t.append(t)
                loop.y.append(float(value["value"]))
                loop.t_sampled.append(int(value["t_sampled"]))
            elif parts[2] == "u":
                value = body()
                made = self._moves.setdefault(parts[1], {})
                made.setdefault(int(value["t_computed"]), []).append(float(value["value"]))
        elif len(parts) == 3 and parts[0] == "link" and parts[1] in rec.links:
            link = rec.links[parts[1]]
            if parts[2] == "tx":
                link.sent += 1
            elif parts[2] == "rx":
                link.t.append(t)
                link.t_sent.append(int(body()["t_sent"]))
        elif key == keys.net_applied():
            applied = {"t": t, **body()}
            if applied["event"] in ("rates", "no_alternative"):
                rec.wncsca.setdefault("applied", []).append(applied)
            else:
                rec.configurations.append(applied)
        elif key == keys.net_proposal() and self._governed:
            rec.wncsca.setdefault("proposals", []).append({"t": t, "order": order, **body()})
        elif key in _WNCSCA:
            rec.wncsca.setdefault(_WNCSCA[key], []).append({"t": t, "order": order, **body()})
        elif key.startswith(_MONITOR):
            loop_name = key.removeprefix(_MONITOR)
            rec.monitor.setdefault(loop_name, []).append({"t": t, **body()})
        elif key == keys.net_stats():
            rec.net_nodes.update(body()["nodes"])  # the last one wins
        elif key == keys.net_lost():
            loss = body()
            if loss["direction"] == "link":
                if loss["loop"] in rec.links:
                    rec.links[loss["loop"]].lost += 1
            elif loss["loop"] in rec.loops:
                lost_loop = rec.loops[loss["loop"]]
                if loss["direction"] == "sensor":
                    lost_loop.lost += 1
                else:
                    lost_loop.lost_moves += 1
        elif len(parts) == 3 and parts[0] == "plant" and parts[2] == "state":
            plant = rec.plants.get(parts[1])
            if plant is not None:
                batch = body()
                columns = [batch["values"][s] for s in plant.state_names]
                plant.t.extend(int(v) for v in batch["t"])
                plant.x.extend([float(v) for v in row] for row in zip(*columns, strict=True))

    def finish(
        self, *, dropped_invalid: dict[str, int], dropped_nodes: dict[str, int]
    ) -> RunRecord:
        """The record, once every message is in: samples paired with the moves made from
        them, counts of what was sent and dropped."""
        rec = self.rec
        for name, loop in rec.loops.items():
            lp = self.scenario.loops[name]
            if lp.sensor is not None:
                loop.sent = rec.published.get(keys.sensor(lp.plant, lp.sensor), 0)
        for name, loop in rec.loops.items():  # pair each delivered sample with its move
            pending = self._moves.get(name, {})
            if loop.sensor is None:  # an actuator-only loop: its moves, in the order made
                for t, made in sorted(pending.items()):
                    loop.t += [t] * len(made)
                    loop.t_sampled += [t] * len(made)
                    loop.y += [None] * len(made)
                    loop.u += made
                continue
            loop.u = [pending[t].pop(0) if pending.get(t) else None for t in loop.t]
        rec.dropped_invalid = dict(dropped_invalid)
        rec.dropped_nodes = dict(dropped_nodes)
        return rec
