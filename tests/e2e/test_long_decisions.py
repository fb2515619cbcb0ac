"""A node busy thinking is not a fault (issue 41): the chance agent's first decision on the
jitter case, as an OS process on a secure run, takes many times the clock's round timeout and
the run completes (its progress beats pass the router's access control); the decision's wall
time is in the summary and the timeline."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import SCENARIOS, write_variant

pytestmark = pytest.mark.slow

WNCS = str(Path(sys.executable).parent / "wncs")
ROUND_TIMEOUT_S = 0.5


def _short(data: dict) -> None:
    """To 0.5 pu (the first decision and a few rounds after it), silence judged at 0.5 s."""
    data["end_time"] = 0.5
    data["setpoints"], data["modes"] = [], []
    data["clock"] = {"round_timeout_s": ROUND_TIMEOUT_S}


def test_a_decision_many_round_timeouts_long_completes_on_the_processes_engine(tmp_path):
    scenario = write_variant(tmp_path, SCENARIOS / "jcstr_wncs_jitter.yaml", "j.yaml", _short)
    out = tmp_path / "run"
    proc = subprocess.run(
        [WNCS, "run", str(scenario), "--out", str(out), "--engine", "processes"],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    decisions = json.loads((out / "summary.json").read_text())["wncsca"]["decisions"]
    first = next(d for d in decisions if d["subject"] == "proposal")
    assert first["verdict"] == "accept"
    took = first["decision_time_s"]
    # the premise: the agent was busy for at least four of the clock's round timeouts
    assert took >= 4 * ROUND_TIMEOUT_S, f"the decision took only {took:.2f} s"
    assert f"ACCEPT [{took:.2f} s]" in proc.stdout
