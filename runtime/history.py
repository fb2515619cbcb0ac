"""The run's history database (SQLite in WAL mode): schema, reading, digest.

Tables (keys are run-relative, so histories of two runs compare equal when their messages do):

``meta(name, value)``
    run id, scenario, seed, engine, the clock's stop message (JSON).
``ticks(round, t, expected)``
    every clock round: time in ticks and the expected counts (JSON).
``messages(id, round, t, key, src, seq, body)``
    every data message of the run, in the deterministic order the historian handled them
    (round, then key, source, sequence); ``body`` is the msgpack body.

The historian node writes it; :func:`load_record` rebuilds an engine-independent
:class:`~runtime.record.RunRecord` from it, and :func:`messages_digest` hashes the message table.
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
from pathlib import Path
from typing import Any

from bus_schemas import codec, keys
from gateway.carrier import path_hops
from runtime.record import LinkRecord, LoopRecord, PlantRecord, RunRecord
from runtime.scenario import Scenario

__all__ = ["SCHEMA", "connect", "messages_digest", "load_record", "read_meta"]

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS ticks (round INTEGER PRIMARY KEY, t INTEGER NOT NULL,
                                  expected TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS messages (id INTEGER PRIMARY KEY, round INTEGER NOT NULL,
                                     t INTEGER NOT NULL, key TEXT NOT NULL, src TEXT NOT NULL,
                                     seq INTEGER NOT NULL, body BLOB NOT NULL);
CREATE INDEX IF NOT EXISTS messages_key ON messages (key);
"""


def connect(path: str | Path, *, create: bool = False) -> sqlite3.Connection:
    """Open a history database (WAL mode); ``create`` makes the tables."""
    path = Path(path)
    if not create and not path.exists():
        raise FileNotFoundError(f"{path}: no history database")
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA journal_mode=WAL")
    conn.execute("PRAGMA synchronous=NORMAL")
    if create:
        conn.executescript(SCHEMA)
    return conn


def read_meta(path: str | Path) -> dict[str, Any]:
    """The ``meta`` table as a dict (JSON values decoded)."""
    with connect(path) as conn:
        return {name: json.loads(value) for name, value in conn.execute("SELECT * FROM meta")}


def messages_digest(path: str | Path) -> str:
    """SHA-256 of the message table, row by row in id order (no run id in it), without the
    agent's wall-clock measurements (``wncsca/timing``), which no seed can reproduce."""
    h = hashlib.sha256()
    with connect(path) as conn:
        rows = conn.execute("SELECT round, t, key, src, seq, body FROM messages ORDER BY id")
        for rnd, t, key, src, seq, body in rows:
            if key == keys.wncsca_timing():
                continue
            h.update(f"{rnd}|{t}|{key}|{src}|{seq}|".encode())
            h.update(body)
            h.update(b"\n")
    return h.hexdigest()


def load_record(path: str | Path, scenario: Scenario, *, engine: str) -> RunRecord:
    """Rebuild the run's record (traces, true outputs, message counts) from its history."""
    from runtime.time import to_ticks

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
    moves: dict[str, dict[int, list[float]]] = {}
    # the set points the controllers followed (from operations, or passed on by the agent)
    sp_keys = {scenario.setpoint_key(name): name for name in scenario.loops}
    with connect(path) as conn:
        rows = conn.execute("SELECT t, key, body FROM messages ORDER BY id")
        for order, (t, key, body) in enumerate(rows):
            rec.published[key] = rec.published.get(key, 0) + 1
            parts = key.split("/")
            if key in sp_keys:
                rec.loops[sp_keys[key]].setpoints.append(
                    (t, float(codec.unpack_mapping(body)["value"]))
                )
            elif len(parts) == 3 and parts[0] == "loop" and parts[1] in rec.loops:
                loop = rec.loops[parts[1]]
                value = codec.unpack_mapping(body)
                if parts[2] == "meas":
                    loop.t.append(t)
                    loop.y.append(float(value["value"]))
                    loop.t_sampled.append(int(value["t_sampled"]))
                elif parts[2] == "u":
                    moves.setdefault(parts[1], {}).setdefault(int(value["t_computed"]), []).append(
                        float(value["value"])
                    )
            elif len(parts) == 3 and parts[0] == "link" and parts[1] in rec.links:
                link = rec.links[parts[1]]
                if parts[2] == "tx":
                    link.sent += 1
                elif parts[2] == "rx":
                    link.t.append(t)
                    link.t_sent.append(int(codec.unpack_mapping(body)["t_sent"]))
            elif key == keys.net_applied():
                applied = {"t": t, **codec.unpack_mapping(body)}
                if applied["event"] in ("rates", "no_alternative"):
                    rec.wncsca.setdefault("applied", []).append(applied)
                else:
                    rec.configurations.append(applied)
            elif key == keys.net_proposal() and scenario.agent_node() is not None:
                rec.wncsca.setdefault("proposals", []).append(
                    {"t": t, "order": order, **codec.unpack_mapping(body)}
                )
            elif key in (keys.wncsca_decision(), keys.wncsca_rates(), keys.wncsca_timing()):
                name = {
                    keys.wncsca_decision(): "decisions",
                    keys.wncsca_rates(): "rates",
                    keys.wncsca_timing(): "timing",
                }[key]
                rec.wncsca.setdefault(name, []).append(
                    {"t": t, "order": order, **codec.unpack_mapping(body)}
                )
            elif key == keys.net_stats():
                rec.net_nodes.update(codec.unpack_mapping(body)["nodes"])  # the last one wins
            elif key == keys.net_lost():
                loss = codec.unpack_mapping(body)
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
                    batch = codec.unpack_mapping(body)
                    columns = [batch["values"][s] for s in plant.state_names]
                    plant.t.extend(int(v) for v in batch["t"])
                    plant.x.extend([float(v) for v in row] for row in zip(*columns, strict=True))
        meta = {n: json.loads(v) for n, v in conn.execute("SELECT * FROM meta")}
    for name, loop in rec.loops.items():
        lp = scenario.loops[name]
        if lp.sensor is not None:
            loop.sent = rec.published.get(keys.sensor(lp.plant, lp.sensor), 0)
    for name, loop in rec.loops.items():  # pair each delivered sample with the move made from it
        pending = moves.get(name, {})
        if loop.sensor is None:  # an actuator-only loop: its moves, in the order they were made
            for t, made in sorted(pending.items()):
                loop.t += [t] * len(made)
                loop.t_sampled += [t] * len(made)
                loop.y += [None] * len(made)
                loop.u += made
            continue
        loop.u = [pending[t].pop(0) if pending.get(t) else None for t in loop.t]
    stop = meta.get("stop") or {}
    rec.dropped_invalid = dict(stop.get("dropped_invalid", {}))
    rec.dropped_nodes = dict(stop.get("dropped_nodes", {}))
    return rec
