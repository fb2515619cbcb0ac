"""Oscillation diagnosis and the Harris index of oscillating loops (issue 16, item 1): limit
cycles of known period assessed, not refused; drift, random walk and manual refused by name;
the interval never inverted."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter  # noqa: TID253 - not a node: imports what it uses at the top

from agents.monitor.errors import IdentificationError
from agents.monitor.harris import harris_index
from agents.monitor.oscillation import acf, detect_oscillation

PERIOD = 15
NOISE = 0.2


def _wave(kind: str, n: int, seed: int) -> tuple[np.ndarray, float]:
    """A wave of amplitude 1 and period 15 plus white noise, and the wave's variance."""
    t = np.arange(n)
    if kind == "sine":
        s, var = np.sin(2 * np.pi * t / PERIOD), 0.5
    else:  # triangle (stiction-like), amplitude 1
        s, var = 2 / np.pi * np.arcsin(np.sin(2 * np.pi * t / PERIOD)), 1 / 3
    return 50.0 + s + NOISE * np.random.default_rng(seed).standard_normal(n), var


def test_acf_equals_the_direct_sum():
    y = np.random.default_rng(3).standard_normal(300)
    yc = y - y.mean()
    direct = [np.sum(yc[h:] * yc[: yc.size - h]) / np.sum(yc**2) for h in range(40)]
    np.testing.assert_allclose(acf(y, 39), direct, atol=1e-12)


@pytest.mark.parametrize("n", [751, 5000])
@pytest.mark.parametrize("kind", ["sine", "triangle"])
def test_limit_cycle_flagged_with_its_period(kind, n):
    y, var = _wave(kind, n, seed=1)
    osc = detect_oscillation(y)
    assert osc.oscillating and osc.regular
    assert osc.period == pytest.approx(PERIOD, rel=0.1)
    assert osc.regularity > 1.0 and osc.decay > 0.9
    # amplitude of the sine with the periodic part's variance: sqrt(2 var) (1 for the sine)
    assert osc.amplitude == pytest.approx(math.sqrt(2 * var), rel=0.1)
    assert "sustained oscillation" in osc.text


@pytest.mark.parametrize("n", [751, 5000])
@pytest.mark.parametrize("kind", ["sine", "triangle"])
def test_limit_cycle_harris_index_of_the_data(kind, n):
    """The cycle is predictable d samples ahead, the noise is not: the minimum variance is the
    noise's, and the index sigma^2 / (var(wave) + sigma^2) (0.074 sine, 0.107 triangle); the
    AR(30) approximation of the cycle's predictor adds a little."""
    y, var = _wave(kind, n, seed=2)
    h = harris_index(y, 3)
    closed = NOISE**2 / (var + NOISE**2)
    assert h.index < 0.2
    assert h.index == pytest.approx(closed, abs=0.035)
    assert h.oscillating_model and h.model_period == pytest.approx(PERIOD, rel=0.02)
    assert h.uncertainty == "delta_numerator"
    assert h.ci[0] <= h.index <= h.ci[1] and h.std > 0


def test_underdamped_loop_is_not_a_limit_cycle():
    """AR(2) with poles 0.8 exp(+-2 pi i / 15): regular ACF crossings at first, but it decays by
    0.8^15 per period; not flagged as a sustained oscillation."""
    a1, a2 = 2 * 0.8 * math.cos(2 * math.pi / PERIOD), -0.64
    y = lfilter([1.0], [1.0, -a1, -a2], np.random.default_rng(4).standard_normal(5000))
    assert not detect_oscillation(y).oscillating
    a1, a2 = 2 * 0.95 * math.cos(2 * math.pi / PERIOD), -(0.95**2)
    osc = detect_oscillation(
        lfilter([1.0], [1.0, -a1, -a2], np.random.default_rng(4).standard_normal(5000))
    )
    assert not osc.oscillating
    if osc.regular:  # decay per period 0.95^15 = 0.46
        assert osc.decay == pytest.approx(0.95**PERIOD, abs=0.15) and "decaying" in osc.text


@pytest.mark.parametrize("seed", range(5))
def test_white_noise_and_random_walk_do_not_oscillate(seed):
    e = np.random.default_rng(seed).standard_normal(751)
    assert not detect_oscillation(e).oscillating
    assert not detect_oscillation(np.cumsum(e)).oscillating


@pytest.mark.parametrize("n", [751, 5000])
@pytest.mark.parametrize("seed", [1, 2])
def test_random_walk_refused_as_integrating(n, seed):
    y = np.cumsum(np.random.default_rng(seed).standard_normal(n))
    with pytest.raises(IdentificationError) as exc:
        harris_index(y, 3, name="PV")
    assert exc.value.reason == "unstable_model" and exc.value.kind == "integrating"
    assert "not stationary over the record (integrating)" in exc.value.detail


@pytest.mark.parametrize("n", [751, 5000])
def test_linear_drift_refused_as_drift(n):
    t = np.arange(n)
    y = 0.01 * t + lfilter([1.0], [1.0, -0.5], np.random.default_rng(5).standard_normal(n))
    with pytest.raises(IdentificationError) as exc:
        harris_index(y, 3, name="PV")
    assert exc.value.kind == "drift" and "drifts by 0.01" in exc.value.detail


def test_loop_in_manual_named_from_the_still_output():
    y = np.cumsum(np.random.default_rng(2).standard_normal(2000))
    with pytest.raises(IdentificationError) as exc:
        harris_index(y, 3, name="PV", op=np.full(2000, 42.0))
    assert exc.value.kind == "manual" and "in manual" in exc.value.detail


def test_index_above_one_never_inverts_the_interval():
    """White noise under d = 1 is at minimum variance: true index 1, estimates scatter around
    it, some above 1; every interval holds its index and is ordered."""
    above = 0
    for seed in range(20):
        y = np.random.default_rng(seed).standard_normal(751)
        h = harris_index(y, 1)
        assert h.ci[0] <= h.index <= h.ci[1], (seed, h.index, h.ci)
        assert h.above_one == (h.index > 1.0)
        assert h.index == pytest.approx(1.0, abs=0.05)
        above += h.above_one
    assert above >= 1
