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
:class:`~core.record.RunRecord` from it, and :func:`messages_digest` hashes the message table.
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from bus_schemas import (
    Decision,
    Estimate,
    Loss,
    ModelEstimate,
    ModeRequest,
    MonitorAssessment,
    Move,
    NetApplied,
    NetStats,
    NetworkEvent,
    PlantState,
    Proposal,
    Rates,
    Sample,
    SamplingPeriod,
    Setpoint,
    Timing,
    codec,
    keys,
)
from bus_schemas.errors import SchemaError
from core.record import RunRecord
from runtime.records import RecordBuilder
from scenario import Scenario

__all__ = [
    "SCHEMA",
    "BODIES",
    "connect",
    "messages_digest",
    "load_record",
    "read_meta",
    "body_schema",
]

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


BODIES: tuple[tuple[str, type[BaseModel]], ...] = (
    ("plant/*/sensor/*", Sample),
    ("plant/*/actuator/*", Move),
    ("plant/*/state", PlantState),
    ("plant/*/sampling/*", SamplingPeriod),
    ("loop/*/meas", Sample),
    ("loop/*/u", Move),
    ("loop/*/sp", Setpoint),
    ("link/*/tx", Estimate),
    ("link/*/rx", Estimate),
    ("ops/setpoint/*", Setpoint),
    ("ops/mode", ModeRequest),
    ("events/*", NetworkEvent),
    ("net/applied", NetApplied),
    ("net/proposal", Proposal),
    ("net/stats", NetStats),
    ("net/lost", Loss),
    ("wncsca/decision", Decision),
    ("wncsca/rates", Rates),
    ("wncsca/timing", Timing),
    ("wncsca/model", ModelEstimate),
    ("monitor/assessment/*", MonitorAssessment),
)
"""The body schema of every data key (run-relative key expression -> body)."""


def body_schema(key: str) -> type[BaseModel] | None:
    """The schema of the bodies on concrete key ``key`` (``None``: not a data key we know)."""
    for pattern, schema in BODIES:
        if keys.intersects(pattern, key):
            return schema
    return None


def load_record(path: str | Path, scenario: Scenario, *, engine: str) -> RunRecord:
    """Rebuild the run's record (traces, true outputs, message counts) from its history.

    Only validated messages go into it: a stored body that does not decode or fails its key's
    schema (a forged or garbled message the nodes refused, which the historian still keeps) is
    listed in :attr:`RunRecord.invalid`, never read as a number.
    """
    builder = RecordBuilder(scenario, engine=engine)
    invalid: list[dict[str, Any]] = []
    with connect(path) as conn:
        rows = conn.execute("SELECT round, t, key, src, seq, body FROM messages ORDER BY id")
        for rnd, t, key, src, seq, body in rows:
            try:
                mapping = codec.unpack_mapping(body)
                schema = body_schema(key)
                if schema is not None:
                    codec.validate_body(mapping, schema)
            except SchemaError as err:
                invalid.append(
                    {"round": rnd, "key": key, "src": src, "seq": seq, "reason": str(err)}
                )
                continue
            builder.add(t, key, lambda m=mapping: m)
        meta = {n: json.loads(v) for n, v in conn.execute("SELECT * FROM meta")}
    stop = meta.get("stop") or {}
    rec = builder.finish(
        dropped_invalid=dict(stop.get("dropped_invalid", {})),
        dropped_nodes=dict(stop.get("dropped_nodes", {})),
    )
    rec.invalid = invalid
    return rec
