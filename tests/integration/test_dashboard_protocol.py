"""The dashboard's protocol without a browser (Starlette's test client on the real app): the
stream carries what the history holds, in order; a request from the page reaches the run's
clock and shows in the history; bad requests are answered with their reason and change
nothing in the run (its history digest equals a clean run's)."""

from __future__ import annotations

import json
import sqlite3
import threading

import msgpack
import numpy as np
import pytest
from starlette.testclient import TestClient

from bus_schemas import keys
from dashboard.server import Dashboard, create_app
from runtime.history import messages_digest
from runtime.launcher import launch
from tests.conftest import SCENARIOS, wait_until, write_variant

pytestmark = pytest.mark.slow


def _variant(tmp_path, end_time: float):
    def edit(d: dict) -> None:
        d["end_time"] = end_time
        d["setpoints"] = [s for s in d["setpoints"] if s["t"] < end_time]
        d["modes"] = [m for m in d["modes"] if m["t"] < end_time]
        events = d["nodes"]["network"]["events"]
        d["nodes"]["network"]["events"] = [e for e in events if e["t"] < end_time]

    return write_variant(tmp_path, SCENARIOS / "jcstr_wncs.yaml", f"demo_{end_time:g}.yaml", edit)


def _history(out, key: str) -> list[tuple[int, dict]]:
    with sqlite3.connect(out / "history.sqlite") as conn:
        rows = conn.execute("SELECT t, body FROM messages WHERE key = ? ORDER BY id", (key,))
        return [(t, msgpack.unpackb(body)) for t, body in rows]


def _read_until_finished(ws) -> tuple[dict, dict[str, list], list[dict]]:
    """hello, the records by stream, and the answers to requests, until the run's end."""
    hello = ws.receive_json()
    assert hello["type"] == "hello"
    streams: dict[str, list] = {}
    answers = []
    while True:
        msg = ws.receive_json()
        if msg["type"] == "data":
            for name, records in msg["append"].items():
                streams.setdefault(name, []).extend(records)
        elif msg["type"] == "finished":
            return hello, streams, answers
        else:
            answers.append(msg)


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("dash")
    out = tmp / "run"
    result = launch(_variant(tmp, 26.0), out, engine="threads")
    assert result.code == 0, result.error
    return out


def test_the_stream_carries_the_history_in_order(finished_run):
    out = finished_run
    with TestClient(create_app(Dashboard(out))) as client, client.websocket_connect("/ws") as ws:
        hello, streams, _ = _read_until_finished(ws)
        assert hello["live"] is False
        assert set(hello["static"]["loops"]) == {"level", "temperature"}
        # a replay takes no requests
        ws.send_text(json.dumps({"id": 1, "type": "mode", "mode": "steady_state"}))
        answer = ws.receive_json()
    assert answer == {
        "type": "error",
        "id": 1,
        "reason": "the run has ended: a replay takes no requests",
    }
    for loop in ("level", "temperature"):
        meas = _history(out, keys.meas(loop))
        assert streams[f"meas/{loop}"] == [[t / 1e6, b["value"]] for t, b in meas]
        np.testing.assert_allclose(
            streams[f"delay/{loop}.sensor"],
            [[t / 1e6, (t - b["t_sampled"]) / 1e6] for t, b in meas],
            atol=1e-12,
        )
        moves = _history(out, keys.move(loop))
        assert streams[f"u/{loop}"] == [[t / 1e6, b["value"]] for t, b in moves]
    decisions = [r for r in streams["timeline"] if r["kind"] == "decision"]
    stored = _history(out, keys.wncsca_decision())
    assert [(d["t"], d["verdict"], d["reasons"]) for d in decisions] == [
        (t / 1e6, b["verdict"], b["reasons"]) for t, b in stored
    ]
    # the demo's relay failure at 24 pu: the slow route rejected, the alternative accepted
    at_24 = [(d["verdict"], d["proposal"]) for d in decisions if d["t"] == 24.0]
    assert at_24 == [("reject", 1), ("accept", 2)]
    times = [r["t"] for r in streams["timeline"]]
    assert times == sorted(times)
    routes = streams["routes/network"][-1]["routes"]
    assert routes["level.sensor"] == ["s_level", "r4", "r5", "r2", "gw"]
    assert streams["topology/network"][-1]["nodes"]["r1"]["up"] is False


