"""``wncs analyze`` (issue 17, item 6) says what it judged (the scenario's initial configuration,
or the given delays: there is no gateway proposal, so no "proposal #None") and, with a WSN, the
projected network lifetime of the assignment against the benchmark periods."""

from __future__ import annotations

import json
from pathlib import Path

from agents.wncsca.timeline import format_timeline
from cli.main import main

ROOT = Path(__file__).resolve().parents[2]
WNCS = ROOT / "scenarios" / "jcstr_wncs.yaml"  # the demo: a WSN and the coordination agent


def test_analyze_names_what_it_judged_and_the_lifetime(capsys, tmp_path):
    out = tmp_path / "an"
    argv = ["analyze", str(WNCS), "--delays", "level=0.17,temperature=0.1", "--method", "paper"]
    assert main([*argv, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "#None" not in text
    assert "the given delays: ACCEPT" in text
    summary = json.loads((out / "summary.json").read_text())
    w = summary["wncsca"]
    assert w["decisions"][0]["subject"] == "the given delays"
    (energy,) = w["energy"]
    assert energy["network"] == "network"
    # the negotiated periods are longer than the benchmark's: the batteries last longer
    periods = w["assignments"][0]["control_periods"]
    assert all(p >= 0.1 for p in periods.values())
    assert energy["lifetime_h_assigned"] > energy["lifetime_h_benchmark"] > 0
    assert energy["ratio"] == energy["lifetime_h_assigned"] / energy["lifetime_h_benchmark"]
    line = (
        f"projected network lifetime {energy['lifetime_h_assigned']:.0f} h under the negotiated "
        f"periods vs {energy['lifetime_h_benchmark']:.0f} h at the benchmark periods"
    )
    assert line in text and line in format_timeline(summary)
