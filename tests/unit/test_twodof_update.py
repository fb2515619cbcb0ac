"""The agent's modelled 2-DOF laws (:class:`agents.wncsca.laws.TwoDofLaw`, executing
:func:`controllers.nlpi.twodof_update`) are the controller node's laws of seed 002.

The chance and fast methods execute a loop's law elementwise over realizations; a controller node
runs :class:`~controllers.nlpi.NonlinearPI` or :class:`~controllers.nlpi.TwoDofPI` one execution
at a time. Both run the same random executions (uneven intervals, set-point steps, every
integration rule and start rule, the pump's limits hit from both sides) and must agree to the
last bit, commands and integrals alike. Then the linear form: the non-linear PI's tangent on the
tank's tangent gives the designed closed loop ``s^2 + 2 zeta w_n s + w_n^2`` at every level
(seed 002 eq. (23)), an independent computation of what the law is designed for.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.wncsca.laws import PILaw, TwoDofLaw, modelled_law, stack
from controllers.nlpi import NLPIConfig, PI2DOFConfig, design_targets
from controllers.pi import PIConfig
from controllers.registry import build_law
from plants.registry import build as build_plant

TANK = build_plant("tank", {"b": 2.0, "a_prime": 0.5, "u_min": 0.0, "u_max": 6.0})
SPEC = {"overshoot_pct": 4.3, "settling_time": 13.0}


def _configs() -> list[NLPIConfig | PI2DOFConfig]:
    out: list[NLPIConfig | PI2DOFConfig] = []
    for integration in ("backward", "forward", "trapezoidal"):
        out.append(NLPIConfig(**SPEC, integration=integration))
        out.append(PI2DOFConfig(**SPEC, h_design=80.0, integration=integration, start="zero"))
    out.append(NLPIConfig(**SPEC, u_start=1.2))
    out.append(PI2DOFConfig(**SPEC, h_design=80.0))  # start: rest on the design model
    return out


@pytest.mark.parametrize("config", _configs(), ids=lambda c: f"{c.type}-{c.integration}")
def test_the_modelled_law_is_the_node_law_to_the_bit(config):
    rng = np.random.default_rng(35)
    items, steps = 48, 300
    laws = [build_law(config, u_bar=0.0, plant=TANK, tau_s=0.1) for _ in range(items)]
    model = modelled_law(config, TANK)
    assert isinstance(model, TwoDofLaw)
    t = np.cumsum(rng.uniform(0.01, 2.0, (steps, items)), axis=0)
    y = np.abs(rng.normal(60.0, 40.0, (steps, items)))
    y[::37] = 0.0  # an empty tank: the square root's edge
    r = np.repeat(rng.choice([20.0, 60.0, 140.0], (steps // 25, items)), 25, axis=0)

    integral = np.zeros(items)
    e_prev = np.zeros(items)
    low = high = 0
    for k in range(steps):
        expected = [
            law.step(float(t[k, i]), float(y[k, i]), float(r[k, i])) for i, law in enumerate(laws)
        ]
        e = r[k] - y[k]
        if k == 0:
            integral = model.start(y[k], integral)
            increment = np.zeros(items)
        else:
            increment = model.increment(e, e_prev, t[k] - t[k - 1])
        u, integral = model.update(e, y[k], increment, integral, 0.0)
        e_prev = e
        assert u.tolist() == expected, f"execution {k}"
        assert integral.tolist() == [law.integral for law in laws], f"execution {k}"
        low += int(np.sum(u == laws[0].u_min))
        high += int(np.sum(u == laws[0].u_max))
    assert low > steps and high > steps  # the clamps were exercised, on both sides


@pytest.mark.parametrize("level", [10.0, 50.0, 150.0])
def test_the_nonlinear_pi_linearised_on_the_linearised_tank_is_the_designed_loop(level):
    """Tank tangent at ``h``: ``dh' = -a'/(2 sqrt h) dh + b du``; law tangent ``du = -k_y dh +
    k_i q``, ``q' = r - h``: characteristic polynomial ``s^2 + (a'/(2 sqrt h) + b k_y) s +
    b k_i``, which must be eq. (23)'s ``s^2 + 2 zeta w_n s + w_n^2``."""
    config = NLPIConfig(**SPEC)
    form = modelled_law(config, TANK).linear(level, level)
    a_small = 0.5 / (2.0 * math.sqrt(level))
    zeta, w_n = design_targets(config)
    assert a_small + 2.0 * form.k_y == pytest.approx(2.0 * zeta * w_n, rel=1e-12)
    assert 2.0 * form.k_i == pytest.approx(w_n**2, rel=1e-12)
    assert form.k_r == 0.0  # proportional action on the measurement only
    # at rest at the level it started from, the form gives the equilibrium command a' sqrt(h)/b
    assert form.c - form.k_y * level == pytest.approx(0.5 * math.sqrt(level) / 2.0, rel=1e-12)


def test_the_nonlinear_pi_has_no_linear_form_at_an_empty_tank():
    with pytest.raises(ValueError, match="infinite slope at 0"):
        modelled_law(NLPIConfig(**SPEC), TANK).linear(0.0, 0.0)


def test_a_pi_keeps_its_gains_and_draws_stack_per_realization():
    pi = modelled_law(PIConfig(Kp=1.0, Ki=0.5), TANK)
    assert isinstance(pi, PILaw) and pi.linear(3.0, 1.0) == pi.linear(9.0, 1.0)
    other = build_plant("tank", {"b": 2.5, "a_prime": 0.5, "u_min": 0.0, "u_max": 6.0})
    laws = [modelled_law(NLPIConfig(**SPEC), p) for p in (TANK, other)]
    both = stack(laws, np.array([0, 1, 1, 0]))
    assert isinstance(both, TwoDofLaw)
    assert np.asarray(both.kp).tolist() == [laws[0].kp, laws[1].kp, laws[1].kp, laws[0].kp]
    assert both.integration == "backward" and stack(laws[:1], np.zeros(3, int)) is laws[0]
