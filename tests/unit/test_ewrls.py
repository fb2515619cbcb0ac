"""EW-RLS of seed 002 eq. (16)-(19), the tank estimator and the self-tuning non-linear PI."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from controllers.ewrls import EWRLS, SelfTuningNLPI, STNLPIConfig, TankEstimator
from controllers.nlpi import NLPIConfig, NonlinearPI
from plants.integrate import rk4
from plants.tank import RIG_PARAMS, SIM_PARAMS, Tank, TankParams
from tests.unit.test_nlpi import (
    closed_loop,
    disturbance,
    disturbance_peaks,
    staircase,
    step_figures,
)

SIM = Tank(SIM_PARAMS)
TRUE = np.array((SIM_PARAMS.b, SIM_PARAMS.a_prime))
SPEC = {"overshoot_pct": 4.321, "settling_time": 13.0}


def st_law(plant: Tank = SIM, tau_s: float = 0.05, **kw) -> SelfTuningNLPI:
    return SelfTuningNLPI.from_config(STNLPIConfig(**SPEC, **kw), plant=plant, tau_s=tau_s)


def estimates(law: SelfTuningNLPI) -> tuple[float, float, float]:
    return law.b, law.a_prime, float(law.estimator.updated)


# -- the generic estimator ----------------------------------------------------------------------
def test_ewrls_recovers_a_linear_model_like_least_squares():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(200, 3))
    beta = np.array([1.5, -0.7, 3.0])
    y = X @ beta + 0.01 * rng.normal(size=200)
    est = EWRLS(np.zeros(3), 1e6, 1.0)
    for x, yk in zip(X, y, strict=True):
        est.update(x, yk)
    # independent: batch least squares (the 1e-6 prior is negligible)
    ls = np.linalg.lstsq(X, y, rcond=None)[0]
    assert est.beta == pytest.approx(ls, abs=1e-6)


def test_ewrls_forgetting_is_exponentially_weighted_least_squares():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(100, 2))
    y = X @ np.array([2.0, 1.0]) + rng.normal(size=100)
    lam = 0.9
    est = EWRLS(np.zeros(2), 1e8, lam)
    for x, yk in zip(X, y, strict=True):
        est.update(x, yk)
    w = np.sqrt(lam ** np.arange(99, -1, -1))
    wls = np.linalg.lstsq(X * w[:, None], y * w, rcond=None)[0]
    assert est.beta == pytest.approx(wls, rel=1e-6)


def test_ewrls_tracks_a_change_with_forgetting():
    rng = np.random.default_rng(3)
    est = EWRLS(np.zeros(2), 100.0, 0.95)
    for k in range(400):
        beta = np.array([1.0, 2.0]) if k < 200 else np.array([1.5, 1.0])
        x = rng.normal(size=2)
        est.update(x, x @ beta)
    assert est.beta == pytest.approx([1.5, 1.0], abs=1e-3)  # old data weigh 0.95^200


def test_ewrls_guards_division_and_nan():
    est = EWRLS((1.0, 1.0), 10.0, 0.99)
    before = est.beta.copy(), est.P.copy()
    assert math.isnan(est.update([math.nan, 1.0], 0.0))
    assert math.isnan(est.update([math.inf, 1.0], 0.0))
    assert math.isnan(est.update([1.0, 1.0], math.inf))
    assert est.n_skipped == 3
    assert np.array_equal(est.beta, before[0]) and np.array_equal(est.P, before[1])
    tiny = EWRLS((0.0,), 1e-30, 1e-30)  # lambda + x P x below eps: skipped, no division
    assert math.isnan(tiny.update([1.0], 1.0))


def test_ewrls_covariance_reset_bounds_windup():
    est = EWRLS((0.0, 0.0), 1.0, 0.8, p_max=50.0)
    for _ in range(100):  # one direction only: P winds up along the other
        est.update([1.0, 0.0], 2.0)
        assert np.trace(est.P) <= 50.0
    assert est.n_resets > 0
    assert est.beta[0] == pytest.approx(2.0)
    est.reset_covariance(3.0)
    assert np.array_equal(est.P, 3.0 * np.eye(2))


def test_ewrls_refuses_bad_settings():
    for lam in (0.0, -0.5, 1.01):
        with pytest.raises(ValueError, match="forgetting"):
            EWRLS((0.0,), 1.0, lam)
    with pytest.raises(ValueError, match="p0"):
        EWRLS((0.0, 0.0), -1.0)


# -- the tank estimator -------------------------------------------------------------------------
def test_tank_estimator_holds_without_excitation():
    est = TankEstimator(3.0, 0.25, tau_ref=0.05, window=0.0, excitation_min=1e-3)
    u_eq = SIM.equilibrium({"h": 100.0})[1][0]
    for k in range(200):  # rest: every regressor is the same
        assert not est.update(0.05 * k, 100.0, u_eq if k else None)
    assert (est.b, est.a_prime) == (3.0, 0.25)
    assert est.excitation < 1e-12
    assert est.update(10.0, 100.0, u_eq) is False and est.update(10.0, 100.0, u_eq) is False


def test_tank_estimator_open_loop_identifies_exactly():
    # open-loop fill and drain with a varying pump command, noise-free
    est = TankEstimator(1.0, 1.0, tau_ref=0.1, window=0.5, change_error=None)
    x = np.array([20.0])

    u_prev = None
    for k in range(1500):
        t = 0.1 * k
        est.update(t, float(x[0]), u_prev)
        u = 2.0 + 1.5 * math.sin(0.05 * t) + 0.5 * math.sin(0.31 * t)
        x = rk4(SIM.rhs, t, x, t + 0.1, np.array([u, 0.0]), max_step=0.05)
        u_prev = u
    # within the pull of the weak prior P0 = 100 I towards the guess (1, 1)
    assert (est.b, est.a_prime) == pytest.approx(TRUE, rel=1e-3)


# -- the self-tuning law on the simulated tank --------------------------------------------------
STUDY_R = staircase((50.0, 100.0, 150.0), (0.0, 50.0, 100.0))


@pytest.mark.parametrize("b0, a0", [(3.0, 0.25), (1.0, 0.75), (3.0, 0.75), (1.0, 0.25)])
def test_converges_from_a_50_percent_wrong_guess(b0, a0):
    law = st_law(b0=b0, a_prime0=a0)
    run = closed_loop(SIM, law, ts=0.05, t_end=150.0, r=STUDY_R, probe=estimates)
    est = run["probe"][:, :2]
    err = np.abs(est / TRUE - 1.0)
    assert np.all(err[-1] < 0.02)
    assert np.all(err[run["t"] >= 20.0] < 0.02)  # within the first set-point step
    assert law.estimator.n_changes == 0
    # later steps meet the specification
    for t0, r0, r1 in ((50.0, 50.0, 100.0), (100.0, 100.0, 150.0)):
        overshoot, settling = step_figures(run["t"], run["h"], t0, t0 + 50.0, r0, r1)
        assert overshoot == pytest.approx(4.3, abs=0.5)
        assert settling == pytest.approx(13.0, abs=1.5)


def test_with_noise_during_steps_estimates_and_their_ratio_converge():
    law = st_law(b0=3.0, a_prime0=0.25)
    rng = np.random.default_rng(11)
    run = closed_loop(
        SIM, law, ts=0.05, t_end=150.0, r=STUDY_R, noise=0.5, rng=rng, probe=estimates
    )
    b, a = run["probe"][-1, :2]
    assert b / a == pytest.approx(4.0, rel=0.01)
    assert (b, a) == pytest.approx(TRUE, rel=0.02)
    assert law.estimator.n_changes == 0  # noise is not taken for a change of the plant


def test_small_unmeasured_draw_offs_bias_the_estimates_little():
    # eq. (3a) has no disturbance term; 0.2 mm/s is 4 % of the outflow at 100 mm
    law = st_law()
    run = closed_loop(
        SIM, law, ts=0.05, t_end=150.0, r=STUDY_R, q_d=disturbance(0.2), probe=estimates
    )
    assert np.all(np.abs(run["probe"][:, :2] / TRUE - 1.0) < 0.07)
    peaks = disturbance_peaks(run)
    assert np.max(peaks) / np.min(peaks) - 1.0 < 0.10
    for t0, r0, r1 in ((0.0, 0.0, 50.0), (50.0, 50.0, 100.0), (100.0, 100.0, 150.0)):
        assert step_figures(run["t"], run["h"], t0, t0 + 25.0, r0, r1)[0] == pytest.approx(
            4.3, abs=1.0
        )


def run_at_rest(noise: float, **kw) -> tuple[dict[str, np.ndarray], SelfTuningNLPI]:
    law = st_law(**kw)
    rng = np.random.default_rng(2)
    run = closed_loop(
        SIM,
        law,
        ts=0.05,
        t_end=500.0,
        r=lambda t: 100.0,
        h0=100.0,
        noise=noise,
        rng=rng,
        probe=estimates,
    )
    return run, law


def test_at_rest_with_noise_only_the_ratio_is_identifiable():
    # without the excitation hold, 500 s of noisy rest: b and a' wander together, b/a' does not
    run, _ = run_at_rest(0.5, excitation_min=0.0)
    b, a = run["probe"][:, 0], run["probe"][:, 1]
    assert np.max(np.abs(b / 2.0 - 1.0)) > 0.2
    assert np.max(np.abs(a / 0.5 - 1.0)) > 0.2
    assert np.max(np.abs((b / a) / 4.0 - 1.0)) < 0.05
    # the loop stays safe: the linearizing term depends on the ratio only
    assert np.max(np.abs(run["h"] - 100.0)) < 1.0
    assert np.all(np.isfinite(run["u"])) and np.min(run["u"]) >= 0.0


def test_at_rest_with_noise_the_hold_keeps_the_estimates():
    run, law = run_at_rest(0.5)
    assert np.all(run["probe"][:, 0] == 2.0) and np.all(run["probe"][:, 1] == 0.5)
    assert law.estimator.n_changes == 0
    assert np.max(np.abs(run["h"] - 100.0)) < 1.0


def test_projection_keeps_estimates_in_range():
    run, _ = run_at_rest(0.5, excitation_min=0.0, param_range=1.5, forgetting=0.99)
    est = run["probe"][:, :2]
    assert np.all(est >= TRUE / 1.5 - 1e-12) and np.all(est <= TRUE * 1.5 + 1e-12)
    assert np.all(np.isfinite(run["u"]))


# -- a change of the plant mid-run --------------------------------------------------------------
CHANGE_R = staircase((50.0, 100.0, 150.0, 50.0, 100.0, 150.0), (0, 50, 100, 150, 200, 250))


def run_with_change(law, new: TankParams, noise: float = 0.0) -> dict[str, np.ndarray]:
    after = Tank(new)
    rng = np.random.default_rng(3)
    return closed_loop(
        lambda t: SIM if t < 75.0 else after,
        law,
        ts=0.05,
        t_end=300.0,
        r=CHANGE_R,
        noise=noise,
        rng=rng,
        probe=estimates,
    )


def last_steps(run: dict[str, np.ndarray]) -> list[tuple[float, float]]:
    return [
        step_figures(run["t"], run["h"], t0, t0 + 50.0, r0, r1)
        for t0, r0, r1 in ((100.0, 100.0, 150.0), (200.0, 50.0, 100.0), (250.0, 100.0, 150.0))
    ]


@pytest.mark.parametrize("noise", [0.0, 0.1])
def test_reconverges_after_a_step_of_a_prime(noise):
    new = TankParams(b=2.0, a_prime=0.75)  # the outlet opened by 50 % at 75 s, at 100 mm
    law = st_law(b0=3.0, a_prime0=0.25)
    run = run_with_change(law, new, noise)
    est = run["probe"][:, :2]
    assert est[-1] == pytest.approx((2.0, 0.75), rel=0.02)
    assert law.estimator.n_changes == 1
    # no collapse of the estimates after the change (see the next test)
    after = est[run["t"] >= 75.0]
    assert np.min(after[:, 0]) > 1.2 and np.min(after[:, 1]) > 0.45
    for overshoot, settling in last_steps(run):
        assert overshoot == pytest.approx(4.3, abs=0.5)
        assert settling == pytest.approx(13.0, abs=1.5)


def test_without_change_detection_the_estimates_collapse_after_the_change():
    # old and new steady states are inconsistent homogeneous constraints: b, a' -> 0 together
    law = st_law(b0=3.0, a_prime0=0.25, change_error=None)
    run = run_with_change(law, TankParams(b=2.0, a_prime=0.75))
    after = run["probe"][run["t"] >= 75.0, :2]
    assert np.min(after[:, 0]) < 1.0 and np.min(after[:, 1]) < 0.3
    overshoot, _ = last_steps(run)[0]
    assert overshoot < 4.3 - 0.5  # the first step after the change misses the design
    assert run["probe"][-1, :2] == pytest.approx((2.0, 0.75), rel=0.02)  # and recovers later


def test_after_a_step_of_b_the_self_tuning_law_keeps_the_design_and_the_fixed_one_does_not():
    new = TankParams(b=1.2, a_prime=0.5)  # pump wear: 40 % less flow per unit command
    law = st_law()
    run = run_with_change(law, new)
    assert run["probe"][-1, :2] == pytest.approx((1.2, 0.5), rel=0.02)
    st = last_steps(run)
    fixed_law = NonlinearPI.from_config(NLPIConfig(**SPEC), plant=SIM)
    fixed = last_steps(
        closed_loop(
            lambda t: SIM if t < 75.0 else Tank(new), fixed_law, ts=0.05, t_end=300.0, r=CHANGE_R
        )
    )
    for overshoot, settling in st:
        assert overshoot == pytest.approx(4.3, abs=0.5)
        assert settling == pytest.approx(13.0, abs=1.5)
    for overshoot, _ in fixed[1:]:
        assert overshoot > 4.3 + 3.0  # the loop gain fell to 0.6: zeta 0.55


def test_self_tuning_on_the_rig():
    rig = Tank(RIG_PARAMS)
    law = SelfTuningNLPI.from_config(
        STNLPIConfig(overshoot_pct=4.321, settling_time=100.0, b0=0.0183, a_prime0=0.002485),
        plant=rig,
        tau_s=1.0,
    )
    r = staircase((0.5, 1.0, 0.5, 1.0), (0.0, 250.0, 500.0, 750.0))
    run = closed_loop(rig, law, ts=1.0, t_end=1000.0, r=r, max_step=0.25, probe=estimates)
    assert run["probe"][-1, :2] == pytest.approx((0.0122, 0.00497), rel=0.02)
    overshoot, settling = step_figures(run["t"], run["h"], 750.0, 1000.0, 0.5, 1.0)
    assert overshoot == pytest.approx(4.3, abs=1.5)
    assert settling == pytest.approx(100.0, abs=15.0)


# -- configuration ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"forgetting": 0.0}, "forgetting"),
        ({"forgetting": 1.5}, "forgetting"),
        ({"forgetting": -0.2}, "forgetting"),
        ({"b0": -1.0}, "b0"),
        ({"a_prime0": -0.5}, "a_prime0"),
        ({"settling_time": -1.0}, "settling_time"),
        ({"overshoot_pct": 100.0}, "overshoot_pct"),
        ({"p0": 0.0}, "p0"),
        ({"excitation_min": 0.7}, "excitation_min"),
        ({"param_range": 1.0}, "param_range"),
    ],
)
def test_bad_configuration_is_refused_naming_the_field(kwargs, field):
    with pytest.raises(ValidationError, match=field):
        STNLPIConfig(**{**SPEC, **kwargs})


def test_forgetting_one_is_allowed_and_defaults_follow_the_design():
    assert STNLPIConfig(**SPEC, forgetting=1.0).forgetting == 1.0
    assert STNLPIConfig(**SPEC).type == "stnlpi"
    law = st_law()
    est = law.estimator
    assert est.rls.forgetting == pytest.approx(math.exp(-0.05 / 26.0))
    assert est.window == pytest.approx(13.0 / 4) and est.change_time == pytest.approx(1.3)
    assert (law.b, law.a_prime) == (2.0, 0.5)
    with pytest.raises(ValueError, match="'b'"):
        SelfTuningNLPI.from_config(STNLPIConfig(**SPEC), plant=object(), tau_s=0.05)


def test_reset_goes_back_to_the_guesses():
    law = st_law(b0=3.0, a_prime0=0.25)
    closed_loop(SIM, law, ts=0.05, t_end=20.0, r=STUDY_R)
    assert law.b != 3.0
    law.reset()
    assert (law.b, law.a_prime) == (3.0, 0.25) and law.pi.integral == 0.0
