"""PI law with feedforward: integration over actual sample intervals, limits, anti-windup."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from controllers.pi import PI, PIConfig


def test_forward_euler_uses_previous_error_and_actual_interval():
    pi = PI(PIConfig(Kp=2.0, Ki=3.0), u_bar=1.0)
    assert pi.step(0.0, 0.0, 1.0) == pytest.approx(1.0 + 2.0)  # no integral yet
    # interval 0.25: I = 3 * e_prev(1) * 0.25
    assert pi.step(0.25, 0.5, 1.0) == pytest.approx(1.0 + 2.0 * 0.5 + 0.75)
    # uneven interval 0.1 (periods change at run time): I += 3 * 0.5 * 0.1
    assert pi.step(0.35, 0.5, 1.0) == pytest.approx(1.0 + 1.0 + 0.75 + 0.15)


def test_backward_euler_uses_current_error():
    pi = PI(PIConfig(Kp=0.0, Ki=1.0, integration="backward"))
    pi.step(0.0, 0.0, 1.0)
    assert pi.step(0.5, 0.0, 3.0) == pytest.approx(1.5)


def test_feedforward_changes_output_directly():
    pi = PI(PIConfig(Kp=1.0, Ki=0.0), u_bar=0.4)
    pi.step(0.0, 1.0, 1.0)
    pi.set_feedforward(0.6)
    assert pi.step(0.1, 1.0, 1.0) == pytest.approx(0.6)


def test_output_limits_and_clamping_anti_windup():
    pi = PI(PIConfig(Kp=1.0, Ki=10.0, u_min=0.0, u_max=1.0))
    for k in range(50):  # large persistent error: saturated high
        u = pi.step(0.1 * k, 0.0, 5.0)
        assert 0.0 <= u <= 1.0
    assert u == 1.0
    # the integral did not wind up: once the error reverses, the output leaves the limit at once
    assert pi.integral < 1.0
    assert pi.step(5.0, 6.0, 5.0) < 1.0


def test_negative_gains_for_reverse_acting_loops():
    pi = PI(PIConfig(Kp=-2.0, Ki=-1.0, u_min=0.0, u_max=5.0), u_bar=1.0)
    assert pi.step(0.0, 0.8, 0.7) == pytest.approx(1.2)  # level above set point: open the outlet


def test_time_going_back_is_refused():
    pi = PI(PIConfig(Kp=1.0, Ki=1.0))
    pi.step(1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="backwards"):
        pi.step(0.5, 0.0, 0.0)


def test_limits_must_be_ordered():
    with pytest.raises(ValidationError, match="u_min"):
        PIConfig(Kp=1.0, Ki=1.0, u_min=2.0, u_max=1.0)
