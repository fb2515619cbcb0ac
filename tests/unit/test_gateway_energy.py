"""Node energy: counted charge against hand computation, relays paying for forwarding, lifetime."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from core.time import to_ticks
from gateway.energy import EnergyConfig, EnergyMeter, projected_lifetime, traffic_per_second
from gateway.paths import deliver
from gateway.topology import NodeDown, Topology, TopologyConfig

# Round numbers for hand computation: a 125-byte frame (119 + 6) at 1 Mb/s is 1 ms on air, a
# 25-byte acknowledgement 0.2 ms, and the sender listens 0.3 ms before it.
SIMPLE = EnergyConfig(
    i_tx_mA=20.0,
    i_rx_mA=10.0,
    i_sleep_mA=0.0,
    listen_duty_cycle=0.1,
    bitrate_bps=1_000_000.0,
    frame_bytes=119,
    ack_bytes=19,
    phy_bytes=6,
    listen_s=0.3e-3,
    battery_mAh=1.0,
    seconds_per_unit=2.0,
)
MAS = 1.0 / 3600.0  # one mA s in mAh
Q_TX = (20.0 * 1.0e-3 + 10.0 * (0.3e-3 + 0.2e-3)) * MAS  # 25 mA ms per attempt
Q_RX = 10.0 * 1.0e-3 * MAS  # 10 mA ms per attempt
Q_ACK = 20.0 * 0.2e-3 * MAS  # 4 mA ms per successful attempt
I_IDLE = 0.1 * 10.0  # mA


def line(prr: float = 1.0, retry_limit: int = 3) -> Topology:
    return Topology(
        TopologyConfig(
            nodes={"s": {"kind": "sensor"}, "r": {"kind": "relay"}, "g": {"kind": "gateway"}},
            links=[{"a": "s", "b": "r", "prr": prr}, {"a": "r", "b": "g", "prr": prr}],
            paths={"y": {"src": "s", "dst": "g"}},
            retry_limit=retry_limit,
        )
    )


def run(topology: Topology, tau_s: float, t_end: float, config=SIMPLE, seed=0) -> EnergyMeter:
    """Sample every ``tau_s`` over ``[0, t_end)`` and carry every sample to the gateway."""
    meter = EnergyMeter(config, topology)
    route = topology.routes()["y"]
    rng = np.random.default_rng(seed)
    n = round(t_end / tau_s)
    for k in range(n):
        meter.record(route, deliver(route, to_ticks(k * tau_s), rng))
    meter.advance(to_ticks(t_end))
    return meter


def test_charge_constants_from_the_config():
    assert SIMPLE.q_tx_mAh == pytest.approx(Q_TX)
    assert SIMPLE.q_rx_mAh == pytest.approx(Q_RX)
    assert SIMPLE.q_ack_mAh == pytest.approx(Q_ACK)
    assert SIMPLE.i_idle_mA == pytest.approx(I_IDLE)
    # TelosB / Tmote Sky defaults: 56 bytes at 250 kb/s = 1.792 ms, ACK 11 bytes = 0.352 ms
    d = EnergyConfig()
    assert d.q_tx_mAh == pytest.approx((19.5 * 1.792e-3 + 21.8 * (0.32e-3 + 0.352e-3)) / 3600)
    assert d.q_rx_mAh == pytest.approx(21.8 * 1.792e-3 / 3600)
    assert d.q_ack_mAh == pytest.approx(19.5 * 0.352e-3 / 3600)
    assert d.i_idle_mA == pytest.approx(0.01 * 21.8 + 0.99 * 0.0051)


def test_counted_charge_on_a_line_equals_hand_computation():
    # tau_s = 0.5 units = 1 s; 100 units = 200 s: 200 packets, PRR 1 (one attempt per hop)
    meter = run(line(), tau_s=0.5, t_end=100.0)
    idle = I_IDLE * 200.0 * MAS
    s, r, g = meter.charge("s"), meter.charge("r"), meter.charge("g")
    assert (s.tx_attempts, s.rx_attempts, r.tx_attempts, r.rx_attempts, g.rx_attempts) == (
        200,
        0,
        200,
        200,
        200,
    )
    assert s.tx_mAh == pytest.approx(200 * Q_TX) and s.rx_mAh == 0.0
    assert r.tx_mAh == pytest.approx(200 * Q_TX)  # the relay pays for forwarding ...
    assert r.rx_mAh == pytest.approx(200 * (Q_RX + Q_ACK))  # ... and for receiving
    assert g.rx_mAh == pytest.approx(200 * (Q_RX + Q_ACK)) and g.tx_mAh == 0.0
    for c in (s, r, g):
        assert c.idle_mAh == pytest.approx(idle)
    assert s.total_mAh == pytest.approx(200 * 25e-3 * MAS + 200 * MAS)
    # battery: 1 mAh capacity; the gateway is mains powered
    assert meter.battery_pct("s") == pytest.approx(100.0 * (1.0 - s.total_mAh))
    assert meter.battery_pct("g") == 100.0


def test_halving_the_sampling_rate_halves_transmit_charge():
    fast = run(line(), tau_s=0.5, t_end=100.0)
    slow = run(line(), tau_s=1.0, t_end=100.0)
    for node in ("s", "r"):
        assert slow.charge(node).tx_mAh == pytest.approx(fast.charge(node).tx_mAh / 2)
    assert slow.charge("r").rx_mAh == pytest.approx(fast.charge("r").rx_mAh / 2)
    assert slow.charge("s").idle_mAh == pytest.approx(fast.charge("s").idle_mAh)


def test_analytic_rates_and_lifetime_match_hand_computation():
    t = line()
    routes = t.routes()
    for tau_s, pkts_per_s in ((0.5, 1.0), (1.0, 0.5)):
        rates = traffic_per_second(routes, {"y": tau_s}, SIMPLE.seconds_per_unit)
        assert rates == {
            "s": pytest.approx((pkts_per_s, 0.0, 0.0)),
            "r": pytest.approx((pkts_per_s, pkts_per_s, pkts_per_s)),
            "g": pytest.approx((0.0, pkts_per_s, pkts_per_s)),
        }
        e = projected_lifetime(t, routes, {"y": tau_s}, SIMPLE)
        assert e["s"].tx_mA == pytest.approx(pkts_per_s * 25e-3)  # 25 mA ms per packet
        assert e["r"].tx_mA == pytest.approx(pkts_per_s * 25e-3)
        assert e["r"].rx_mA == pytest.approx(pkts_per_s * 14e-3)
        assert e["s"].current_mA == pytest.approx(pkts_per_s * 25e-3 + 1.0)
        assert e["s"].lifetime_s == pytest.approx(1.0 / (pkts_per_s * 25e-3 + 1.0) * 3600)
        assert math.isinf(e["g"].lifetime_s)


def test_counted_and_analytic_agree():
    t = line()
    meter = run(t, tau_s=0.5, t_end=100.0)
    e = projected_lifetime(t, t.routes(), {"y": 0.5}, SIMPLE, meter)
    for node in ("s", "r"):
        assert meter.charge(node).total_mAh == pytest.approx(e[node].current_mA * 200.0 * MAS)
        assert e[node].remaining_mAh == pytest.approx(meter.remaining_mAh(node))


def test_lossy_line_counts_retries_as_expected():
    prr, r, n = 0.7, 2, 20_000
    t = line(prr, r)
    route = t.routes()["y"]
    meter = EnergyMeter(SIMPLE, t)
    rng = np.random.default_rng(3)
    for _ in range(n):
        meter.record(route, deliver(route, 0, rng))
    # exact expectation, by enumeration of the truncated geometric number of attempts
    q = 1.0 - prr
    pk = np.array([prr * q**k for k in range(r + 1)])  # first success at attempt k + 1
    ok = pk.sum()
    a = np.arange(1, r + 2)
    mean_a = (a * pk).sum() + (r + 1) * (1 - ok)
    var_a = (a**2 * pk).sum() + (r + 1) ** 2 * (1 - ok) - mean_a**2
    tol = 5.0 * math.sqrt(n * var_a)
    assert abs(meter.charge("s").tx_attempts - n * mean_a) < tol
    assert abs(meter.charge("r").rx_attempts - n * mean_a) < tol
    assert abs(meter.charge("r").tx_attempts - n * ok * mean_a) < tol + 5 * math.sqrt(n)
    assert abs(meter.charge("g").acks - n * ok * ok) < 5 * math.sqrt(n)
    # analytic rates per packet: (tx attempts, rx attempts, acks)
    rates = traffic_per_second({"y": route}, {"y": 1.0})
    assert rates["s"] == pytest.approx((mean_a, 0, 0))
    assert rates["r"] == pytest.approx((ok * mean_a, mean_a, ok))
    assert rates["g"] == pytest.approx((0, ok * mean_a, ok * ok))
    assert meter.charge("r").acks <= n and meter.charge("g").acks <= meter.charge("r").acks


def test_down_node_does_not_listen_and_depleted_nodes_reported():
    t = line()
    cfg = SIMPLE.model_copy(update={"batteries": {"r": 0.1}})
    meter = EnergyMeter(cfg, t)
    meter.advance(to_ticks(50.0))  # 100 s at 1 mA = 0.0278 mAh
    t.apply(NodeDown(node="r"))
    meter.advance(to_ticks(200.0))
    assert meter.charge("r").idle_mAh == pytest.approx(100.0 * MAS)
    assert meter.charge("s").idle_mAh == pytest.approx(400.0 * MAS)
    assert meter.depleted() == []
    meter.advance(to_ticks(2000.0))  # s: 4000 s at 1 mA > 1 mAh
    assert meter.depleted() == ["s"] and meter.battery_pct("s") == 0.0
    assert meter.battery_pct("r") == pytest.approx(100.0 * (1 - (100.0 * MAS) / 0.1))
    with pytest.raises(ValueError, match="backwards"):
        meter.advance(0)
    e = projected_lifetime(t, t.routes(), {"y": 1.0}, cfg, meter)
    assert e["r"].current_mA == 0.0 and math.isinf(e["r"].lifetime_s)
    assert e["s"].tx_mA == 0.0  # the path is down: no traffic


def test_bad_energy_config_refused_naming_field():
    with pytest.raises(ValidationError, match="i_tx_mA"):
        EnergyConfig(i_tx_mA=-1.0)
    with pytest.raises(ValidationError, match="listen_duty_cycle"):
        EnergyConfig(listen_duty_cycle=1.5)
    with pytest.raises(ValueError, match=r"periods\.y"):
        traffic_per_second(line().routes(), {"y": 0.0})
