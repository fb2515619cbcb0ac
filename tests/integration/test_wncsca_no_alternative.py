"""A rejected proposal with no alternative left (threads engine, real bus): the gateway says so
(``net/applied`` event ``no_alternative``) and the agent keeps the last accepted configuration
and its periods, and says so (verdict ``keep``)."""

from __future__ import annotations

import pytest

from runtime.launcher import launch
from tests.conftest import SCENARIOS, write_variant


@pytest.mark.slow
def test_no_alternative_keeps_the_last_accepted_configuration(tmp_path):
    def edit(d: dict) -> None:
        d["end_time"] = 26.0
        d["modes"] = []
        d["setpoints"] = [s for s in d["setpoints"] if s["t"] < 3.0]
        topo = d["nodes"]["network"]["topology"]
        # without r4 and r5 the only way round a failed r1 is the slow relay r3
        topo["nodes"] = {n: v for n, v in topo["nodes"].items() if n not in ("r4", "r5")}
        topo["links"] = [ln for ln in topo["links"] if not {ln["a"], ln["b"]} & {"r4", "r5"}]

    res = launch(
        write_variant(tmp_path, SCENARIOS / "jcstr_wncs.yaml", "v.yaml", edit),
        tmp_path / "run",
        engine="threads",
    )
    assert res.code == 0, res.error
    w = res.summary["wncsca"]
    verdicts = [(d["proposal"], d["verdict"]) for d in w["decisions"] if d["subject"] == "proposal"]
    assert verdicts == [(0, "accept"), (1, "reject"), (1, "keep")]
    keep = w["decisions"][-1]
    assert "no alternative" in keep["reasons"][0] and "#0" in keep["reasons"][0]
    assert [a["event"] for a in w["applied"]][-1] == "no_alternative"
    # the periods negotiated for proposal #0 stay in force
    negotiated = [a for a in w["assignments"] if "search" in a]
    assert len(negotiated) == 1
    assert w["assignments"][-1]["control_periods"] == negotiated[0]["control_periods"]
    assert w["assignments"][-1]["proposal"] == 0


def test_a_rejected_configuration_the_network_runs_is_reported_and_no_step_goes_over_it(tmp_path):
    """Issue 35, item 6, the case a user met: relay r4 down at 20.5 pu, then r1 at 24 pu; the
    only route left for the level goes over the slow relay r3, which the agent rejects. The
    network runs it anyway: the summary records that configuration, the agent says the level is
    at risk, and a level step requested at 26 pu is refused (the temperature's, whose path is
    unchanged, goes through)."""

    def edit(d: dict) -> None:
        d["nodes"]["network"]["events"].insert(
            0, {"t": 20.5, "event": {"type": "node_down", "node": "r4"}}
        )
        d["setpoints"].append({"t": 26.0, "loop": "level", "value": 0.75, "announce": 0.5})

    res = launch(
        write_variant(tmp_path, SCENARIOS / "jcstr_wncs.yaml", "r4r1.yaml", edit),
        tmp_path / "run",
        engine="direct",
    )
    assert res.code == 0, res.error
    summary = res.summary
    ran = [c for c in summary["network"]["configurations"] if c["t"] == 24.0]
    assert len(ran) == 1 and ran[0]["event"] == "no_alternative", ran
    assert "r3" in ran[0]["paths"]["level.sensor"]["route"]  # what really ran
    assert "rejected, no alternative left" in ran[0]["reason"]
    decisions = summary["wncsca"]["decisions"]
    keep = next(d for d in decisions if d["verdict"] == "keep")
    assert keep["proposal"] == 2 and "loops at risk: level" in " ".join(keep["reasons"])
    steps = {  # "step level 0.72 -> 0.75 refused: ..." / "temperature -> 58 at t=28; ..."
        next(w for w in d["reasons"][0].split()[:2] if w in ("level", "temperature")): d["verdict"]
        for d in decisions
        if d["subject"] == "setpoint" and d["t"] > 24.0
    }
    assert steps == {"level": "refuse", "temperature": "accept"}, steps
    level = [(s["from"], s["to"]) for s in summary["loops"]["level"]["steps"]]
    assert (0.72, 0.75) not in level  # the refused step was not applied
