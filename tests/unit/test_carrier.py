"""Loop paths over a wired network and over a WSN gateway (gateway/carrier.py)."""

from __future__ import annotations

import numpy as np
import pytest

from core.errors import ConfigError
from core.record import summarize
from core.time import to_ticks
from gateway.carrier import ACTUATOR, SENSOR, PathCarrier, initial_hops
from runtime.direct import simulate
from scenario import load_scenario
from scenario.views import carrier_spec, path_hops
from tests.conftest import BENCHMARK, SCENARIOS, write_variant

WSN = SCENARIOS / "jcstr_wsn.yaml"


def test_wired_paths_are_constant():
    s = load_scenario(BENCHMARK).with_loops(tau_d={"level": 0.17})
    c = PathCarrier.from_spec(carrier_spec(s, "network"))
    assert c.deliver("level", SENSOR, 1000) == 1000 + to_ticks(0.17)
    assert c.deliver("level", ACTUATOR, 1000) == 1000
    assert path_hops(s) == {"level": 0, "temperature": 0}


def test_wsn_paths_have_the_scenarios_mean_delays():
    s = load_scenario(WSN)
    assert path_hops(s) == {"level": 3, "temperature": 2}
    c = PathCarrier.from_spec(carrier_spec(s, "network"))
    for loop, mean in (("level", 0.17), ("temperature", 0.10)):
        assert c.routes[loop, SENSOR].mean_delay == pytest.approx(mean, rel=1e-4)
        delays = [c.deliver(loop, SENSOR, 0) for _ in range(4000)]
        got = np.mean([d for d in delays if d is not None]) / 1e6
        assert got == pytest.approx(mean, rel=0.03)  # 4000 draws: well inside 3 %
    assert c.deliver("level", ACTUATOR, 500) == 500  # actuator paths wired


def test_each_path_draws_from_its_own_seeded_generator():
    s = load_scenario(WSN)
    a, b = (
        PathCarrier.from_spec(carrier_spec(s, "network")),
        PathCarrier.from_spec(carrier_spec(s, "network")),
    )
    seq_a = [a.deliver("level", SENSOR, 0) for _ in range(50)]
    for _ in range(7):  # drawing on another path does not change this path's draws
        b.deliver("temperature", SENSOR, 0)
    assert [b.deliver("level", SENSOR, 0) for _ in range(50)] == seq_a
    other_seed = PathCarrier.from_spec(carrier_spec(s.model_copy(update={"seed": 1}), "network"))
    assert [other_seed.deliver("level", SENSOR, 0) for _ in range(50)] != seq_a


def test_a_path_without_route_loses_everything(tmp_path):
    def cut(d):
        topo = d["nodes"]["network"]["topology"]
        topo["links"] = [ln for ln in topo["links"] if "s_level" not in (ln["a"], ln["b"])]
        topo["links"].append({"a": "s_level", "b": "r1", "prr": 0.98})
        d["nodes"]["network"]["events"] = []
        topo["links"] = [ln for ln in topo["links"] if {ln["a"], ln["b"]} != {"r1", "r2"}]

    s = load_scenario(write_variant(tmp_path, WSN, "cut.yaml", cut))
    assert path_hops(s)["level"] == -1
    summary = summarize(simulate(s))
    level = summary["network"]["paths"]["level"]
    assert level["lost"] == level["sent"] > 0
    assert summary["loops"]["level"]["trace"]["t"] == []
    assert summary["messages"]["lost"] == level["lost"]


def test_gateway_loops_are_validated(tmp_path):
    bad = write_variant(
        tmp_path, WSN, "bad.yaml", lambda d: d["loops"]["level"].update(sensor_node="s_nowhere")
    )
    with pytest.raises(ConfigError, match="loops.level.sensor_node: 's_nowhere'"):
        load_scenario(bad)
    bad = write_variant(tmp_path, WSN, "bad2.yaml", lambda d: d["loops"]["level"].update(tau_d=0.1))
    with pytest.raises(ConfigError, match="loops.level.tau_d: a gateway's paths"):
        load_scenario(bad)


