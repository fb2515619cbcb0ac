"""Every scenario runs on the direct engine with the bus engines' results (issue 13, DESIGN §3).

The direct engine runs the same behaviours as the bus nodes in the same rounds, so its traces,
the agent's proposals, decisions and assignments, and the monitor's assessments must equal those
of a ``threads`` run on a real router exactly, wall-clock measurements apart.
"""

from __future__ import annotations

from typing import Any

import pytest

from runtime.launcher import launch
from tests.conftest import SCENARIOS, write_variant
from tests.integration.test_monitor_bus import shortened

pytestmark = pytest.mark.slow

_WALL = {"decision_time_s", "wall_s", "phases_s", "engine", "timing"}
_BUS_ONLY = {"router"}  # what the bus's router refused: a direct run has no router


def _without_wall_clock(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _without_wall_clock(v) for k, v in x.items() if k not in _WALL}
    if isinstance(x, list):
        return [_without_wall_clock(v) for v in x]
    return x


def _both(path, tmp_path):
    runs = {}
    for engine in ("direct", "threads"):
        res = launch(path, tmp_path / engine, engine=engine)
        assert res.code == 0, res.error
        runs[engine] = _without_wall_clock(res.summary)
        if engine == "threads":
            assert res.summary["router"] == {"refused": 0, "attempts": []}
        runs[engine] = {k: v for k, v in runs[engine].items() if k not in _BUS_ONLY}
    return runs["direct"], runs["threads"]


def test_the_coordination_agent_on_the_direct_engine_decides_as_on_the_bus(tmp_path):
    """``wncs run scenarios/jcstr_wncs.yaml --engine direct``: relay failure, rejection, the
    alternatives and the negotiated periods, as the threads engine gives them."""
    direct, bus = _both(SCENARIOS / "jcstr_wncs.yaml", tmp_path)
    assert direct["wncsca"]["decisions"], "the agent decided nothing"
    verdicts = [d["verdict"] for d in direct["wncsca"]["decisions"] if d["subject"] == "proposal"]
    assert "reject" in verdicts and "accept" in verdicts  # the demo's rejected relay route
    assert direct["wncsca"] == bus["wncsca"]
    assert direct["loops"] == bus["loops"]  # traces, overshoots, settling times, IAE
    assert direct["network"] == bus["network"] and direct["messages"] == bus["messages"]
    assert direct == bus


def test_the_performance_monitor_on_the_direct_engine_assesses_as_on_the_bus(tmp_path):
    path = write_variant(tmp_path, SCENARIOS / "cascade_routine.yaml", "short.yaml", shortened)
    direct, bus = _both(path, tmp_path)
    assert direct["monitor"]["temperature"], "the monitor assessed nothing"
    assert direct["monitor"] == bus["monitor"]
    assert direct == bus
