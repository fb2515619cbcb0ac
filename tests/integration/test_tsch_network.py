"""A TSCH network carrying the demo's loops (issue 15): what the scenario runs shows the
capacity check, the interference re-judged, the battery that runs out, the delays from the
schedule, and the engines agreeing.

Independent computations: the charge per slotframe of a relay is summed from the schedule's
cells and the datasheet's charges per slot type (not from the network's own projection); the
delay of an aligned chain without loss is its cells' span, read from the schedule.
"""

from __future__ import annotations

import pytest

import wncs
from gateway.carrier import PathCarrier
from gateway.tsch.energy import RADIOS
from runtime.launcher import launch
from scenario.views import carrier_spec
from tests.conftest import SCENARIOS, write_variant
from tests.integration.test_engines_agree import _without_wall_clock

TSCH = SCENARIOS / "jcstr_tsch.yaml"


@pytest.fixture(scope="module")
def demo():
    """``jcstr_tsch.yaml`` on the direct engine."""
    return wncs.run(TSCH)


def _decisions(result, subject):
    return [d for d in result.summary["wncsca"]["decisions"] if d["subject"] == subject]


def test_rates_the_manager_cannot_carry_are_refused_naming_the_link(demo):
    """At 10 pu the operator asks for identification rates (0.05 pu): the agent asks the
    manager, which lacks cells on the relay's links; the mode is refused and the loops keep
    their periods."""
    [refused] = [d for d in _decisions(demo, "mode") if d["verdict"] == "refuse"]
    assert refused["t"] == pytest.approx(10.0)
    assert "identification refused" in refused["reasons"][0]
    assert "link r2->gw lacks" in refused["reasons"][0]
    modes = [a["mode"] for a in demo.summary["wncsca"]["assignments"]]
    assert "identification" not in modes


def test_interference_raises_the_delays_and_the_agent_judges_again(demo):
    """At 12 pu six of the 16 channels keep 30 % of their frames for 4 pu: the gateway proposes
    the same routes with the delays its probes now see; the level's is longer, the agent
    accepts it and shortens the level's period to keep its overshoot within the limit."""
    proposals = _decisions(demo, "proposal")
    first = next(d for d in proposals if d["proposal"] == 0)
    burst = next(d for d in proposals if d["proposal"] == 1)
    assert burst["t"] == pytest.approx(12.0)
    assert burst["delays"]["level"] > 2 * first["delays"]["level"]
    assert burst["verdict"] == "accept"
    at = {round(a["t"], 6): a for a in demo.summary["wncsca"]["assignments"] if a.get("method")}
    assert at[12.0]["control_periods"]["level"] < at[0.0]["control_periods"]["level"]
    config = next(c for c in demo.summary["network"]["configurations"] if c["t"] == 12.0)
    assert config["event"] == "interference"


def test_the_schedule_shrinks_when_the_rates_relax():
    carrier = PathCarrier.from_spec(carrier_spec(wncs.load(TSCH), "network"))
    fast = carrier.plan({"level": 0.1, "temperature": 0.1})
    slow = carrier.plan({"level": 1.0, "temperature": 1.0})
    assert fast.feasible and slow.feasible
    total = lambda s: sum(s.cells_per_frame().values())  # noqa: E731
    assert total(slow) < total(fast)
    too_fast = carrier.plan({"level": 0.05, "temperature": 0.05})
    assert not too_fast.feasible and ("r2", "gw") in too_fast.lacking


def _no_agent(data, battery=None):
    del data["nodes"]["wncsca"]
    data.pop("modes", None)
    net = data["nodes"]["network"]
    net["events"] = []
    net["tsch"]["link_model"] = "prr"  # every topology link's prr (1.0) on every channel
    data["end_time"] = 6.0
    data["setpoints"] = [s for s in data["setpoints"] if s["t"] < 6.0]
    if battery is not None:
        net["energy"]["batteries"] = dict([battery])


def _level_alone(data):
    _no_agent(data)
    data["nodes"]["wired"] = {"kind": "network"}
    temperature = data["loops"]["temperature"]
    temperature["network"] = "wired"
    del temperature["sensor_node"]


def test_an_aligned_chain_without_loss_takes_its_cells_span(tmp_path):
    """One path over links of PRR 1, its samples on its chains' first slots: every delivered
    sample's delay, the ping estimate and the predicted distribution are the span of the
    path's cells, from the first cell's start to the last cell's end, read off the schedule."""
    sc = wncs.load(write_variant(tmp_path, TSCH, "alone.yaml", _level_alone))
    carrier = PathCarrier.from_spec(carrier_spec(sc, "network"))
    route = carrier.routes["level", "sensor"].nodes
    cells = [c for c in carrier.tsch.schedule.cells if c.flow == "level.sensor"]
    last = -1
    for a, b in zip(route[:-1], route[1:], strict=True):  # the chain that starts at slot 0
        last = min(c.slot for c in cells if c.link == (a, b) and c.slot > last)
    span = (last + 1) * 0.01  # slots of 0.01 pu
    proposed = carrier.configuration(0)["level.sensor"]
    assert proposed["estimates"]["ping"] == pytest.approx(span, abs=1e-12)
    assert {round(d, 9) for d in proposed["distribution"]["delays"]} == {round(span, 9)}
    df = wncs.run(sc).loops["level"].to_pandas()
    assert len(df) > 50
    assert set((df["t"] - df["t_sampled"]).round(9)) == {round(span, 9)}


