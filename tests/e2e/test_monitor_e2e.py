"""The performance monitor with real OS processes: ``wncs run`` (processes engine) then
``wncs assess RUN_DIR`` as a separate command: the node's final assessment equals the command's."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from agents.monitor.behaviour import assessment_body
from bus_schemas import MonitorAssessment, codec, keys
from runtime.history import connect
from tests.conftest import SCENARIOS, write_variant

pytestmark = pytest.mark.slow

WNCS = str(Path(sys.executable).parent / "wncs")


def _short(data: dict) -> None:
    data["end_time"] = 500.0
    data["nodes"]["monitor"].update(window=400, start=50.0, period=None, analysis={"max_order": 10})


def test_processes_engine_node_equals_command(tmp_path):
    scenario = write_variant(tmp_path, SCENARIOS / "cascade_routine.yaml", "short.yaml", _short)
    run_dir = tmp_path / "run"
    proc = subprocess.run(
        [WNCS, "run", str(scenario), "--out", str(run_dir), "--quiet"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    with connect(run_dir / "history.sqlite") as conn:
        rows = conn.execute(
            "SELECT src, body FROM messages WHERE key = ?",
            (keys.monitor_assessment("temperature"),),
        ).fetchall()
    assert [src for src, _ in rows] == ["monitor"]
    body = MonitorAssessment.model_validate(codec.unpack_mapping(rows[0][1]))
    assert body.final and body.status == "ok" and body.n_samples == 400
    out = tmp_path / "cli.json"
    cmd = [
        WNCS, "assess", str(run_dir),
        "--primary", "temperature", "--setpoint", "temperature.sp",
        "--secondary", "reactor.y2,reactor.y3", "--delays", "3,1,3,1",
        "--window", "400", "--start", "50", "--max-order", "10", "--out", str(out),
    ]  # fmt: skip
    assess = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    parts = [body.harris, *body.candidates]
    assert assess.returncode == (0 if all(p.status == "ok" for p in parts) else 3), assess.stderr
    assert "Harris index" in assess.stdout
    assert assessment_body(json.loads(out.read_text()), final=True) == body
