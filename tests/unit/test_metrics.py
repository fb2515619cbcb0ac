"""Step metrics against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from core.metrics import step_metrics


@pytest.mark.parametrize("zeta", [0.3, 0.5, 0.7])
def test_overshoot_of_second_order_step(zeta):
    wn = 5.0
    t = np.linspace(0, 10, 200_001)
    wd = wn * np.sqrt(1 - zeta**2)
    y = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * t))
    m = step_metrics(t + 1.0, 2.0 + 3.0 * y, t_step=1.0, t_end=11.0, r_from=2.0, r_to=5.0)
    expected = 100 * np.exp(-zeta * np.pi / np.sqrt(1 - zeta**2))
    assert m.overshoot_pct == pytest.approx(expected, rel=1e-4)


def test_settling_time_and_iae_of_first_order_step_down():
    tau = 0.4
    t = np.linspace(0, 5, 500_001)
    y = 1.0 - 1.0 * (1 - np.exp(-t / tau))  # from 1 to 0
    m = step_metrics(t, y, t_step=0.0, t_end=5.0, r_from=1.0, r_to=0.0)
    assert m.overshoot_pct == 0.0
    assert m.settling_time == pytest.approx(tau * np.log(50), abs=1e-4)
    assert m.iae == pytest.approx(tau * (1 - np.exp(-5 / tau)), rel=1e-6)


def test_unsettled_response_reports_none():
    t = np.linspace(0, 1, 101)
    m = step_metrics(t, np.sin(20 * t), t_step=0.0, t_end=1.0, r_from=-1.0, r_to=0.0)
    assert m.settling_time is None
