"""Supervised open loops (threads engine, real bus): in steady state the agent opens the loop and
cuts its sensor to the monitoring period; a disturbance that moves the level beyond the loop's
alarm band turns steady state into fault detection (faster reports), a confirming sample closes
the loop (regulation), and the controller brings the level back."""

from __future__ import annotations

import math

import pytest

from runtime.launcher import launch
from tests.conftest import SCENARIOS, write_variant

pytestmark = pytest.mark.slow

H0 = 50.0  # mm
U0 = 0.5 * math.sqrt(H0) / 2.0  # equilibrium inflow: b u = a' sqrt(h)


def _scenario(tmp_path):
    def edit(d: dict) -> None:
        d["end_time"] = 120.0
        d["nodes"]["tank"]["x0"] = {"h": H0}
        d["nodes"]["tank"]["u0"] = {"u": U0, "q_d": 0.0}
        d["loops"]["level"]["setpoint"] = H0
        d["setpoints"] = []
        d["disturbances"] = [{"t": 60.0, "plant": "tank", "input": "q_d", "value": 1.0}]
        d["modes"] = [{"t": 20.0, "mode": "steady_state"}]
        d["nodes"]["wncsca"] = {
            "kind": "agent",
            "method": "paper",  # the level loop is nlpi: only the paper method simulates it
            "phase": "fixed",
            "max_delay": 2.0,
            "test": {"end_time": 20.0, "setpoints": [{"t": 1.0, "loop": "level", "value": 60.0}]},
            "modes": {"monitoring": {"level": 5.0}, "fault_detection": {"level": 1.0}},
            "alarm": {"level": 2.0},
            "confirm": 2,
        }

    return write_variant(tmp_path, SCENARIOS / "tank_sim.yaml", "tank_alarm.yaml", edit)


def test_an_alarm_in_steady_state_closes_the_loop(tmp_path):
    res = launch(_scenario(tmp_path), tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    w = res.summary["wncsca"]
    modes = [
        (a["t"], a["mode"], a["periods"]["level"], a["closed"]["level"]) for a in w["assignments"]
    ]
    seq = [m for _, m, _, _ in modes]
    assert seq[seq.index("steady_state") :][:3] == ["steady_state", "fault_detection", "regulation"]
    t_fd = next(t for t, m, _, _ in modes if m == "fault_detection")
    t_reg = next(t for t, m, _, _ in modes if m == "regulation")
    assert 60.0 < t_fd <= 65.0 + 1e-9  # the first monitoring sample after the disturbance
    assert t_fd < t_reg <= t_fd + 2 * 1.0 + 1e-9  # confirmed at the fault-detection period
    steady = next(p for t, m, p, c in modes if m == "steady_state")
    fault = next((p, c) for t, m, p, c in modes if m == "fault_detection")
    reg = next((p, c) for t, m, p, c in modes if m == "regulation")
    assert steady == 5.0 and fault == (1.0, False) and reg[1] is True and reg[0] < 1.0
    alarms = [d for d in w["decisions"] if "alarm" in d["reasons"][0]]
    assert len(alarms) == 2 and "confirmed" in alarms[1]["reasons"][0]
    # the controller brings the level back to its set point against the disturbance
    trace = res.summary["loops"]["level"]["trace"]
    late = [y for t, y in zip(trace["t"], trace["y"], strict=True) if t > 110.0]
    assert late and max(abs(y - H0) for y in late) < 1.0
    # while the loop was open no move was made
    moves = [
        t for t, u in zip(trace["t"], trace["u"], strict=True) if 20.0 < t < t_reg and u is not None
    ]
    assert moves == []
