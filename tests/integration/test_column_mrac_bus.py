"""Seed 003's MRAC over the bus (threads engine, a real zenoh router): one controller node for two
loops, through the generic plant, network and controller nodes, equals the direct engine."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.mrac import replay
from core.record import summarize
from core.time import to_units
from runtime.direct import simulate
from runtime.executions import multi_loop_executions
from runtime.history import load_record
from runtime.launcher import launch
from scenario import load_scenario
from tests.conftest import SCENARIOS, write_variant

THESIS = SCENARIOS / "column_mrac.yaml"
NONLINEAR = SCENARIOS / "column_mrac_nonlinear.yaml"
WSN = SCENARIOS / "column_mrac_wsn.yaml"


def assert_traces_equal(bus: dict, direct: dict, atol: float = 1e-9) -> None:
    """Same samples at the same instants, same moves (None where no move was made), values
    within ``atol`` (the acceptance; they are in fact identical)."""
    assert bus["loops"].keys() == direct["loops"].keys()
    for name, loop in direct["loops"].items():
        a, b = bus["loops"][name]["trace"], loop["trace"]
        assert a["t"] == b["t"], name
        assert [u is None for u in a["u"]] == [u is None for u in b["u"]], name
        for k in ("y", "u"):
            x = np.array([np.nan if v is None else v for v in a[k]])
            y = np.array([np.nan if v is None else v for v in b[k]])
            assert np.nanmax(np.abs(x - y), initial=0.0) <= atol, (name, k)
        assert len(b["t"]) > 10


def _shorter(end_time: float):
    def edit(d):
        d["end_time"] = end_time

    return edit


@pytest.mark.parametrize(
    ("base", "edit"),
    [
        (THESIS, None),  # the whole thesis test, 20 h
        (NONLINEAR, _shorter(21.0)),  # through the second reference step (20 h)
        (WSN, _shorter(21.0)),  # samples apart, losses
    ],
    ids=["thesis", "nonlinear", "wsn"],
)
def test_column_mrac_over_the_bus_equals_direct(tmp_path, base, edit):
    path = base if edit is None else write_variant(tmp_path, base, base.name, edit)
    res = launch(path, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    scenario = load_scenario(path)
    rec = simulate(scenario)
    direct = summarize(rec)
    assert_traces_equal(res.summary, direct)
    assert res.summary["network"]["paths"] == direct["network"]["paths"]
    # the law's own signals (x_m, e, theta: not on the bus) replay identically from either record
    bus_rec = load_record(tmp_path / "run" / "history.sqlite", scenario, engine="threads")
    loops = scenario.nodes["mrac"].loops
    law = scenario.nodes["mrac"].law
    replays = [
        replay(
            law,
            loops,
            [(to_units(e.t), e.y, e.r) for e in multi_loop_executions(scenario, r, "mrac")],
        )
        for r in (bus_rec, rec)
    ]
    for key in ("x_m", "e", "theta", "u"):
        np.testing.assert_array_equal(replays[0][key], replays[1][key])
    if base == WSN:
        assert res.summary["network"]["paths"]["bottom"]["lost"] > 0


def test_delayed_and_zero_delay_samples_over_the_bus(tmp_path):
    """The round structure the direct engine mirrors: x2's sample delayed by one period, x1's
    not, so the controller executes twice at every instant (two rounds), and a delayed actuator
    path on x1: the bus gives the same traces as the direct engine."""

    def mixed(d):
        d["end_time"] = 4.0
        d["loops"]["x2"]["tau_d"] = 0.1
        d["loops"]["x1"]["tau_a"] = 0.05
        d["setpoints"] = [{"t": 2.0, "loop": "x1", "value": -0.5}]

    path = write_variant(tmp_path, THESIS, "mixed.yaml", mixed)
    res = launch(path, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    scenario = load_scenario(path)
    rec = simulate(scenario)
    assert_traces_equal(res.summary, summarize(rec))
    execs = multi_loop_executions(scenario, rec, "mrac")
    assert len(execs) == 2 * 40  # from 0.1 h: two per instant, 0.1 ... 4.0 h
    plant = res.summary["loops"]["x1"]
    assert plant["trace"]["u"][0] is None  # x1 alone at t = 0: no move yet
