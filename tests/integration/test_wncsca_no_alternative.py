"""A rejected proposal with no alternative left (threads engine, real bus): the gateway says so
(``net/applied`` event ``no_alternative``) and the agent keeps the last accepted configuration
and its periods, and says so (verdict ``keep``)."""

from __future__ import annotations

import pytest

from runtime.launcher import launch
from tests.conftest import SCENARIOS, write_variant

pytestmark = pytest.mark.slow


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