def test_a_scheduled_relay_failure_reroutes_with_more_hops_and_longer_delays():
    s = load_scenario(WSN)
    summary = summarize(simulate(s))
    configs = summary["network"]["configurations"]
    assert [c["event"] for c in configs] == ["initial", "node_down"]
    assert (
        configs[0]["paths"]["level.sensor"]["hops"] == 3
        and configs[1]["paths"]["level.sensor"]["hops"] == 4
    )
    assert configs[1]["paths"]["temperature.sensor"]["hops"] == 2  # not through r1: unchanged
    assert summary["events"] == [{"t": 3.0, "kind": "node_down", "source": "scenario"}]
    tr = summary["loops"]["level"]["trace"]
    rec = simulate(s).loops["level"]
    delays = np.array([(d - k) / 1e6 for d, k in zip(rec.t, rec.t_sampled, strict=True)])
    sampled = np.array(rec.t_sampled) / 1e6
    before, after = delays[sampled < 3.0].mean(), delays[sampled >= 3.0].mean()
    assert len(tr["t"]) == len(rec.t)
    # exact route means 0.17 and 0.23 pu; 30 samples each: within 20 %
    assert before == pytest.approx(0.17, rel=0.2) and after == pytest.approx(0.23, rel=0.2)
    assert after > before


def test_scheduled_events_are_validated(tmp_path):
    bad = write_variant(
        tmp_path,
        WSN,
        "bad_event.yaml",
        lambda d: d["nodes"]["network"]["events"].append(
            {"t": 1.0, "event": {"type": "node_down", "node": "r9"}}
        ),
    )
    with pytest.raises(ConfigError, match=r"nodes.network.gateway: events\[1\].event: .*r9"):
        load_scenario(bad)


def test_configurations_carry_the_three_delay_estimates_and_energy():
    s = load_scenario(WSN)
    summary = summarize(simulate(s))
    first, second = summary["network"]["configurations"]
    level0 = first["paths"]["level.sensor"]
    assert level0["route"] == ["s_level", "r1", "r2", "gw"]
    est = level0["estimates"]
    assert est["timestamps"] is None  # nothing delivered yet at t = 0
    assert est["hops"] == pytest.approx(0.17, rel=1e-4)  # hops x mean per-hop delay
    assert est["ping"] == pytest.approx(0.17, rel=0.35)  # 10 probes of a random delay
    # after the reroute: time stamps measured on the old route, the others on the new one
    level1 = second["paths"]["level.sensor"]
    assert level1["estimates"]["timestamps"] == pytest.approx(0.17, rel=0.2)
    assert level1["estimates"]["hops"] == pytest.approx(0.23, rel=1e-4)
    nodes = summary["network"]["nodes"]
    assert set(nodes) == {"s_level", "s_temp", "r1", "r2", "r4", "r5", "gw"}
    assert nodes["gw"]["lifetime_h"] is None  # mains powered
    # r2 forwards both sensors: it spends the most
    battery = {n: v["energy_mAh"] for n, v in nodes.items() if n != "gw"}
    assert max(battery, key=battery.get) == "r2"
    for name in battery:
        assert 0.0 < nodes[name]["energy_mAh"] and nodes[name]["battery_pct"] < 100.0


@pytest.mark.parametrize(
    ("scenario", "network", "hops"),
    [
        # seed 000's demo: the gateway's first proposal routes level over 3 hops and
        # temperature over 2 (README, docs/seeds/000-wncsca.md)
        ("jcstr_wncs.yaml", "network", {"level": 3, "temperature": 2}),
        ("jcstr_benchmark.yaml", "network", {"level": 0, "temperature": 0}),  # wired
    ],
)
def test_the_hops_a_record_names_are_the_routes_first_proposed(scenario, network, hops):
    """``initial_hops`` reads the routes alone (no MAC, energy or generators)."""
    assert initial_hops(carrier_spec(load_scenario(SCENARIOS / scenario), network)) == hops
