"""``wncs inject`` of operations into a running run (threads engine, real bus, real time): an
operating mode and a set point reach the coordination agent through the clock, which stamps them
into its next round, and the agent acts on them; bad requests are refused before anything is
sent."""

from __future__ import annotations

import json

import pytest

from bus_schemas import keys
from core.errors import ConfigError
from kernel.bus import open_client
from kernel.security import SECURITY_DIR
from runtime.inject import build_request, send
from runtime.security import DASHBOARD, INJECT, credentials_of
from tests.conftest import SCENARIOS, last_tick, launch_aside, wait_until, write_variant

pytestmark = pytest.mark.slow


def _scenario(tmp_path):
    def edit(d: dict) -> None:
        d["end_time"] = 12.0
        d["modes"] = []
        d["setpoints"] = [s for s in d["setpoints"] if s["t"] < 3.0]
        d["nodes"]["network"]["events"] = []

    return write_variant(tmp_path, SCENARIOS / "jcstr_wncs.yaml", "ops.yaml", edit)


def test_mode_and_setpoint_injected_into_a_running_run(tmp_path):
    out = tmp_path / "run"
    scenario = _scenario(tmp_path)
    runner, result = launch_aside(scenario, out, engine="threads", realtime=0.5)
    info = json.loads((out / "run.json").read_text())
    security = out / SECURITY_DIR
    session = open_client(info["endpoint"], settings=credentials_of(security, DASHBOARD))
    creds = credentials_of(security, INJECT)
    now = [0]
    sub = session.declare_subscriber(
        keys.full(info["run_id"], keys.tick_log()),
        lambda s: now.__setitem__(0, getattr(last_tick(s), "t", now[0])),
    )
    try:
        wait_until(lambda: now[0] >= 5_000_000, timeout=60, what="virtual time 5 pu")
        send(
            info["endpoint"],
            info["run_id"],
            build_request("mode", ["steady_state"], run_dir=out, network=None),
            settings=creds,
        )
        wait_until(lambda: now[0] >= 8_000_000, timeout=60, what="virtual time 8 pu")
        request = build_request("setpoint", ["level=0.72"], run_dir=out, network=None)
        send(info["endpoint"], info["run_id"], request, settings=creds)
        runner.join(120)
    finally:
        sub.undeclare()
        session.close()
    res = result["r"]
    assert res.code == 0, res.error
    w = res.summary["wncsca"]
    [mode] = [d for d in w["decisions"] if d["subject"] == "mode"]
    assert mode["verdict"] == "accept" and mode["reasons"][0].endswith("-> steady_state")
    assert 5.0 <= mode["t"] < 8.0
    sp = [d for d in w["decisions"] if d["subject"] == "setpoint" and d["t"] >= 8.0]
    assert len(sp) == 1 and sp[0]["verdict"] == "accept" and "level -> 0.72" in sp[0]["reasons"][0]
    modes = [a["mode"] for a in w["assignments"]]
    assert modes[-2:] == ["steady_state", "setpoint_change"]
    steps = res.summary["loops"]["level"]["steps"]
    assert [(s["from"], s["to"]) for s in steps] == [(0.7, 0.75), (0.75, 0.72)]
    assert steps[1]["t"] == sp[0]["t"]


def test_bad_ops_requests_are_refused_before_anything_is_sent(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "scenario.yaml").write_text(_scenario(tmp_path).read_text())
    for kind, words, fragment in (
        ("mode", ["party"], "unknown mode 'party'"),
        ("mode", [], "usage"),
        ("setpoint", ["flow=1.0"], "unknown loop 'flow'"),
        ("setpoint", ["level=high"], "not a finite number"),
        ("setpoint", ["level=0.7", "temperature=50"], "usage"),
    ):
        with pytest.raises(ConfigError, match=fragment):
            build_request(kind, words, run_dir=out, network=None)
    benchmark = tmp_path / "bench"
    benchmark.mkdir()
    (benchmark / "scenario.yaml").write_text((SCENARIOS / "jcstr_benchmark.yaml").read_text())
    with pytest.raises(ConfigError, match="no coordination agent"):
        build_request("mode", ["steady_state"], run_dir=benchmark, network=None)
