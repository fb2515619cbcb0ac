"""Seed 001's two CSTRs under quasi-decentralized control over the bus (threads engine, a real
zenoh router): the plant and the two local control systems as separate nodes, the estimates
crossing the network on links every h; the traces equal the direct engine's."""

from __future__ import annotations

import pytest
from pydantic import BaseModel, ConfigDict

from bus_schemas import keys
from core.record import summarize
from gateway.behaviour import NetworkBehaviour
from runtime.direct import simulate
from runtime.launcher import launch
from scenario import load_scenario
from tests.conftest import SCENARIOS, write_variant
from tests.integration.test_column_mrac_bus import assert_traces_equal

QDC = SCENARIOS / "cstr_recycle_qdc.yaml"
T_BAD = 50_000  # 0.05 h, ticks


def _short(end_time: float, **more):
    def edit(d):
        d["end_time"] = end_time
        for name, value in more.items():
            if name == "link_delay":
                for link in d["links"].values():
                    link["delay"] = value
            elif name == "tau_d":
                d["loops"]["t2"]["tau_d"] = value
            elif name == "wsn":
                _over_a_wsn(d)

    return edit


def _over_a_wsn(d):
    """Both temperatures and both links over a small WSN (exponential per-hop jitter, a lossy
    link), the moves wired."""
    d["nodes"]["network"] = {
        "kind": "gateway",
        "topology": {
            "nodes": {
                "s1": {"kind": "sensor"},
                "s2": {"kind": "sensor"},
                "r": {"kind": "relay"},
                "gw": {"kind": "gateway"},
            },
            "retry_limit": 1,
            "delay": {"type": "exponential", "base": 0.0002, "mean": 0.0002},
            "links": [
                {"a": "s1", "b": "r", "prr": 0.95},
                {"a": "s2", "b": "r", "prr": 0.9},
                {"a": "r", "b": "gw", "prr": 1.0},
            ],
        },
    }
    d["loops"]["t1"]["sensor_node"] = "s1"
    d["loops"]["t2"]["sensor_node"] = "s2"
    d["links"]["x1"].update(source_node="s1", dest_node="s2")
    d["links"]["x2"].update(source_node="s2", dest_node="s1")


@pytest.mark.parametrize(
    "edit",
    [
        _short(0.2),  # zero delays: samples, estimates and moves in one instant's rounds
        _short(0.12, link_delay=0.0013, tau_d=0.0005),  # delayed estimates and samples
        _short(0.12, wsn=True),  # jitter and losses on every path and link
    ],
    ids=["wired", "delayed", "wsn"],
)
def test_qdc_over_the_bus_equals_direct(tmp_path, edit):
    path = write_variant(tmp_path, QDC, "qdc.yaml", edit)
    res = launch(path, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    direct = summarize(simulate(load_scenario(path)))
    assert_traces_equal(res.summary, direct)
    assert res.summary["network"]["paths"] == direct["network"]["paths"]
    assert res.summary["network"]["links"] == direct["network"]["links"]
    assert res.summary["network"]["links"]["x1"]["delivered"] >= 3
    assert res.summary["loops"]["ca0"]["trace"]["y"] == [None] * len(
        res.summary["loops"]["ca0"]["trace"]["t"]
    )


class _Raw(BaseModel):
    """Any mapping, published as it is."""

    model_config = ConfigDict(extra="allow", frozen=True)


class _NoisyNetwork(NetworkBehaviour):
    """The wired network, which at 0.05 h also delivers nonsense on link/x1/rx: a vector of
    text, a vector of the wrong length and a negative send time."""

    def __init__(self, name, scenario) -> None:
        super().__init__(name, scenario)
        self.at(T_BAD, self._nonsense)

    def _nonsense(self) -> None:
        self.publish(keys.link_rx("x1"), _Raw(values=["hot", "cold"], t_sent=T_BAD))
        self.publish(keys.link_rx("x1"), _Raw(values=[1.0], t_sent=T_BAD))
        self.publish(keys.link_rx("x1"), _Raw(values=[1.0, 0.0], t_sent=-5))


def test_malformed_estimates_are_dropped_and_change_nothing(tmp_path, stand_in):
    path = write_variant(tmp_path, QDC, "qdc.yaml", _short(0.1))
    stand_in("network", _NoisyNetwork)
    res = launch(path, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    assert res.summary["messages"]["dropped_invalid"]["link/x1/rx"] == 3
    direct = summarize(simulate(load_scenario(path)))
    for name, loop in direct["loops"].items():
        assert res.summary["loops"][name]["trace"] == loop["trace"], name
