"""Seed 001's two CSTRs under quasi-decentralized control with real ``wncs run`` processes
(processes engine) on a real zenoh router: the plant, the network and the two local control
systems are separate OS processes; the traces equal the direct engine's."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from core.record import summarize
from runtime.direct import simulate
from scenario import load_scenario
from tests.conftest import SCENARIOS, write_variant
from tests.integration.test_column_mrac_bus import assert_traces_equal

pytestmark = pytest.mark.slow

WNCS = str(Path(sys.executable).parent / "wncs")
QDC = SCENARIOS / "cstr_recycle_qdc.yaml"


def _run(path: Path, out: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [WNCS, "run", str(path), "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_qdc_by_processes_equals_direct(tmp_path):
    path = write_variant(tmp_path, QDC, "qdc.yaml", lambda d: d.update(end_time=0.1))
    proc = _run(path, tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["engine"] == "processes"
    direct = summarize(simulate(load_scenario(path)))
    assert_traces_equal(summary, direct)
    assert summary["network"]["links"] == direct["network"]["links"]
    assert summary["network"]["links"]["x2"]["delivered"] == 3  # at 0, h and 2 h


def test_bad_update_period_is_refused_before_anything_starts(tmp_path):
    text = QDC.read_text()
    old = "x1: {from: unit1, to: unit2, network: network, period: 0.038806}"
    assert old in text
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace(old, old.replace("0.038806", "0.0"), 1))
    proc = _run(bad, tmp_path / "out")
    assert proc.returncode == 2
    assert str(bad) in proc.stderr and "links.x1.period" in proc.stderr, proc.stderr
    assert not (tmp_path / "out").exists()
