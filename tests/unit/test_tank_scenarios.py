"""Seed 002's studies as shipped scenarios, by the direct engine (issue: tank level over the bus).

The same figures the numerical-core tests check with their own loop, here through the scenario
files, the generic controller mechanism and the platform's metrics (1 % settling band).
"""

from __future__ import annotations

import numpy as np
import pytest

from core.record import summarize
from runtime.direct import simulate
from scenario import load_scenario
from tests.conftest import SCENARIOS


def _steps(name):
    return summarize(simulate(load_scenario(SCENARIOS / name)))["loops"]["level"]["steps"]


def test_simulation_study_same_response_at_every_level():
    steps = _steps("tank_sim.yaml")
    assert [s["to"] for s in steps] == [50.0, 100.0, 150.0]
    for s in steps:
        assert s["overshoot_pct"] == pytest.approx(4.3, abs=0.5)
        assert s["settling_time"] == pytest.approx(13.0, abs=1.5)


def test_baseline_varies_with_level_more_than_the_nonlinear_pi():
    nl = _steps("tank_sim.yaml")
    base = _steps("tank_sim_baseline.yaml")
    spread = lambda steps: np.ptp([s["overshoot_pct"] for s in steps])  # noqa: E731
    assert spread(base) > 10 * spread(nl)


def test_disturbance_peaks_agree_across_levels():
    s = load_scenario(SCENARIOS / "tank_sim.yaml")
    rec = simulate(s)
    t, h = rec.plants["tank"].signal("h")
    peaks = []
    for d in s.disturbances:
        if d.value == 0.0:
            continue
        window = (t >= d.t) & (t <= d.t + 10.0)
        level = {25.0: 50.0, 75.0: 100.0, 125.0: 150.0}[d.t]
        peaks.append(np.max(np.abs(h[window] - level)))
    assert max(peaks) <= 1.10 * min(peaks)


def test_rig_study_with_noise_and_self_tuning():
    for s in _steps("tank_rig.yaml"):
        assert s["overshoot_pct"] == pytest.approx(4.3, abs=1.5)
        assert s["settling_time"] == pytest.approx(100.0, abs=15.0)
