"""A run's routine data for the monitor (no bus): column names, alignment on the loop's samples,
set points by round, the window, refusals naming column and row; the monitor node's
configuration and its checks against the scenario; the bus contract of its assessments."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import zenoh

from agents.monitor.columns import resolve_column
from agents.monitor.errors import DataError
from agents.monitor.run_data import RunSeries, assess_series
from bus_schemas import MonitorAssessment, MonitorCandidate, MonitorHarris, codec, keys
from bus_schemas.bodies import PlantState, Sample, Setpoint
from core.errors import ConfigError, SchemaError
from scenario import parse_scenario
from scenario.views import run_shape
from tests.conftest import SCENARIOS, load_yaml

CASCADE = SCENARIOS / "cascade_routine.yaml"
S = 1_000_000  # ticks per minute


@pytest.fixture(scope="module")
def data():
    return load_yaml(CASCADE)


@pytest.fixture(scope="module")
def scenario(data):
    return parse_scenario(data, source=str(CASCADE))


def _variant(data, **monitor):
    d = copy.deepcopy(data)
    d["nodes"]["monitor"].update(monitor)
    return d


# ---------------------------------------------------------------------------------------------
# Columns
# ---------------------------------------------------------------------------------------------
def test_column_names(scenario):
    c = resolve_column(run_shape(scenario), "temperature")
    assert (c.kind, c.loop) == ("meas", "temperature")
    c = resolve_column(run_shape(scenario), "temperature.sp")
    assert (c.kind, c.loop) == ("sp", "temperature")
    c = resolve_column(run_shape(scenario), "reactor.y2")
    assert (c.kind, c.plant, c.state) == ("state", "reactor", "y2")
    with pytest.raises(ValueError) as exc:
        resolve_column(run_shape(scenario), "reactor.T_j")
    text = str(exc.value)
    assert "'reactor.T_j' is not a column of this run" in text
    assert "loops ['temperature']" in text and "reactor.y2" in text and "reactor.n3" in text


def test_series_refuses_unknown_columns_naming_them(scenario):
    with pytest.raises(DataError) as exc:
        RunSeries(run_shape(scenario), "level", [])
    assert exc.value.column == "level" and "not a loop of this run" in str(exc.value)
    with pytest.raises(DataError) as exc:
        RunSeries(run_shape(scenario), "temperature", ["reactor.y9"])
    assert exc.value.column == "reactor.y9"
    with pytest.raises(DataError, match="the primary itself"):
        RunSeries(run_shape(scenario), "temperature", ["temperature"])


# ---------------------------------------------------------------------------------------------
# Alignment and window
# ---------------------------------------------------------------------------------------------
STATES = "y3 y2 z1 z2 z3 z4 z5 z6 z7 z8 y1 n1 n2 n3".split()  # the plant's states


def _feed_run(series: RunSeries, n: int, *, sp_at: dict[int, float] | None = None) -> None:
    """A run as the bus delivers it: at each minute k the plant samples (round 5k) with its state
    batch, the sample reaches the controller in round 5k + 1; set point changes in given rounds."""
    rng = np.random.default_rng(0)
    sp_at = dict(sp_at or {})
    for k in range(n):
        t = k * S
        x = {name: (float(rng.standard_normal()),) for name in ("y2", "y3")}
        others = {s: (0.0,) for s in STATES if s not in x}
        series.feed(keys.plant_state("reactor"), 5 * k, t, PlantState(t=(t,), values=x | others))
        if 5 * k + 1 in sp_at:
            value = sp_at.pop(5 * k + 1)
            series.feed(keys.setpoint("temperature"), 5 * k + 1, t, Setpoint(value=value))
        series.feed(
            keys.meas("temperature"),
            5 * k + 1,
            t,
            Sample(value=float(np.sin(k) + 0.1 * k % 7), t_sampled=t),
        )
        if 5 * k + 2 in sp_at:
            value = sp_at.pop(5 * k + 2)
            series.feed(keys.setpoint("temperature"), 5 * k + 2, t, Setpoint(value=value))


def test_columns_align_on_the_loops_samples(scenario):
    s = RunSeries(
        run_shape(scenario), "temperature", ["temperature.sp", "reactor.y2", "reactor.y3"]
    )
    assert [k for k, _ in s.subscriptions()] == [
        "loop/temperature/meas",
        "ops/setpoint/temperature",
        "plant/reactor/state",
    ]
    # a set point published in the round that delivers sample 10 applies to it (the controller
    # handles both in that round); one published in the round after sample 20 applies from 21
    _feed_run(s, 40, sp_at={5 * 10 + 1: 1.5, 5 * 20 + 2: 2.5})
    table, info = s.table()
    assert info.n == 40 and info.t_first == 0 and info.t_last == 39 * S and info.gaps == 0
    sp = table["temperature.sp"]
    assert list(sp[:10]) == [0.0] * 10 and list(sp[10:21]) == [1.5] * 11
    assert list(sp[21:]) == [2.5] * 19
    rng = np.random.default_rng(0)
    expected = np.array([[rng.standard_normal() for _ in range(2)] for _ in range(40)])
    assert np.array_equal(table["reactor.y2"], expected[:, 0])
    assert np.array_equal(table["reactor.y3"], expected[:, 1])


def test_window_start_and_out_of_order_delivery(scenario):
    s = RunSeries(run_shape(scenario), "temperature", ["reactor.y2"], start=3 * S, window=5)
    grid = tuple(range(0, 9 * S, 2 * S))  # a grid of 2 min
    s.feed(keys.plant_state("reactor"), 0, 0, PlantState(t=grid, values={"y2": (0, 2, 4, 6, 8)}))
    for k, ts in enumerate([0, 1, 2, 3, 5, 4, 6, 8, 7]):  # 4 and 7 arrive late
        s.feed(keys.meas("temperature"), k + 1, k * S, Sample(value=float(ts), t_sampled=ts * S))
    table, info = s.table()
    # taken at or after 3, the last 5 delivered (5, 4, 6, 8, 7), sorted by sampling instant
    assert list(table["temperature"]) == [4.0, 5.0, 6.0, 7.0, 8.0]
    assert list(table["reactor.y2"]) == [4.0, 4.0, 6.0, 6.0, 8.0]  # the grid point at or before
    assert info.delivered == 6 and info.gaps == 0


def test_pruned_window_equals_the_tail_of_the_whole_series(scenario):
    whole = RunSeries(run_shape(scenario), "temperature", ["temperature.sp", "reactor.y2"])
    windowed = RunSeries(
        run_shape(scenario), "temperature", ["temperature.sp", "reactor.y2"], window=37
    )
    for s in (whole, windowed):
        _feed_run(s, 300, sp_at={11: 1.0, 5 * 150 + 1: 2.0})
    a, _ = whole.table()
    b, info = windowed.table()
    assert info.n == 37 and info.t_first == 263 * S
    for name in a:
        assert np.array_equal(a[name][-37:], b[name])
    assert len(windowed._held["reactor.y2"].t) < 100  # older grid points were dropped


def test_refusals_name_column_and_row(scenario):
    s = RunSeries(run_shape(scenario), "temperature", ["reactor.y2"])
    s.feed(keys.meas("temperature"), 1, 0, Sample(value=1.0, t_sampled=0))
    s.feed(keys.plant_state("reactor"), 2, S, PlantState(t=(S,), values={"y2": (0.5,)}))
    s.feed(keys.meas("temperature"), 3, S, Sample(value=2.0, t_sampled=S))
    with pytest.raises(DataError) as exc:
        s.table()
    assert (exc.value.column, exc.value.row) == ("reactor.y2", 1)
    assert "column 'reactor.y2', row 1 (sampled at t = 0): missing value" in str(exc.value)

    s = RunSeries(run_shape(scenario), "temperature", ["temperature.sp", "reactor.y2"])
    _feed_run(s, 30)
    table, _ = s.table(min_rows=30)  # the set point may be constant
    assert np.ptp(table["temperature.sp"]) == 0.0
    with pytest.raises(DataError) as exc:
        s.table(min_rows=31)
    assert exc.value.row == 30 and "30 samples in the window; the model needs at least 31" in str(
        exc.value
    )
    s = RunSeries(run_shape(scenario), "temperature", ["reactor.z1"])
    _feed_run(s, 30)
    with pytest.raises(DataError) as exc:
        s.table()
    assert exc.value.column == "reactor.z1" and "is constant (0 in all 30 rows" in str(exc.value)


def test_assess_series_uses_the_control_error(scenario):
    s = RunSeries(run_shape(scenario), "temperature", ["temperature.sp", "reactor.y2"])
    _feed_run(s, 400, sp_at={5 * 200 + 1: 3.0})
    result, info = assess_series(s, 4, [], setpoint=True)
    table, _ = s.table()
    e = table["temperature.sp"] - table["temperature"]
    assert result.n_samples == info.n == 400 and result.variance == pytest.approx(np.var(e))


# ---------------------------------------------------------------------------------------------
# The monitor node's configuration
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "monitor, message",
    [
        ({"window": 100}, "window: 100 samples, fewer than the 335 the analysis needs"),
        (
            {
                "secondaries": [
                    {"name": "reactor.y2", "d1": 3, "d2": 1},
                    {"name": "reactor.y3", "d1": 3, "d2": 2},
                ]
            },
            "secondaries[1]: d1 + d2 = 3 + 2 = 5, but secondaries[0] gives 4",
        ),
        ({"delay": 5}, "secondaries[0]: d1 + d2 = 3 + 1 = 4, but delay gives 5"),
        ({"secondaries": []}, "delay: needed when there are no secondaries"),
        ({"secondaries": [{"name": "temperature", "d1": 3, "d2": 1}]}, "the primary itself"),
        ({"period": 0}, "period: Input should be greater than 0"),
    ],
)
def test_node_config_refused_naming_the_field(data, monitor, message):
    with pytest.raises(ConfigError) as exc:
        parse_scenario(_variant(data, **monitor), source="x.yaml")
    assert "x.yaml: nodes.monitor." in str(exc.value) and message in str(exc.value)


@pytest.mark.parametrize(
    "monitor, message",
    [
        ({"loop": "level"}, "nodes.monitor.loop: unknown loop 'level' (loops: ['temperature'])"),
        (
            {"secondaries": [{"name": "reactor.T_j", "d1": 3, "d2": 1}]},
            "nodes.monitor.secondaries[0].name: 'reactor.T_j' is not a column of this run",
        ),
        ({"start": 3000.0}, "nodes.monitor.start: 3000.0 is not before end_time 3000.0"),
    ],
)
def test_node_config_checked_against_the_scenario(data, monitor, message):
    """Names are checked when the scenario loads, before anything starts."""
    with pytest.raises(ConfigError) as exc:
        parse_scenario(_variant(data, **monitor), source="x.yaml")
    assert f"x.yaml: {message}" in str(exc.value)


def test_shipped_scenario_passes_its_checks(scenario):
    cfg = scenario.nodes["monitor"]
    cfg.check(run_shape(scenario), "monitor")
    assert cfg.d == 4 and cfg.columns() == ["temperature.sp", "reactor.y2", "reactor.y3"]


# ---------------------------------------------------------------------------------------------
# Bus contract
# ---------------------------------------------------------------------------------------------
BODY = MonitorAssessment(
    loop="temperature",
    status="ok",
    final=True,
    until=3000 * S,
    n_samples=2000,
    t_first=1000 * S,
    t_last=2999 * S,
    delay=4,
    variance=0.018,
    harris=MonitorHarris(
        status="ok", index=0.11, std=0.01, ci=(0.09, 0.13), confidence=0.95, order=9
    ),
    candidates=(
        MonitorCandidate(
            name="reactor.y2",
            d1=3,
            d2=1,
            status="ok",
            components={"1a": 0.001, "1b": 0.0002, "2a": 0.004, "2b": 0.012},
            band=(0.003, 0.005),
            point=0.003,
            minimum=0.001,
            reduction=0.8,
            order=8,
        ),
        MonitorCandidate(
            name="reactor.y3", d1=3, d2=1, status="unidentifiable", reason="collinear", detail="x"
        ),
    ),
    ranking=("reactor.y2",),
    cascade=True,
    secondary="reactor.y2",
    text="cascade with 'reactor.y2'",
)


def test_assessment_round_trip_and_key():
    raw = codec.encode(run="r1", src="monitor", seq=0, round=3, t=5, body=BODY)
    assert codec.decode(raw, MonitorAssessment).body == BODY
    rel = keys.monitor_assessment("temperature")
    assert rel == "monitor/assessment/temperature"
    assert str(zenoh.KeyExpr(keys.full("r1a2", rel))) == keys.full("r1a2", rel)
    with pytest.raises(ValueError):
        keys.monitor_assessment("a/b")


@pytest.mark.parametrize(
    "change",
    [
        {"status": "great"},
        {"delay": 0},
        {"until": 1.5},
        {"extra": 1},
        {"candidates": [{"name": "x", "d1": 0, "d2": 0, "status": "ok"}]},
        {"harris": {"status": "ok", "order": 0}},
    ],
)
def test_assessment_rejected_input(change):
    body = BODY.model_dump() | change
    raw = codec.encode(run="r1", src="monitor", seq=0, round=3, t=5, body=BODY)
    env = codec.decode_envelope(raw)
    env = env.model_copy(update={"body": body})
    with pytest.raises(SchemaError):
        codec.decode_body(env, MonitorAssessment)
