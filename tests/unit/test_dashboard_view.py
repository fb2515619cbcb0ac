"""The dashboard's view of a run (dashboard.view) and its request checks (dashboard.commands),
without a browser or a bus: rows in, records out, checked against numbers computed here."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from bus_schemas import InjectRequest, keys
from core.time import to_ticks
from dashboard.commands import CommandError, parse
from dashboard.feed import Row
from dashboard.view import RunView, decimate
from runtime.artefacts import SCENARIO_FILE
from runtime.inject import build_request
from scenario import load_scenario
from tests.conftest import SCENARIOS

DEMO = SCENARIOS / "jcstr_wncs.yaml"


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(DEMO)


def _row(i: int, t: float, key: str, body: dict | None, src: str = "x", invalid=None) -> Row:
    return Row(i, i, to_ticks(t), key, src, body, invalid)


def test_delays_and_their_statistics_match_numpy(scenario):
    rng = np.random.default_rng(3)
    sampled = np.sort(rng.uniform(0, 10, 300))
    delay = rng.uniform(0.15, 0.3, 300)
    rows = [
        _row(i, s + d, keys.meas("level"), {"value": 0.7 + i * 1e-4, "t_sampled": to_ticks(s)})
        for i, (s, d) in enumerate(zip(sampled, delay, strict=True))
    ]
    rows.sort(key=lambda r: r.t)
    view = RunView(scenario)
    batch = view.ingest(rows)
    got = np.array([d for _, d in batch["delay/level.sensor"]])
    expected = np.array([r.t / 1e6 - r.body["t_sampled"] / 1e6 for r in rows])
    np.testing.assert_allclose(got, expected, atol=1e-12)
    [stats] = batch["pathstats/level.sensor"]
    assert stats["n"] == 300
    assert stats["mean"] == pytest.approx(expected.mean(), abs=1e-12)
    assert stats["p95"] == pytest.approx(np.percentile(expected, 95), abs=1e-12)
    assert stats["last"] == pytest.approx(expected[-1], abs=1e-12)
    assert [p[1] for p in batch["meas/level"]] == [r.body["value"] for r in rows]


def test_losses_are_counted_per_path_and_reason(scenario):
    view = RunView(scenario)
    loss = {"loop": "level", "direction": "sensor", "t_ready": 0}
    batch = view.ingest(
        [
            _row(1, 1.0, keys.net_lost(), {**loss, "reason": "retries"}),
            _row(2, 1.5, keys.net_lost(), {**loss, "reason": "retries"}),
            _row(3, 2.0, keys.net_lost(), {**loss, "reason": None}),
        ]
    )
    [stats] = batch["pathstats/level.sensor"]
    assert stats["lost"] == 3
    assert stats["reasons"] == {"retries": 2, "lost": 1}
    assert stats["n"] == 0 and stats["mean"] is None


def test_true_output_comes_from_the_plant_state_of_the_loop_sensor(scenario):
    view = RunView(scenario)
    body = {
        "t": [0, 10_000, 20_000],
        "values": {"H": [0.66, 0.67, 0.68], "T": [50.0] * 3, "T_j": [143.0] * 3},
    }
    batch = view.ingest([_row(1, 0.02, keys.plant_state("reactor"), body)])
    assert batch["y/level"] == [[0.0, 0.66], [0.01, 0.67], [0.02, 0.68]]
    assert batch["y/temperature"] == [[0.0, 50.0], [0.01, 50.0], [0.02, 50.0]]


def test_injected_and_scheduled_events_change_the_topology(scenario):
    view = RunView(scenario)
    first = view.streams["topology/network"][0]
    assert first["nodes"]["r1"]["up"] is True
    batch = view.ingest(
        [
            _row(
                1,
                5.0,
                keys.network_events("network"),
                {"event": {"type": "node_down", "node": "r3"}, "source": "injected"},
            )
        ]
    )
    [topo] = batch["topology/network"]
    assert topo["nodes"]["r3"]["up"] is False and topo["nodes"]["r1"]["up"] is True
    assert batch["timeline"][0]["kind"] == "request"
    # the scenario's own event (r1 fails at 24 pu) is applied once the rows pass its time
    batch = view.ingest([_row(2, 23.9, keys.loop_setpoint("level"), {"value": 0.7})])
    assert "topology/network" not in batch
    batch = view.ingest([_row(3, 24.0, keys.loop_setpoint("level"), {"value": 0.7})])
    assert batch["topology/network"][-1]["nodes"]["r1"]["up"] is False
    # an event the gateway would refuse (unknown node) changes nothing
    batch = view.ingest(
        [
            _row(
                4,
                25.0,
                keys.network_events("network"),
                {"event": {"type": "node_down", "node": "zz"}},
            )
        ]
    )
    assert "topology/network" not in batch


def test_battery_from_net_stats(scenario):
    view = RunView(scenario)
    stats = {
        "t": 0,
        "paths": {},
        "nodes": {"r1": {"energy_mAh": 1.0, "battery_pct": 42.5, "lifetime_h": 10.0}},
    }
    batch = view.ingest([_row(1, 4.0, keys.net_stats(), stats, src="network")])
    assert batch["topology/network"][-1]["nodes"]["r1"]["battery"] == 42.5


def test_invalid_rows_are_listed_never_read(scenario):
    view = RunView(scenario)
    batch = view.ingest(
        [
            _row(1, 1.0, keys.meas("level"), None, invalid="value: not a finite number"),
            _row(2, 1.0, keys.meas("level"), {"value": 0.7, "t_sampled": 900_000}),
        ]
    )
    assert batch["invalid"] == [
        {"t": 1.0, "key": "loop/level/meas", "src": "x", "reason": "value: not a finite number"}
    ]
    assert batch["meas/level"] == [[1.0, 0.7]]


def test_decisions_rates_and_periods(scenario):
    view = RunView(scenario)
    decision = {
        "subject": "proposal",
        "network": "network",
        "proposal": 1,
        "verdict": "reject",
        "reasons": ["level: delay too long"],
    }
    rates = {
        "mode": "steady_state",
        "periods": {"level": 1_000_000, "temperature": 500_000},
        "closed": {"level": False, "temperature": True},
        "proposal": 0,
    }
    batch = view.ingest(
        [_row(1, 24.0, keys.wncsca_decision(), decision), _row(2, 24.0, keys.wncsca_rates(), rates)]
    )
    kinds = [(r["kind"], r.get("verdict")) for r in batch["timeline"]]
    assert kinds == [("decision", "reject"), ("rates", None)]
    assert batch["timeline"][0]["reasons"] == ["level: delay too long"]
    assert batch["period/level"] == [[24.0, 1.0, False]]
    assert batch["period/temperature"] == [[24.0, 0.5, True]]


def test_snapshot_is_the_sum_of_the_batches(scenario):
    view = RunView(scenario)
    before = view.snapshot()
    rows = [
        _row(i, i * 0.1, keys.move("level"), {"value": float(i), "t_computed": 0})
        for i in range(1, 50)
    ]
    a = view.ingest(rows[:20])
    b = view.ingest(rows[20:])
    snap = view.snapshot()
    assert snap["u/level"] == a["u/level"] + b["u/level"]
    assert snap["sp/level"] == before["sp/level"]  # the initial set point, at t = 0


def test_decimation_keeps_peaks_and_order():
    rng = np.random.default_rng(0)
    t = np.arange(100_000) * 1e-3
    v = rng.normal(size=t.size)
    v[31_337] = 50.0  # a spike the page must still show
    v[77_001] = -50.0
    points = [[float(a), float(b)] for a, b in zip(t, v, strict=True)]
    kept = decimate(points, 2000)
    assert len(kept) <= 2000
    times = [p[0] for p in kept]
    assert times == sorted(times)
    assert max(p[1] for p in kept) == 50.0 and min(p[1] for p in kept) == -50.0
    assert kept[0] == points[0] and kept[-1] == points[-1]
    assert decimate(points[:10], 2000) == points[:10]


def test_a_batch_beyond_max_points_is_decimated(scenario):
    view = RunView(scenario, max_points=400)
    rows = [
        _row(i, i * 1e-3, keys.move("level"), {"value": float(i % 7), "t_computed": 0})
        for i in range(1, 10_001)
    ]
    batch = view.ingest(rows)
    assert len(batch["u/level"]) <= 400
    assert view.rows == 10_000


# -- requests from the page --------------------------------------------------------------------


@pytest.fixture
def run_dir(tmp_path, scenario):
    (tmp_path / SCENARIO_FILE).write_text(yaml.safe_dump(scenario.model_dump(mode="json")))
    return tmp_path


def test_a_button_makes_the_request_wncs_inject_makes(run_dir):
    cmd = parse(
        json.dumps({"id": 3, "type": "event", "event": "node_down", "fields": {"node": "r1"}}),
        run_dir,
    )
    assert cmd.id == 3
    assert cmd.request == build_request("node_down", ["node=r1"], run_dir=run_dir, network=None)
    cmd = parse(json.dumps({"type": "setpoint", "loop": "level", "value": 0.72}), run_dir)
    assert cmd.request == InjectRequest(setpoint={"loop": "level", "value": 0.72})
    cmd = parse(json.dumps({"type": "mode", "mode": "steady_state"}), run_dir)
    assert cmd.request == InjectRequest(mode="steady_state")
    cmd = parse(
        json.dumps(
            {
                "type": "event",
                "event": "link_degraded",
                "fields": {"a": "r1", "b": "r2", "prr": 0.5},
            }
        ),
        run_dir,
    )
    assert cmd.request.event == {"type": "link_degraded", "a": "r1", "b": "r2", "prr": 0.5}


@pytest.mark.parametrize(
    ("text", "named"),
    [
        ("{not json", "not JSON"),
        ("[1, 2]", "expected a JSON object"),
        ('{"type": "reboot"}', "unknown request 'reboot'"),
        ('{"type": "mode", "mode": "warp"}', "unknown mode 'warp'"),
        ('{"type": "mode", "mode": "steady_state", "extra": 1}', "unknown field(s) extra"),
        ('{"type": "setpoint", "loop": "pressure", "value": 1}', "unknown loop 'pressure'"),
        ('{"type": "setpoint", "loop": "level", "value": "high"}', "not a finite number"),
        ('{"type": "setpoint", "loop": "level", "value": NaN}', "not a finite number"),
        ('{"type": "setpoint", "loop": "level", "value": 1e300}', "beyond a physical value"),
        ('{"type": "event", "event": "node_down", "fields": {"node": "r9"}}', "unknown node 'r9'"),
        ('{"type": "event", "event": "meteor", "fields": {}}', "event 'meteor'"),
        (
            '{"type": "event", "event": "link_degraded", "fields": {"a": "r1", "b": "r2", '
            '"prr": 7}}',
            "prr",
        ),
        (
            '{"type": "event", "event": "interference", "fields": {"channels": [11], "prr": 0.1}}',
            "needs a TSCH network",
        ),
        ('{"id": [1], "type": "mode", "mode": "steady_state"}', "id: must be"),
        ("x" * 70_000, "too long"),
    ],
)
def test_bad_requests_are_refused_with_their_reason(run_dir, text, named):
    with pytest.raises(CommandError) as err:
        parse(text, run_dir)
    assert named in err.value.reason


def test_the_accepted_tsch_schedule_is_shown():
    scenario = load_scenario(SCENARIOS / "jcstr_tsch.yaml")
    view = RunView(scenario)
    [net] = scenario.gateways()
    cells = [
        {"slot": 3, "channel": 0, "tx": "s_level", "rx": "r1"},
        {"slot": 7, "channel": 1, "tx": "r1", "rx": "gw"},
    ]
    tsch = {
        "slot_ticks": 10_000,
        "length": 240,
        "channel_offsets": 4,
        "retry_cells": 1,
        "static": False,
        "cells": cells,
    }
    proposal = {"id": 0, "event": "initial", "source": "initial", "paths": {}, "tsch": tsch}
    decision = {
        "subject": "proposal",
        "network": net,
        "proposal": 0,
        "verdict": "accept",
        "reasons": [],
    }
    batch = view.ingest(
        [
            _row(1, 0.0, keys.net_proposal(), proposal, src=net),
            _row(2, 0.0, keys.wncsca_decision(), decision, src="wncsca"),
        ]
    )
    [schedule] = batch[f"schedule/{net}"]
    assert schedule["length"] == 240 and schedule["channel_offsets"] == 4
    assert schedule["cells"] == cells
    assert view.static()["networks"][net]["tsch"] is True
    rejected = {**decision, "proposal": 1, "verdict": "reject"}
    batch = view.ingest(
        [
            _row(3, 1.0, keys.net_proposal(), {**proposal, "id": 1}, src=net),
            _row(4, 1.0, keys.wncsca_decision(), rejected, src="wncsca"),
        ]
    )
    assert f"schedule/{net}" not in batch
