"""Harris index from routine data: against a minimum-variance loop and analytic closed loops."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.monitor.errors import IdentificationError
from agents.monitor.harris import harris_index, model_index
from agents.monitor.timeseries import fit_var
from controllers.cascade.model import SFBPI, LinearFeedback, LinearFeedbackConfig, SFBPIConfig
from plants.cascade.model import CascadeProcessConfig, StageConfig, closed_loop
from plants.cascade.routine import simulate

# y = q^-d b/(1 - a q^-1) u + 1/(1 - c q^-1) e
A_POLE, B_GAIN, C_POLE, DELAY = 0.8, 0.2, 0.9, 3


def _siso(noise_den: tuple[float, ...] = (1.0, -C_POLE)) -> CascadeProcessConfig:
    stage = StageConfig(
        name="y",
        delay=DELAY,
        num=(B_GAIN,),
        den=(1.0, -A_POLE),
        noise_den=noise_den,
        noise_std=1.0,
    )
    return CascadeProcessConfig(stages=(stage,))


def _mv_law() -> LinearFeedbackConfig:
    """Minimum-variance law from the Diophantine equation C' = A' F + q^-d G (written here
    independently of the monitor): A' y = q^-d B' u + C' e with A' = (1 - a q)(1 - c q),
    B' = b (1 - c q), C' = 1 - a q; u = -G / (B' F) y; closed loop y = F e."""
    a_p = np.convolve([1.0, -A_POLE], [1.0, -C_POLE])
    b_p = B_GAIN * np.array([1.0, -C_POLE])
    c_p = np.array([1.0, -A_POLE])
    # F: first d terms of C'/A'
    f = np.zeros(DELAY)
    rem = np.r_[c_p, np.zeros(DELAY + a_p.size)]
    for i in range(DELAY):
        f[i] = rem[i]
        rem[i : i + a_p.size] -= f[i] * a_p
    g = rem[DELAY : DELAY + a_p.size - 1]
    den = np.convolve(b_p, f)
    return LinearFeedbackConfig(measurement="y", num=tuple(g / den[0]), den=tuple(den / den[0]))


def test_mv_law_closed_loop_is_the_invariant_ma():
    """The law above really is minimum variance: closed loop e -> y is F = first d terms."""
    law = _mv_law()
    resp = closed_loop(_siso(), law.feedback())[("a", "y")]
    h = resp.impulse(40)
    expected = C_POLE ** np.arange(DELAY)  # first d terms of 1/(1 - c q^-1)
    assert np.allclose(h[:DELAY], expected, atol=1e-12)
    assert np.allclose(h[DELAY:], 0.0, atol=1e-10)


def test_harris_index_of_minimum_variance_loop_is_one():
    run = simulate(_siso(), LinearFeedback(_mv_law()), 5000, np.random.default_rng(11))
    res = harris_index(run.measured["y"], DELAY)
    assert res.index == pytest.approx(1.0, abs=0.1)
    assert res.ci[0] <= 1.0
    # the minimum variance itself: sigma_e^2 (1 + c^2 + c^4)
    assert res.sigma2_mv == pytest.approx(1.0 + C_POLE**2 + C_POLE**4, rel=0.1)


def _pi_process() -> CascadeProcessConfig:
    # integrated disturbance 1/((1 - 0.5 q^-1)(1 - q^-1)) so that the PI loop is invertible
    return _siso(noise_den=tuple(np.convolve([1.0, -0.5], [1.0, -1.0])))


@pytest.mark.parametrize("kc, ti", [(0.3, 10.0), (1.0, 5.0), (2.0, 20.0)])
def test_harris_index_matches_analytic_closed_loop(kc, ti):
    proc = _pi_process()
    cfg = SFBPIConfig(measurement="y", Kc=kc, Ti=ti)
    h = closed_loop(proc, cfg.feedback())[("a", "y")].impulse()
    assert h[0] == pytest.approx(1.0)
    eta_true = float(np.sum(h[:DELAY] ** 2) / np.sum(h**2))
    run = simulate(proc, SFBPI(cfg), 8000, np.random.default_rng(5))
    res = harris_index(run.measured["y"], DELAY)
    assert res.index == pytest.approx(eta_true, abs=max(0.05, 3 * res.std))
    assert res.model_index == pytest.approx(eta_true, abs=max(0.05, 3 * res.std))
    assert eta_true < 0.95  # a PI is not minimum variance here: the test can fail


def test_delta_and_bootstrap_uncertainty_agree_with_the_spread_over_runs():
    proc = _pi_process()
    cfg = SFBPIConfig(measurement="y", Kc=0.3, Ti=10.0)
    estimates, deltas = [], []
    for seed in range(8):
        run = simulate(proc, SFBPI(cfg), 3000, np.random.default_rng(100 + seed))
        r = harris_index(run.measured["y"], DELAY)
        estimates.append(r.index)
        deltas.append(r.std)
    spread = float(np.std(estimates, ddof=1))
    assert 0.4 < np.mean(deltas) / spread < 2.5
    boot = harris_index(
        run.measured["y"], DELAY, uncertainty="bootstrap", n_boot=100, rng=np.random.default_rng(3)
    )
    assert 0.5 < boot.std / deltas[-1] < 2.0
    assert boot.ci[0] < boot.index < boot.ci[1]


def test_bootstrap_is_reproducible_and_needs_a_generator():
    run = simulate(
        _pi_process(),
        SFBPI(SFBPIConfig(measurement="y", Kc=0.3, Ti=10.0)),
        2000,
        np.random.default_rng(1),
    )
    y = run.measured["y"]
    a = harris_index(y, DELAY, uncertainty="bootstrap", n_boot=30, rng=np.random.default_rng(7))
    b = harris_index(y, DELAY, uncertainty="bootstrap", n_boot=30, rng=np.random.default_rng(7))
    assert a.std == b.std and a.ci == b.ci
    with pytest.raises(ValueError, match="rng"):
        harris_index(y, DELAY, uncertainty="bootstrap")


def test_model_index_of_known_ar1():
    # AR(1) with pole phi: psi_i = phi^i, sum = 1/(1 - phi^2)
    phi, d = 0.7, 2
    assert model_index(np.array([phi]), d) == pytest.approx((1 + phi**2) * (1 - phi**2))
    assert math.isnan(model_index(np.array([1.01]), d))


def test_fit_var_recovers_a_known_var1():
    rng = np.random.default_rng(2)
    a = np.array([[0.5, 0.2], [-0.3, 0.4]])
    y = np.zeros((20000, 2))
    e = rng.standard_normal((20000, 2)) * [1.0, 0.5]
    for t in range(1, y.shape[0]):
        y[t] = a @ y[t - 1] + e[t]
    for method in ("ls", "yule_walker"):
        m = fit_var(y, order=1, method=method)
        assert np.allclose(m.coefs[0], a, atol=0.03)
        assert np.allclose(np.diag(m.sigma), [1.0, 0.25], rtol=0.05)
    m = fit_var(y, max_order=8, criterion="bic")
    assert m.order == 1


@pytest.mark.parametrize(
    "y, delay, reason",
    [
        (np.full(2000, 3.0), 3, "constant"),
        (np.r_[np.ones(10), np.nan, np.zeros(1989)], 3, "not_finite"),
        (np.random.default_rng(0).standard_normal(100), 3, "too_short"),
        (np.random.default_rng(0).standard_normal(2000), 0, "bad_delay"),
        (np.cumsum(np.random.default_rng(0).standard_normal(5000)), 3, "unstable_model"),
    ],
)
def test_harris_refusals_name_the_reason(y, delay, reason):
    with pytest.raises(IdentificationError) as exc:
        harris_index(y, delay, name="PV")
    assert exc.value.reason == reason