def test_the_proposed_delays_are_what_the_samples_then_see(tmp_path):
    """Both loops over the relay r2, PRR 1: their packets queue behind each other on r2's link to
    the gateway; the probes, sent with the other path's traffic, predict exactly the delays the
    run's samples see."""
    sc = wncs.load(write_variant(tmp_path, TSCH, "lossless.yaml", _no_agent))
    proposed = PathCarrier.from_spec(carrier_spec(sc, "network")).configuration(0)
    result = wncs.run(sc)
    for loop in ("level", "temperature"):
        df = result.loops[loop].to_pandas()
        seen = set((df["t"] - df["t_sampled"]).round(9))
        entry = proposed[f"{loop}.sensor"]
        assert seen == {round(entry["estimates"]["ping"], 9)}
        assert {round(d, 9) for d in entry["distribution"]["delays"]} == seen


def test_a_relay_whose_battery_runs_out_goes_down_when_predicted_and_the_run_goes_on(tmp_path):
    """The level's first relay carries only its samples: per slotframe of L slots (10 ms) at
    tau_s = 0.1 pu (10 slots) it receives and forwards L/10 packets in L/5 RX and L/5 TX cells
    (a primary and a retry cell per hop and chain), PRR 1. Its charge per slotframe, from the
    datasheet: L/10 TxDataRxAck + L/10 RxDataTxAck + L/10 idle RX cells + the sleeping slots.
    With a battery of 1.25 slotframes' charge it goes down 1.25 slotframes in."""
    radio = RADIOS["openmote_cc2538"]
    probe = wncs.load(write_variant(tmp_path, TSCH, "probe.yaml", _no_agent))
    length = probe.nodes["network"].tsch.length
    carrier = PathCarrier.from_spec(carrier_spec(probe, "network"))
    relay = carrier.routes["level", "sensor"].nodes[1]
    sched = carrier.tsch.schedule
    rx = sum(1 for c in sched.cells if c.rx == relay)
    tx = sum(1 for c in sched.cells if c.tx == relay)
    packets = length // 10
    assert (rx, tx) == (2 * packets, 2 * packets)
    per_frame = (
        packets * radio.tx_ack_uC
        + packets * radio.rx_ack_uC
        + (rx - packets) * radio.idle_uC
        + (length - rx - packets) * radio.sleep_uA * 0.01
    )
    frames = 1.25
    capacity_mAh = frames * per_frame / 3.6e6
    frame_pu = length * 0.01
    predicted = frames * frame_pu
    path = write_variant(
        tmp_path, TSCH, "battery.yaml", lambda d: _no_agent(d, battery=(relay, capacity_mAh))
    )
    result = wncs.run(path)
    [down] = [
        c for c in result.summary["network"]["configurations"] if c["event"] == "battery_empty"
    ]
    assert down["source"] == "battery"
    assert abs(down["t"] - predicted) <= frame_pu  # within one slotframe
    assert relay not in down["paths"]["level.sensor"]["route"]
    df = result.loops["level"].to_pandas()
    assert (df["t"] > down["t"] + 0.5).sum() > 5  # rerouted: samples keep coming
    assert result.summary["network"]["nodes"][relay]["battery_pct"] == pytest.approx(0.0, abs=2)


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["threads", "processes"])
def test_the_bus_engines_run_the_tsch_demo_as_the_direct_engine(engine, tmp_path):
    direct = launch(TSCH, tmp_path / "direct", engine="direct")
    bus = launch(TSCH, tmp_path / engine, engine=engine)
    assert direct.code == 0 and bus.code == 0, bus.error
    a, b = _without_wall_clock(direct.summary), _without_wall_clock(bus.summary)
    assert b.pop("router") == {"refused": 0, "attempts": []}  # bus only: nobody was refused
    assert a["wncsca"]["decisions"] and a == b


def test_losses_are_counted_by_reason(tmp_path):
    """Links of PRR 0.5 and no retransmission: about half the level's samples are lost on each
    hop, every loss counted as retries exhausted, and the counts add up to the path's losses."""

    def lossy(data):
        _no_agent(data)
        net = data["nodes"]["network"]
        net["tsch"]["max_retries"] = 0
        for link in net["topology"]["links"]:
            link["prr"] = 0.5

    result = wncs.run(write_variant(tmp_path, TSCH, "lossy.yaml", lossy))
    path = result.summary["network"]["paths"]["level"]
    assert path["lost"] > 0
    assert set(path["lost_by_reason"]) == {"sensor.retries_exhausted"}
    assert path["lost_by_reason"]["sensor.retries_exhausted"] == path["lost"]
    delivered = path["sent"] - path["lost"] - path["in_flight_at_end"]
    # three hops at 0.5 each, one retry cell per hop unused (no retransmission): 1/8 delivered
    assert delivered / path["sent"] == pytest.approx(0.125, abs=4 * (0.125 * 0.875 / 60) ** 0.5)
