"""A bounded, seeded fuzzer on every key of a live run (issue 19): random bytes, msgpack that is
not an envelope, envelopes with broken fields, and envelopes of the run whose body breaks the
key's schema (a wrong type, a non-finite number, a missing or extra field), on every data key
the run uses and on its control keys, from an outside client of an ``--insecure`` run. The run
completes (exit 0, no node dies), its valid messages are the clean run's bit for bit (so are its
traces), and every bad message on a data key is accounted for: dropped and counted by the nodes
that read the key, or listed by the summary as an invalid row of the history.

It found one fault: garbage on ``clock/stop`` that reached a node while it collected a round's
messages made it leave the round without its ``Done``, and the run stalled until the clock's
timeout; a node now checks a stop message before it acts on it (``BusNode._is_stop``)."""

from __future__ import annotations

import json
import sqlite3
import threading
from collections import Counter
from pathlib import Path

import msgpack
import numpy as np
import pytest

from bus_schemas import codec, keys
from bus_schemas.errors import SchemaError
from kernel.bus import open_client
from runtime.history import body_schema
from runtime.ownership import owners_of, publishers
from scenario import load_scenario
from tests.conftest import SCENARIOS, last_tick
from tests.e2e.test_runs import start_run, traces, wait_for_virtual_time, wncs_run

pytestmark = pytest.mark.slow

DEMO = SCENARIOS / "jcstr_wncs.yaml"
PER_KEY = 40  # bad messages per key: bounded
CONTROL = (
    "clock/tick",
    "clock/tick/network",
    "clock/log",
    "clock/stop",
    "clock/done/reactor",
    "clock/done/wncsca",
    "ops/inject",
)


def _valid_rows(path: Path) -> list[tuple]:
    """The history's rows whose body passes its key's schema (the agent's wall-clock timings
    left out), in the table's order."""
    kept = []
    with sqlite3.connect(path) as db:
        rows = db.execute("SELECT round, t, key, src, seq, body FROM messages ORDER BY id")
        for row in rows:
            key, body = row[2], row[5]
            if key == keys.wncsca_timing():
                continue
            try:
                schema = body_schema(key)
                mapping = codec.unpack_mapping(body)
                if schema is not None:
                    codec.validate_body(mapping, schema)
            except SchemaError:
                continue
            kept.append(row)
    return kept


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("clean")
    return out, wncs_run(DEMO, out, "--engine", "threads")


def _mutations(rng: np.random.Generator, body: dict) -> dict:
    """``body`` (a valid body of the key) with one thing broken."""
    broken = dict(body)
    field = str(rng.choice(sorted(body)))
    how = int(rng.integers(0, 6))
    if how == 0:
        broken[field] = "not a value"
    elif how == 1:
        broken[field] = float("nan")
    elif how == 2:
        broken[field] = float("inf")
    elif how == 3:
        del broken[field]
        if not broken:
            broken = {"x": 1}
    elif how == 4:
        broken["unexpected_field"] = [1, 2, 3]
    else:
        broken[field] = {"nested": [[[]]]}
    return broken


def _garbage(
    rng: np.random.Generator, run_id: str, owner: str, seq: int, round_: int, template: dict | None
) -> bytes:
    kind = int(rng.integers(0, 4 if template is not None else 3))
    if kind == 0:
        return rng.bytes(int(rng.integers(0, 48)))
    if kind == 1:
        return msgpack.packb([1, "x", None, 2.5][int(rng.integers(0, 4))])
    if kind == 2:
        return msgpack.packb(
            {"v": 1, "run": run_id, "src": owner, "seq": "x", "round": -1, "t": None, "body": {}}
        )
    assert template is not None
    # a schema-violating body in a well-formed envelope of the run, from the key's owner
    head = {"v": 1, "run": run_id, "src": owner, "seq": seq, "round": round_, "t": 0}
    return msgpack.packb({**head, "body": _mutations(rng, template)})


def test_fuzzed_keys_change_nothing_and_every_bad_message_is_accounted_for(tmp_path, clean):
    clean_out, clean_summary = clean
    scenario = load_scenario(DEMO)
    table = publishers(scenario)
    with sqlite3.connect(clean_out / "history.sqlite") as db:
        templates = {
            key: msgpack.unpackb(body)
            for key, body in db.execute("SELECT key, body FROM messages ORDER BY id")
        }
    data_keys = sorted(templates)
    rng = np.random.default_rng(19)
    proc, info = start_run(DEMO, tmp_path, "--realtime", "0.25", "--insecure")
    run_id = info["run_id"]
    session = open_client(info["endpoint"])
    current = [0]

    def on_tick(sample) -> None:  # our own garbage on clock/log arrives here too
        try:
            current[0] = getattr(last_tick(sample), "round", current[0])
        except SchemaError:
            pass

    ticks = session.declare_subscriber(keys.full(run_id, keys.tick_log()), on_tick)
    sent: Counter[str] = Counter()
    stop = threading.Event()

    def fuzz() -> None:
        seq = 10**9
        for _ in range(PER_KEY):
            for key in (*data_keys, *CONTROL):
                if stop.is_set():
                    return
                owner = min(owners_of(table, key) or {"clock"})
                seq += 1
                payload = _garbage(rng, run_id, owner, seq, current[0], templates.get(key))
                session.put(keys.full(run_id, key), payload)
                sent[key] += 1
            stop.wait(0.02)

    th = threading.Thread(target=fuzz)
    try:
        wait_for_virtual_time(session, info, proc, 1_000_000)
        th.start()
        th.join(120)
        _, err = proc.communicate(timeout=300)
    finally:
        stop.set()
        th.join()
        ticks.undeclare()
        session.close()
    assert proc.returncode == 0, err
    assert sum(sent.values()) == PER_KEY * (len(data_keys) + len(CONTROL))
    summary = json.loads((tmp_path / "summary.json").read_text())
    # nothing that passed its schema differs from the clean run
    assert _valid_rows(tmp_path / "history.sqlite") == _valid_rows(clean_out / "history.sqlite")
    assert traces(summary) == traces(clean_summary)
    # every bad message on a data key: counted by the nodes that read it, or listed as invalid
    dropped = summary["messages"]["dropped_invalid"]
    listed = Counter(row["key"] for row in summary["messages"].get("invalid_in_history", []))
    for key in data_keys:
        assert dropped.get(key, 0) + listed[key] >= sent[key], (key, dropped.get(key), listed[key])
