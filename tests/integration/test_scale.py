"""Scale scenarios (issue 20, item 4): ``wncs scale`` writes N independent loops over WSN paths
that load, start at rest, step as announced, and run with equal traces on every engine."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cli.main import main
from core.record import summarize
from runtime.direct import simulate
from runtime.history import load_record
from runtime.launcher import launch
from runtime.scale import scale_scenario, write_scale
from scenario import GatewayNodeConfig, load_scenario
from tests.integration.test_engines_agree import _BUS_ONLY, _without_wall_clock


@pytest.mark.parametrize(("plant", "n", "per_gateway"), [("tank", 23, 10), ("jcstr", 8, 4)])
def test_the_generated_scenario_loads_with_n_independent_loops(tmp_path, plant, n, per_gateway):
    path = tmp_path / "scale.yaml"
    write_scale(n, path, plant=plant, per_gateway=per_gateway)
    sc = load_scenario(path)  # as wncs run reads it
    assert len(sc.loops) == n
    plants = {lp.plant for lp in sc.loops.values()}
    assert len(plants) == (n if plant == "tank" else n // 2)  # each loop (pair) its own plant
    assert len({lp.controller for lp in sc.loops.values()}) == n  # each loop its own controller
    gateways = sc.gateways()
    assert len(gateways) == math.ceil(n / per_gateway)
    for name, lp in sc.loops.items():
        assert sc.is_wireless(lp.network), name  # every sensor path over a WSN
        gw = sc.nodes[lp.network]
        assert isinstance(gw, GatewayNodeConfig)
        topo = gw.topology
        hops = [lk for lk in topo.links if lp.sensor_node in (lk.a, lk.b)]
        assert len(hops) == 1, name  # the sensor's one link, to its relay
        relay = hops[0].b if hops[0].a == lp.sensor_node else hops[0].a
        assert topo.nodes[relay].kind == "relay"
        assert any({lk.a, lk.b} == {relay, "gw"} for lk in topo.links)  # two hops in all
    steps = {}
    for change in sc.setpoints:
        steps.setdefault(change.loop, []).append(change)
    assert set(steps) == set(sc.loops)  # every loop steps
    times = {s[0].t for s in steps.values()}
    assert len(times) > 1  # staggered, not in lock-step


def test_the_tanks_start_at_rest():
    """Tank i starts at its set point with the input that holds it (dh/dt = b u - a' sqrt(h),
    seed 002 eq. (22)), and steps 20 mm up and back."""
    data = scale_scenario(7)
    for i in range(7):
        plant = data["nodes"][f"tank{i:03d}"]
        h, u = plant["x0"]["h"], plant["u0"]["u"]
        b, a = plant["params"]["b"], plant["params"]["a_prime"]
        assert h == 60.0 + 10.0 * (i % 5)
        assert b * u - a * np.sqrt(h) == pytest.approx(0.0, abs=1e-12)
        assert data["loops"][f"level{i:03d}"]["setpoint"] == h
        mine = [s["value"] for s in data["setpoints"] if s["loop"] == f"level{i:03d}"]
        assert mine == [h + 20.0, h]


def test_bad_requests_are_refused_naming_the_argument(tmp_path, capsys):
    assert main(["scale", "3", "--plant", "jcstr", "--out", str(tmp_path / "x.yaml")]) == 2
    assert "even number" in capsys.readouterr().err
    assert main(["scale", "0", "--out", str(tmp_path / "x.yaml")]) == 2
    assert not (tmp_path / "x.yaml").exists()
    assert main(["scale", "4", "--out", str(tmp_path / "ok.yaml")]) == 0
    assert "4 loops" in capsys.readouterr().out
    assert len(load_scenario(tmp_path / "ok.yaml").loops) == 4


@pytest.mark.slow
def test_three_loops_give_the_same_run_on_the_direct_and_threads_engines(tmp_path):
    path = tmp_path / "scale3.yaml"
    write_scale(3, path, end_time=20.0)
    runs = {}
    for engine in ("direct", "threads"):
        res = launch(path, tmp_path / engine, engine=engine)
        assert res.code == 0, res.error
        runs[engine] = {
            k: v for k, v in _without_wall_clock(res.summary).items() if k not in _BUS_ONLY
        }
    direct, threads = runs["direct"], runs["threads"]
    assert set(direct["loops"]) == {"level000", "level001", "level002"}
    for name, loop in direct["loops"].items():
        assert loop["overshoot_pct"] is not None, name  # each loop stepped and was judged
    assert direct["loops"] == threads["loops"]  # traces, overshoots, settling times, IAE
    assert direct == threads


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["threads", "processes"])
def test_coupled_loops_give_the_direct_engines_run_on_the_bus_engines(tmp_path, engine):
    """A train of four coupled tanks (``--plant tank_train``): the bus engine gives the direct
    engine's summary (traces, metrics, network) and true states, bit for bit."""
    path = tmp_path / "train4.yaml"
    scenario = write_scale(4, path, plant="tank_train", per_gateway=2, end_time=20.0)
    direct = simulate(scenario)
    expected = _without_wall_clock(summarize(direct))
    assert len(expected["loops"]) == 4
    for name, loop in expected["loops"].items():
        assert loop["overshoot_pct"] is not None, name  # each loop stepped and was judged
    out = tmp_path / engine
    res = launch(path, out, engine=engine)
    assert res.code == 0, res.error
    got = {k: v for k, v in _without_wall_clock(res.summary).items() if k not in _BUS_ONLY}
    assert got["loops"] == expected["loops"]  # traces, overshoots, settling times, IAE
    assert got == expected
    states = load_record(out / "history.sqlite", scenario, engine=engine).plants["train"]
    assert states.t == direct.plants["train"].t
    assert states.x == direct.plants["train"].x  # every level, bit for bit