def _live(tmp_path, end_time: float, realtime: float):
    out = tmp_path / "run"
    result: dict = {}
    scenario = _variant(tmp_path, end_time)
    runner = threading.Thread(
        target=lambda: result.update(r=launch(scenario, out, engine="threads", realtime=realtime))
    )
    runner.start()

    def announced() -> bool:
        run = out / "run.json"
        return run.exists() and bool(json.loads(run.read_text()).get("endpoint"))

    wait_until(announced, timeout=60, what="run.json with the router endpoint")
    return out, runner, result, scenario


BAD = [
    ("{not json", "not JSON"),
    (json.dumps({"id": 5, "type": "reboot"}), "unknown request 'reboot'"),
    (
        json.dumps({"id": 6, "type": "setpoint", "loop": "pressure", "value": 1.0}),
        "unknown loop 'pressure'",
    ),
    (
        json.dumps({"id": 7, "type": "event", "event": "node_down", "fields": {"node": "r9"}}),
        "unknown node 'r9'",
    ),
]


def test_bad_requests_get_their_reason_and_change_nothing(tmp_path):
    out, runner, result, scenario = _live(tmp_path, 8.0, 0.4)
    with TestClient(create_app(Dashboard(out))) as client, client.websocket_connect("/ws") as ws:
        for text, _ in BAD:
            ws.send_text(text)
        ws.send_bytes(b"\x00\x01")
        hello, streams, answers = _read_until_finished(ws)
    runner.join(60)
    assert result["r"].code == 0, result["r"].error
    assert hello["live"] is True
    assert [a["type"] for a in answers] == ["error"] * 5
    for (_, named), answer in zip(BAD, answers, strict=False):
        assert named in answer["reason"]
    assert answers[-1]["reason"] == "binary message"
    assert [a["id"] for a in answers[1:4]] == [5, 6, 7]
    assert "clock" in streams  # simulated against wall time, while live
    clean = launch(scenario, tmp_path / "clean", engine="threads")
    assert clean.code == 0
    assert messages_digest(out / "history.sqlite") == messages_digest(
        tmp_path / "clean" / "history.sqlite"
    )


def test_a_button_request_reaches_the_clock_and_the_history(tmp_path):
    out, runner, result, _ = _live(tmp_path, 14.0, 0.5)
    with TestClient(create_app(Dashboard(out))) as client, client.websocket_connect("/ws") as ws:
        assert ws.receive_json()["live"] is True
        while (msg := ws.receive_json())["type"] != "data" or msg["t"] < 2.0:
            pass  # press the button once the loops run, as a user would
        request = {"id": 42, "type": "event", "event": "node_down", "fields": {"node": "r1"}}
        ws.send_text(json.dumps(request))
        streams: dict[str, list] = {}
        answers = []
        while (msg := ws.receive_json())["type"] != "finished":
            if msg["type"] == "data":
                for name, records in msg["append"].items():
                    streams.setdefault(name, []).extend(records)
            else:
                answers.append(msg)
    runner.join(60)
    assert result["r"].code == 0, result["r"].error
    [ack] = answers
    assert ack["type"] == "ack" and ack["id"] == 42
    assert ack["request"]["event"] == {"type": "node_down", "node": "r1"}
    [(t_event, body)] = _history(out, keys.network_events("network"))
    assert body["event"] == {"type": "node_down", "node": "r1"}
    assert t_event >= 2_000_000
    requests = [
        r for r in streams["timeline"] if r["kind"] == "request" and r["key"] == "events/network"
    ]
    assert [r["t"] for r in requests] == [t_event / 1e6]
    after = [
        (d["verdict"], d["subject"])
        for d in streams["timeline"]
        if d["kind"] == "decision" and d["t"] >= t_event / 1e6 and d["subject"] == "proposal"
    ]
    assert after[:2] == [("reject", "proposal"), ("accept", "proposal")]
