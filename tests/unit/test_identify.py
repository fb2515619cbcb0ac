"""Identification recovers a plant's parameters to the accuracy its covariance states (issue 35,
item 3, acceptance): against closed forms and over many seeds (calibration).

* ARX on a closed-form first-order system ``y_k = 0.9 y_{k-1} + 0.5 u_{k-1} + e_k`` driven by
  GBN: the estimates lie within their 95 % intervals in about 95 % of 200 seeds (binomial
  bounds), and the covariance's standard deviation is the spread of the estimates over seeds.
* Grey box on the tank of seed 002 (``dh/dt = b u - a' sqrt(h)``, b = 2, a' = 0.5) with a GBN
  pump command about a level and Gaussian noise on the level samples: ``b`` and ``a'`` from a
  10 % wrong start, within their 95 % intervals in at least 85 % of 40 seeds, the noise's
  standard deviation recovered, and the stated standard deviation growing with the noise as the
  Gauss-Newton covariance says (proportionally).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.stats  # noqa: TID253 - not a node: imports what it uses at the top

from agents.identify.arx import fit_arx
from agents.identify.excitation import gbn
from agents.identify.greybox import Experiment, fit_grey_box, simulate_experiment
from plants import registry

A, B, SIGMA = 0.9, 0.5, 0.05


def _first_order(seed: int, n: int = 400) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = gbn(n, 0.2, 1.0, rng)
    e = SIGMA * rng.standard_normal(n)
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = A * y[k - 1] + B * u[k - 1] + e[k]
    return u, y


def test_gbn_switches_with_its_probability_and_keeps_its_amplitude():
    x = gbn(20000, 0.1, 2.0, np.random.default_rng(3))
    assert set(np.unique(x)) == {-2.0, 2.0} and x[0] == 2.0
    rate = np.mean(x[1:] != x[:-1])
    assert rate == pytest.approx(0.1, abs=4 * math.sqrt(0.1 * 0.9 / 20000))
    with pytest.raises(ValueError, match="p_switch"):
        gbn(10, 0.0, 1.0, np.random.default_rng(0))


def test_arx_recovers_the_closed_form_within_its_stated_accuracy():
    fits = [fit_arx(*_first_order(seed), na=1, nb=1) for seed in range(200)]
    a = np.array([-f.a[0] for f in fits])  # the ARX sign convention: y + a1 y(-1) = ...
    b = np.array([f.b[0] for f in fits])
    sa = np.array([f.std[0] for f in fits])
    sb = np.array([f.std[1] for f in fits])
    for est, sd, true in ((a, sa, A), (b, sb, B)):
        inside = np.mean(np.abs(est - true) <= 1.96 * sd)
        lo, hi = scipy.stats.binom.ppf([0.001, 0.999], 200, 0.95) / 200
        assert lo <= inside <= hi, inside
        assert np.std(est) == pytest.approx(np.mean(sd), rel=0.2)  # the stated spread is real
    assert np.mean([f.sigma for f in fits]) == pytest.approx(SIGMA, rel=0.02)
    assert all(f.fit_pct > 50 for f in fits)


def test_arx_refuses_what_it_cannot_fit():
    with pytest.raises(ValueError, match="too few"):
        fit_arx(np.zeros(3), np.zeros(3), 1, 1)
    with pytest.raises(ValueError, match="one length"):
        fit_arx(np.zeros(10), np.zeros(11), 1, 1)


TANK = {"b": 2.0, "a_prime": 0.5, "u_min": 0.0}


def _build(params):
    return registry.build("tank", params)


def _tank_experiment(seed: int, noise: float = 0.2) -> Experiment:
    """100 s about a level of 50 mm (u = a' sqrt(50) / b), the pump stepped +-0.3 by a GBN of a
    2 s clock, the level sampled every 0.5 s with Gaussian noise."""
    rng = np.random.default_rng(seed)
    u0 = 0.5 * math.sqrt(50.0) / 2.0
    t_moves = np.arange(0.0, 100.0, 2.0)
    u = np.column_stack([u0 + gbn(len(t_moves), 0.5, 0.3, rng), np.zeros(len(t_moves))])
    t_samples = np.arange(0.5, 100.0, 0.5)
    clean = Experiment((50.0,), t_moves, u, {"h": (t_samples, np.zeros(len(t_samples)))}, 0.05)
    y = simulate_experiment(_build(TANK), clean)["h"] + noise * rng.standard_normal(len(t_samples))
    return Experiment((50.0,), t_moves, u, {"h": (t_samples, y)}, 0.05)


def test_grey_box_recovers_the_tank_within_its_stated_accuracy():
    start = {**TANK, "b": 2.2, "a_prime": 0.45}  # 10 % off either way
    inside = {"b": 0, "a_prime": 0}
    sigmas = []
    for seed in range(40):
        fit = fit_grey_box(_build, start, ("b", "a_prime"), _tank_experiment(seed))
        for name in inside:
            lo, hi = fit.interval(name)
            inside[name] += lo <= TANK[name] <= hi
        sigmas.append(fit.sigma)
        assert fit.fit_pct["h"] > 80
    assert min(inside.values()) >= 34, inside  # >= 85 % of 40 within their 95 % interval
    assert np.mean(sigmas) == pytest.approx(0.2, rel=0.05)


def test_grey_box_states_a_wider_uncertainty_for_noisier_data():
    start = {**TANK, "b": 2.2, "a_prime": 0.45}
    quiet = fit_grey_box(_build, start, ("b", "a_prime"), _tank_experiment(1, noise=0.1))
    loud = fit_grey_box(_build, start, ("b", "a_prime"), _tank_experiment(1, noise=0.4))
    for name in ("b", "a_prime"):
        assert loud.std(name) == pytest.approx(4 * quiet.std(name), rel=0.25)


def test_grey_box_refuses_what_it_cannot_fit():
    exp = _tank_experiment(0)
    with pytest.raises(ValueError, match="not a non-zero numeric parameter"):
        fit_grey_box(_build, TANK, ("u_min",), exp)
    with pytest.raises(ValueError, match="samples for"):
        short = Experiment((50.0,), [0.0], np.array([[1.0, 0.0]]), {"h": ([1.0], [50.0])})
        fit_grey_box(_build, TANK, ("b", "a_prime"), short)
