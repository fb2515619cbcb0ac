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
from scenario import Scenario
from scenario.views import path_hops

__all__ = ["RecordBuilder"]

Body = Callable[[], Mapping[str, Any]]
"""The body of a message as a mapping, computed only when the record needs it."""

_Reader = Callable[[int, int, Body], None]
"""``read(t, order, body)``: what the record takes from one message on a key."""

_MONITOR = keys.monitor_assessment("x").removesuffix("x")

_WNCSCA = {
    keys.wncsca_decision(): "decisions",
    keys.wncsca_rates(): "rates",
    keys.wncsca_timing(): "timing",
    keys.wncsca_model(): "models",
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
        self._keeps: dict[str, bool] = {}
        self._readers: dict[str, _Reader | None] = {}
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
        for name, cfg in sorted(scenario.plants().items()):
            rec.plants[name] = PlantRecord(tuple(cfg.build().state_names))
        self.rec = rec

    def keeps(self, key: str) -> bool:
        """Whether the record keeps the body of messages on ``key`` whole (then it must be the
        mapping a bus subscriber gets); of the others it reads scalar fields only."""
        kept = self._keeps.get(key)
        if kept is None:
            kept = self._keeps[key] = (
                key in _WNCSCA
                or key in (keys.net_applied(), keys.net_proposal(), keys.net_stats())
                or key.startswith(_MONITOR)
            )
        return kept

    def add(self, t: int, key: str, body: Body) -> None:
        """One message on run-relative ``key`` stamped ``t`` (ticks). A body the record cannot
        read (a hostile or malformed message the nodes dropped) is counted in
        :attr:`unreadable` and leaves the record as it was."""
        rec = self.rec
        order = self._order
        self._order += 1
        rec.published[key] = rec.published.get(key, 0) + 1
        if key in self._readers:
            read = self._readers[key]
        else:
            read = self._readers[key] = self._reader(key)
        if read is None:
            return
        try:
            read(t, order, body)
        except (KeyError, TypeError, ValueError):
            self.unreadable[key] = self.unreadable.get(key, 0) + 1

    def _reader(self, key: str) -> _Reader | None:
        """What the record takes from a message on ``key`` (``None``: only its count); worked
        out once per key."""
        rec = self.rec
        parts = key.split("/")
        if key in self._sp_keys:
            setpoints = rec.loops[self._sp_keys[key]].setpoints
            return lambda t, order, body: setpoints.append((t, float(body()["value"])))
        if len(parts) == 3 and parts[0] == "loop" and parts[1] in rec.loops:
            loop = rec.loops[parts[1]]
            if parts[2] == "meas":

                def meas(t: int, order: int, body: Body) -> None:
                    value = body()
                    y, t_sampled = float(value["value"]), int(value["t_sampled"])
                    loop.t.append(t)
                    loop.y.append(y)
                    loop.t_sampled.append(t_sampled)

                return meas
            if parts[2] == "u":
                made = self._moves.setdefault(parts[1], {})

                def move(t: int, order: int, body: Body) -> None:
                    value = body()
                    made.setdefault(int(value["t_computed"]), []).append(float(value["value"]))

                return move
            return None
        if len(parts) == 3 and parts[0] == "link" and parts[1] in rec.links:
            link = rec.links[parts[1]]
            if parts[2] == "tx":

                def sent(t: int, order: int, body: Body) -> None:
                    link.sent += 1

                return sent
            if parts[2] == "rx":

                def received(t: int, order: int, body: Body) -> None:
                    t_sent = int(body()["t_sent"])
                    link.t.append(t)
                    link.t_sent.append(t_sent)

                return received
            return None
        if key == keys.net_applied():
            return self._applied
        if key == keys.net_proposal():
            if not self._governed:
                return None
            proposals = rec.wncsca.setdefault("proposals", [])
            return lambda t, order, body: proposals.append({"t": t, "order": order, **body()})
        if key in _WNCSCA:
            kept = rec.wncsca.setdefault(_WNCSCA[key], [])
            return lambda t, order, body: kept.append({"t": t, "order": order, **body()})
        if key.startswith(_MONITOR):
            assessments = rec.monitor.setdefault(key.removeprefix(_MONITOR), [])
            return lambda t, order, body: assessments.append({"t": t, **body()})
        if key == keys.net_stats():
            # the last one wins
            return lambda t, order, body: rec.net_nodes.update(body()["nodes"])
        if key == keys.net_lost():
            return self._lost
        if len(parts) == 3 and parts[0] == "plant" and parts[2] == "state":
            plant = rec.plants.get(parts[1])
            if plant is None:
                return None

            def state(t: int, order: int, body: Body) -> None:
                batch = body()
                columns = [batch["values"][s] for s in plant.state_names]
                times = [int(v) for v in batch["t"]]
                rows = [[float(v) for v in row] for row in zip(*columns, strict=True)]
                plant.t.extend(times)
                plant.x.extend(rows)

            return state
        return None

    def _applied(self, t: int, order: int, body: Body) -> None:
        applied = {"t": t, **body()}
        if applied["event"] in ("rates", "rates_refused", "no_alternative"):
            self.rec.wncsca.setdefault("applied", []).append(applied)
        if applied["event"] not in ("rates", "rates_refused"):
            # what the network runs: a configuration applied, or a rejected one run for want
            # of an alternative (event no_alternative, the agent's verdict "keep": at risk)
            self.rec.configurations.append(applied)

    def _lost(self, t: int, order: int, body: Body) -> None:
        rec = self.rec
        loss = body()
        if loss["direction"] == "link":
            if loss["loop"] in rec.links:
                rec.links[loss["loop"]].lost += 1
        elif loss["loop"] in rec.loops:
            lost_loop = rec.loops[loss["loop"]]
            if loss.get("reason"):
                why = f"{loss['direction']}.{loss['reason']}"
                lost_loop.lost_by_reason[why] = lost_loop.lost_by_reason.get(why, 0) + 1
            if loss["direction"] == "sensor":
                lost_loop.lost += 1
            else:
                lost_loop.lost_moves += 1

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
