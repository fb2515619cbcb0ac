"""Bad requests to the coordination agent over a real zenoh bus (threads engine): proposals with a
negative delay, an unknown loop or missing fields, an unknown mode and a malformed set point are
refused with a reason on ``wncsca/decision``, and nothing changes: the loops' traces are those of
the same run without them.

The bad requests come from the participants the agent listens to (a gateway that also proposes
nonsense, an operator that also asks for nonsense), so they pass the bus's round protocol and
reach the agent's validation; a forged message from a non-participant never gets that far (the
node base drops it, see ``test_threads_engine.py``).
"""

from __future__ import annotations

import pytest
from pydantic import BaseModel, ConfigDict

from agents.operator.behaviour import OperatorBehaviour
from agents.wncsca.timeline import format_timeline
from bus_schemas import keys
from gateway.behaviour import NetworkBehaviour
from runtime.launcher import launch
from tests.conftest import SCENARIOS, write_variant

pytestmark = pytest.mark.slow

T_BAD = 500_000  # 0.5 pu, ticks
NOISY = {"network", "operator"}  # the scenario's nodes that publish nonsense


class _Raw(BaseModel):
    """Any mapping, published as it is (the agent validates it against its own schemas)."""

    model_config = ConfigDict(extra="allow", frozen=True)


BAD_PROPOSALS = {
    7: (
        {
            "level.sensor": {"hops": 3, "route": [], "estimates": {"hops": -0.1}},
            "temperature.sensor": {"hops": 2, "route": [], "estimates": {"hops": 0.1}},
        },
        "paths.level.sensor.estimates.hops: Input should be greater than or equal to 0 (got -0.1)",
    ),
    8: (
        {
            "flow.sensor": {"hops": 1, "route": [], "estimates": {"hops": 0.01}},
            "level.sensor": {"hops": 3, "route": [], "estimates": {"hops": 0.01}},
            "temperature.sensor": {"hops": 2, "route": [], "estimates": {"hops": 0.01}},
        },
        "unknown loop 'flow'",
    ),
    9: (None, "paths: missing"),
}


class _NoisyGateway(NetworkBehaviour):
    def __init__(self, name, scenario) -> None:
        super().__init__(name, scenario)
        if name in NOISY:  # not the operator of the agent's own model (same behaviour registry)
            self.at(T_BAD, self._nonsense)

    def _nonsense(self) -> None:
        for pid, (paths, _) in BAD_PROPOSALS.items():
            body = {"id": pid, "event": "x", "source": "injected"}
            if paths is not None:
                body["paths"] = paths
            self.publish(keys.net_proposal(), _Raw(**body))


class _NoisyOperator(OperatorBehaviour):
    def __init__(self, name, scenario) -> None:
        super().__init__(name, scenario)
        if name in NOISY:  # not the operator of the agent's own model (same behaviour registry)
            self.at(T_BAD, self._nonsense)

    def _nonsense(self) -> None:
        self.publish(keys.ops_mode(), _Raw(mode="party"))
        self.publish(keys.ops_mode(), _Raw(phase="steady"))
        self.publish(keys.setpoint("level"), _Raw(value="high"))
        self.publish(keys.setpoint("temperature"), _Raw(value=55.0, t_apply=-5))


def _variant(tmp_path):
    def edit(d: dict) -> None:
        d["end_time"] = 6.0
        d["nodes"]["network"]["events"] = []
        d["setpoints"] = [s for s in d["setpoints"] if s["t"] < 6.0]
        d["modes"] = []

    return write_variant(tmp_path, SCENARIOS / "jcstr_wncs.yaml", "wncs_short.yaml", edit)


def test_bad_requests_are_refused_and_change_nothing(tmp_path, stand_in):
    scenario = _variant(tmp_path)
    clean = launch(scenario, tmp_path / "clean", engine="threads")
    assert clean.code == 0, clean.error
    stand_in("gateway", _NoisyGateway)
    stand_in("operator", _NoisyOperator)
    noisy = launch(scenario, tmp_path / "noisy", engine="threads")
    assert noisy.code == 0, noisy.error

    decisions = noisy.summary["wncsca"]["decisions"]
    at_bad = [d for d in decisions if d["t"] == T_BAD / 1e6]
    by_id = {d["proposal"]: d for d in at_bad if d["subject"] == "proposal"}
    for pid, (_, fragment) in BAD_PROPOSALS.items():
        assert by_id[pid]["verdict"] == "refuse", by_id[pid]
        assert fragment in by_id[pid]["reasons"][0], (fragment, by_id[pid]["reasons"])
    modes = [d for d in at_bad if d["subject"] == "mode"]
    assert [d["verdict"] for d in modes] == ["refuse", "refuse"]
    assert any("unknown mode 'party'" in d["reasons"][0] for d in modes)
    sps = [d for d in at_bad if d["subject"] == "setpoint"]
    assert [d["verdict"] for d in sps] == ["refuse", "refuse"]
    assert any(
        "level.value: Input should be a valid number (got 'high')" in d["reasons"][0] for d in sps
    )
    assert any(
        "temperature.t_apply: Input should be greater than or equal to 0 (got -5)"
        in d["reasons"][0]
        for d in sps
    )

    assert "proposal #7: REFUSE" in format_timeline(noisy.summary)

    # nothing changed: same assignments (no new rates at the bad instant), same traces
    assert [a for a in noisy.summary["wncsca"]["assignments"] if a["t"] == T_BAD / 1e6] == []

    def unordered(summary: dict) -> list[dict]:  # "order" counts the extra messages too
        return [
            {k: v for k, v in a.items() if k != "order"} for a in summary["wncsca"]["assignments"]
        ]

    assert unordered(noisy.summary) == unordered(clean.summary)
    for name, loop in clean.summary["loops"].items():
        assert noisy.summary["loops"][name]["trace"] == loop["trace"], name
