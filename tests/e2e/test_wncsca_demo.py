"""The demo (``scenarios/jcstr_wncs.yaml``) end to end: the coordination agent, the gateway, the
plant, two controllers and the operator as OS processes on a real zenoh router (seed 000, III.E).

Everything is read from ``summary.json`` and checked against the scenario and independent
recomputation, never against wall-clock time.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bus_schemas import keys
from runtime.direct import loop_model
from runtime.history import connect, messages_digest
from scenario import load_scenario
from tests.conftest import SCENARIOS

pytestmark = pytest.mark.slow

WNCS_SCENARIO = SCENARIOS / "jcstr_wncs.yaml"
WNCS = str(Path(sys.executable).parent / "wncs")


def run(out: Path, engine: str) -> dict:
    proc = subprocess.run(
        [WNCS, "run", str(WNCS_SCENARIO), "--out", str(out), "--engine", engine],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert "coordination agent (WNCSCA) timeline" in proc.stdout
    return json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("demo")
    return out, run(out, "processes")


def test_every_step_under_negotiated_periods_is_within_the_limit(demo):
    _, s = demo
    limit = load_scenario(WNCS_SCENARIO).nodes["wncsca"].overshoot_limit
    steps = [(n, st) for n, lp in s["loops"].items() for st in lp["steps"]]
    assert len(steps) == 4
    for name, st in steps:
        assert st["overshoot_pct"] <= limit + 1.0, (name, st)
    # the periods in force at each step were negotiated ones, not the benchmark's
    assignments = s["wncsca"]["assignments"]
    for name, st in steps:
        before = [a for a in assignments if a["t"] <= st["t"]][-1]
        assert before["closed"][name] and before["mode"] == "setpoint_change"
        assert before["periods"][name] > 0.1, (name, before)


def test_the_slow_route_is_rejected_for_the_level_loop_and_the_alternative_accepted(demo):
    _, s = demo
    w = s["wncsca"]
    props = {p["id"]: p for p in w["proposals"]}
    verdicts = {d["proposal"]: d for d in w["decisions"] if d["subject"] == "proposal"}
    assert [verdicts[i]["verdict"] for i in sorted(verdicts)] == ["accept", "reject", "accept"]
    rejected = verdicts[1]
    assert rejected["offending"] == ["level"]
    assert rejected["delays"]["level"] >= rejected["bounds"]["level"]
    assert "level" in rejected["reasons"][0] and "bound" in rejected["reasons"][0]
    assert props[1]["event"] == "node_down" and props[2]["source"] == "alternative"
    assert props[2]["hops"]["level.sensor"] > props[0]["hops"]["level.sensor"]
    assert (
        props[2]["estimates"]["level.sensor"]["hops"]
        < props[1]["estimates"]["level.sensor"]["hops"]
    )
    # renegotiated: a longer level delay needs a shorter level period
    negotiated = [a for a in w["assignments"] if "search" in a]
    assert len(negotiated) == 2
    assert negotiated[1]["control_periods"]["level"] < negotiated[0]["control_periods"]["level"]


def test_negotiated_periods_hold_on_the_model_and_extend_the_network_lifetime(demo):
    _, s = demo
    sc = load_scenario(WNCS_SCENARIO)
    model = loop_model(sc, sc.nodes["wncsca"])
    for a in (a for a in s["wncsca"]["assignments"] if "search" in a):
        ev = model.evaluate(a["control_periods"], a["search"]["delays"])
        assert all(v <= sc.nodes["wncsca"].overshoot_limit for v in ev.overshoot_pct.values())
    for e in s["wncsca"]["energy"]:
        assert e["ratio"] > 1.0
        assert e["lifetime_h_assigned"] > e["lifetime_h_benchmark"]


def test_the_sensors_sample_at_the_assigned_periods(demo):
    out, s = demo
    with connect(out / "history.sqlite") as conn:
        rows = conn.execute(
            "SELECT t FROM messages WHERE key = ? ORDER BY id", (keys.sensor("reactor", "H"),)
        ).fetchall()
    sampled = np.array([t for (t,) in rows]) / 1e6
    gaps = np.diff(sampled)
    assignments = s["wncsca"]["assignments"]
    # every gap is the level period in force when the gap began (or shorter, when a new period
    # cut it: the sensor then samples one new period after its last sample)
    for t0, gap in zip(sampled[:-1], gaps, strict=True):
        in_force = [a for a in assignments if a["t"] <= t0 + 1e-9][-1]["periods"]["level"]
        after = [a["periods"]["level"] for a in assignments if t0 < a["t"] < t0 + gap + 1e-9]
        assert np.isclose(gap, in_force, atol=1e-6) or any(
            np.isclose(gap, p, atol=1e-6) or gap < in_force for p in after
        ), (t0, gap, in_force, after)
    assert np.isclose(gaps, 1.0, atol=1e-6).sum() >= 10  # monitoring while the loops are open
    first = next(a for a in assignments if "search" in a)["periods"]["level"]
    assert np.isclose(gaps, first, atol=1e-6).sum() >= 10  # the negotiated control period
    applied = s["wncsca"]["applied"]
    assert applied and all(a["event"] == "rates" for a in applied)


def test_threads_engine_gives_the_same_run(demo, tmp_path):
    out, s = demo
    t = run(tmp_path, "threads")
    for name in s["loops"]:
        for k in ("t", "y", "u"):
            assert s["loops"][name]["trace"][k] == t["loops"][name]["trace"][k], (name, k)
    assert messages_digest(out / "history.sqlite") == messages_digest(tmp_path / "history.sqlite")
