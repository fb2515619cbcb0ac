"""Seed 003's MRAC with real ``wncs run`` processes (processes engine) on a real zenoh router."""

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
THESIS = SCENARIOS / "column_mrac.yaml"
WSN = SCENARIOS / "column_mrac_wsn.yaml"


def _run(path: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [WNCS, "run", str(path), "--out", str(out), "--quiet", *extra],
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_thesis_test_by_processes_equals_direct(tmp_path):
    proc = _run(THESIS, tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["engine"] == "processes"
    assert_traces_equal(summary, summarize(simulate(load_scenario(THESIS))))


def test_wsn_variant_by_processes_equals_direct(tmp_path):
    path = write_variant(tmp_path, WSN, "wsn.yaml", lambda d: d.update(end_time=21.0))
    proc = _run(path, tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    direct = summarize(simulate(load_scenario(path)))
    assert_traces_equal(summary, direct)
    assert summary["network"]["paths"] == direct["network"]["paths"]


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("gamma: 100.0", "gamma: -1.0", "nodes.mrac.controller.law.mrac.gamma"),
        ("      T: 0.1\n", "      T: 0.0\n", "nodes.mrac.controller.law.mrac.T"),
        ("B0: [[-0.14, 0.20], [-0.0020, -0.028]]", "B0: [[1.0, 2.0], [2.0, 4.0]]", "B0: "),
    ],
)
def test_bad_mrac_scenario_is_refused_before_anything_starts(tmp_path, old, new, field):
    text = THESIS.read_text()
    assert old in text
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace(old, new, 1))
    proc = _run(bad, tmp_path / "out")
    assert proc.returncode == 2
    assert str(bad) in proc.stderr and field in proc.stderr, proc.stderr
    assert not (tmp_path / "out").exists()
