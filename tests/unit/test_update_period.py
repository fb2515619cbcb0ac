"""Maximum allowable update period (seed 001, sec. IV-V): Lambda, M(h), h_max, paper results."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from scipy.linalg import expm
from scipy.optimize import brentq

from agents.update_period.analysis import (
    PAPER_H_MAX,
    PAPER_H_MAX_ZOH,
    CSTRRecycleCase,
    UpdatePeriodConfig,
    build_lambda,
    find_h_max,
    rho_curves,
    rho_map,
    rho_map_observer_pole,
    spectral_radius,
    test_matrix,
)
from controllers.qdc.design import LinearUnits, QDCDesign
from controllers.qdc.model import closed_loop_matrices, simulate_linear
from controllers.qdc.network import CentralizedNetwork, QDCNetwork

CASE = CSTRRecycleCase()
H_MAX = CASE.h_max("qdc").h_max
H_MAX_ZOH = CASE.h_max("qdc_zoh").h_max
O2 = np.zeros((2, 2))


def _paper_lambda(plant, gains, model, zoh=False):
    """The two-unit blocks Lambda_11 ... Lambda_33 exactly as printed in seed 001 section V."""
    A1, A2, A12, A21 = plant.a(0, 0), plant.a(1, 1), plant.a(0, 1), plant.a(1, 0)
    B1, B2 = plant.b(0), plant.b(1)
    (K1, K12), (K21, K2) = gains.K
    L1C1, L2C2 = gains.L[0] @ plant.c(0), gains.L[1] @ plant.c(1)
    Ab1, Ab2 = A1 + B1 @ K1, A2 + B2 @ K2
    Ab12, Ab21 = A12 + B1 @ K12, A21 + B2 @ K21
    H1, H2 = Ab1 - L1C1, Ab2 - L2C2
    if zoh:
        At1 = At2 = At12 = At21 = O2
    else:
        At1 = model.a(0, 0) + model.b(0) @ K1
        At2 = model.a(1, 1) + model.b(1) @ K2
        At12 = model.a(0, 1) + model.b(0) @ K12
        At21 = model.a(1, 0) + model.b(1) @ K21
    L11 = np.block([[A1, A12], [A21, A2]])
    L12 = np.block([[B1 @ K1, B1 @ K12], [B2 @ K21, B2 @ K2]])
    L13 = np.block([[O2, O2, -B1 @ K12, O2], [O2, -B2 @ K21, O2, O2]])
    L21 = np.block([[L1C1, O2], [O2, L2C2]])
    L22 = np.block([[H1, Ab12], [Ab21, H2]])
    L23 = np.block([[O2, O2, -Ab12, O2], [O2, -Ab21, O2, O2]])
    L31 = np.block([[O2, O2], [L1C1, O2], [O2, L2C2], [O2, O2]])
    L32 = np.block([[O2, O2], [H1 - At1, Ab12 - At12], [Ab21 - At21, H2 - At2], [O2, O2]])
    L33 = np.block(
        [
            [O2, O2, O2, O2],
            [O2, At1, -Ab12, O2],
            [O2, -Ab21, At2, O2],
            [O2, O2, O2, O2],
        ]
    )
    return np.block([[L11, L12, L13], [L21, L22, L23], [L31, L32, L33]])


# -- Lambda and M(h) -----------------------------------------------------------------------------


@pytest.mark.parametrize("delta1", [0.0, 0.25])
@pytest.mark.parametrize("zoh", [False, True])
def test_lambda_equals_the_blocks_printed_in_section_v(delta1, zoh):
    model = CASE.model(delta1)
    got = build_lambda(CASE.plant, CASE.gains, model=model, scheme="zoh" if zoh else "model")
    assert got.k == 8 and got.Lambda.shape == (16, 16)
    assert_allclose(got.Lambda, _paper_lambda(CASE.plant, CASE.gains, model, zoh), atol=1e-9)


def test_lambda_with_coupling_not_cancelled_still_matches_the_paper_blocks():
    """With K_ij = O the blocks Abar_ij are non-zero: exercises Lambda_23 and Lambda_33 fully."""
    gains = CASE.design.model_copy(update={"cancel_coupling": False}).gains()
    model = CASE.model(0.1)
    got = build_lambda(CASE.plant, gains, model=model)
    assert_allclose(got.Lambda, _paper_lambda(CASE.plant, gains, model), atol=1e-9)


@pytest.mark.parametrize(
    "arch, make",
    [
        ("qdc", lambda m: QDCNetwork(CASE.plant, CASE.gains, model=m)),
        ("qdc_zoh", lambda m: QDCNetwork(CASE.plant, CASE.gains, model=m, scheme="zoh")),
        ("qdc_state", lambda m: QDCNetwork(CASE.plant, CASE.gains, model=m, feedback="state")),
        ("centralized", lambda m: CentralizedNetwork(CASE.plant, CASE.gains, model=m)),
        (
            "centralized_plant_observer",
            lambda m: CentralizedNetwork(CASE.plant, CASE.gains, model=m, observer="plant"),
        ),
    ],
)
def test_spectral_radius_equals_the_monodromy_of_the_implemented_controllers(arch, make):
    """rho(M(h)) from the (x, xbar, e) formulation vs the reset-flow map of the controller
    classes in (x, z) coordinates (built independently from eq. (4))."""
    for delta1 in (0.0, 0.3, -0.2):
        net = make(CASE.model(delta1))
        acl, rcl = closed_loop_matrices(CASE.plant, net)
        hs = np.array([0.005, 0.02, 0.043, 0.07])
        want = [np.max(np.abs(np.linalg.eigvals(rcl @ expm(acl * h)))) for h in hs]
        got = spectral_radius(CASE.system(arch, delta1), hs)
        assert_allclose(got, want, rtol=1e-8)


def test_test_matrix_zeroes_the_errors_and_shares_the_spectral_radius():
    system = CASE.system("qdc", 0.1)
    m = test_matrix(system, 0.03)
    assert m.shape == (16, 16)
    assert_allclose(m[8:, :], 0.0)
    assert_allclose(m[:, 8:], 0.0)
    assert_allclose(np.max(np.abs(np.linalg.eigvals(m))), spectral_radius(system, 0.03), rtol=1e-10)


# -- brute force: the switched system decays iff rho(M(h)) < 1 -----------------------------------


def _brute_force(arch_net, arch, delta1, factors, h_ref, n_periods=1500):
    x0 = np.array([1.0, 0.01, -1.0, 0.01])
    system = CASE.system(arch, delta1)
    for f in factors:
        h = f * h_ref
        rho = spectral_radius(system, h)
        run = simulate_linear(CASE.plant, arch_net, h, x0, n_periods)
        rate = run.growth_rate()
        assert (rate < 0) == (rho < 1), (arch, delta1, h, rho, rate)
        if abs(f - 1.0) > 0.2:  # away from h_max the decay rate is rho's (transients die out)
            assert rate == pytest.approx(np.log(rho), rel=0.1, abs=1e-3)


def test_brute_force_simulation_agrees_with_the_spectral_radius_exact_model():
    factors = (0.3, 0.5, 0.7, 0.85, 0.93, 0.97, 1.03, 1.07, 1.15, 1.3, 1.6, 2.0)
    assert sum(f < 1 for f in factors) >= 5 and sum(f > 1 for f in factors) >= 5
    _brute_force(QDCNetwork(CASE.plant, CASE.gains), "qdc", 0.0, factors, H_MAX)


def test_brute_force_simulation_agrees_zero_order_hold_and_mismatch():
    factors = (0.5, 0.9, 0.97, 1.03, 1.1, 1.5)
    _brute_force(
        QDCNetwork(CASE.plant, CASE.gains, scheme="zoh"), "qdc_zoh", 0.0, factors, H_MAX_ZOH
    )
    model = CASE.model(0.2)
    h_ref = CASE.h_max("qdc", 0.2).h_max
    _brute_force(QDCNetwork(CASE.plant, CASE.gains, model=model), "qdc", 0.2, factors, h_ref)


# -- h_max -----------------------------------------------------------------------------------------


def test_h_max_exact_model_and_zero_order_hold_match_the_paper():
    assert abs(H_MAX - PAPER_H_MAX) <= 0.002
    assert abs(H_MAX_ZOH - PAPER_H_MAX_ZOH) <= 0.002
    for arch, h in (("qdc", H_MAX), ("qdc_zoh", H_MAX_ZOH)):
        assert spectral_radius(CASE.system(arch), h) == pytest.approx(1.0, abs=1e-7)
        result = CASE.h_max(arch, config=UpdatePeriodConfig(h_hi=1.0, n_grid=500))
        assert result.crossings[0] == pytest.approx(h, abs=1e-7)
        assert len(result.crossings) == 1  # single crossing for the CSTRs on (0, 1] h


def test_find_h_max_returns_the_first_crossing_of_a_non_monotone_radius():
    def rho(h):  # stable, unstable on (0.125, 0.375), stable again, unstable again ...
        return 0.5 + np.sin(2 * np.pi * np.asarray(h)) ** 2

    r = find_h_max(rho, UpdatePeriodConfig(h_hi=1.0, n_grid=97))
    assert r.h_max == pytest.approx(0.125, abs=1e-8)
    assert_allclose(r.crossings, [0.125, 0.375, 0.625, 0.875], atol=1e-8)
    # a plain bisection between a stable and an unstable end would find a later crossing
    assert brentq(lambda h: rho(h) - 1, 0.01, 0.7) != pytest.approx(0.125, abs=1e-3)


def test_find_h_max_special_cases():
    cfg = UpdatePeriodConfig(h_hi=1.0, n_grid=50)
    assert find_h_max(lambda h: np.full(np.shape(h), 0.9), cfg).h_max == np.inf
    r = find_h_max(lambda h: 1.0 + np.asarray(h), cfg, continuous_stable=False)
    assert r.h_max == 0.0 and not r.continuous_stable
    # unstable already at the first grid point but stable for h -> 0: refined below it
    r = find_h_max(
        lambda h: 1.0 - np.asarray(h) + 1e3 * np.asarray(h) ** 2, cfg, continuous_stable=True
    )
    assert r.h_max == pytest.approx(1e-3, rel=1e-6)


def test_state_feedback_with_exact_model_has_no_finite_h_max():
    """Fig. 2(b) vs 2(a): rho(M(h)) = exp(-h) (slowest pole -1) for every h."""
    cfg = UpdatePeriodConfig(h_hi=1.0, n_grid=500)
    r = CASE.h_max("qdc_state", 0.0, cfg)
    assert r.h_max == np.inf
    assert_allclose(r.rho_grid, np.exp(-r.h_grid), rtol=1e-6)
    assert np.isfinite(CASE.h_max("qdc", 0.0, cfg).h_max)
    assert np.isfinite(CASE.h_max("qdc_state", 0.3, cfg).h_max)  # a mismatch limits it again


# -- qualitative results of section V --------------------------------------------------------------


def test_zero_order_hold_tolerates_a_shorter_period_than_an_accurate_model():
    assert H_MAX_ZOH < H_MAX
    for d in (0.05, 0.1):
        assert CASE.h_max("qdc_zoh", d).h_max < CASE.h_max("qdc", d).h_max
    # ... but with a large mismatch the hold outperforms the model-based scheme (Fig. 3(a))
    for d in (0.3, 0.5, -0.1, -0.3):
        assert CASE.h_max("qdc_zoh", d).h_max > CASE.h_max("qdc", d).h_max


def _tolerable(rho_column, deltas):
    ok = deltas[rho_column < 1.0]
    assert ok.size, "no tolerable mismatch"
    # one interval on the grid (no holes)
    idx = np.nonzero(rho_column < 1.0)[0]
    assert np.all(np.diff(idx) == 1)
    return ok.min(), ok.max()


def test_tolerable_mismatch_shrinks_as_the_update_period_grows():
    deltas = np.linspace(-1.0, 1.0, 201)
    hs = np.array([0.005, 0.01, 0.02, 0.03, 0.04, 0.045])
    rho = rho_map(CASE, hs, deltas, "qdc")
    intervals = [_tolerable(rho[:, j], deltas) for j in range(hs.size)]
    for (lo0, hi0), (lo1, hi1) in zip(intervals, intervals[1:], strict=False):
        assert lo0 <= lo1 and hi1 <= hi0  # nested
        assert hi1 - lo1 < hi0 - lo0  # and strictly narrower
    assert intervals[-1][1] - intervals[-1][0] < 0.1


def test_quasi_decentralized_tolerates_larger_periods_than_centralized_for_large_mismatch():
    """Fig. 2(a) vs 2(c): for |delta1| large the centralized structure (observer built from the
    model, ref. [24]) has no stabilizing period at all, the quasi-decentralized one has."""
    for d in (-0.5, -0.3, 0.3, 0.5, 1.0):
        qdc = CASE.h_max("qdc", d).h_max
        cen = CASE.h_max("centralized", d).h_max
        assert qdc > 0.005 and qdc > cen
    # and the stability region on a (delta1, h) window is larger
    hs = np.linspace(0.002, 0.06, 30)
    deltas = np.linspace(-0.5, 0.5, 41)
    area_q = np.mean(rho_map(CASE, hs, deltas, "qdc") < 1)
    area_c = np.mean(rho_map(CASE, hs, deltas, "centralized") < 1)
    assert area_q > 1.5 * area_c


def test_observer_pole_fig_4_points():
    """Fig. 4(c)-(d): at h = 0.04 hr and delta1 = 0.1 the loop is stable with lambda_12 = -25
    and unstable with lambda_12 = -20.8; the tolerable mismatch grows as lambda_12 decreases."""
    rho = rho_map_observer_pole(CASE, [-25.0, -20.8], [0.1], h=0.04)[0]
    assert rho[0] < 1.0 < rho[1]
    deltas = np.linspace(-0.2, 0.6, 81)
    lams = np.array([-22.0, -30.0, -40.0])
    rmap = rho_map_observer_pole(CASE, lams, deltas, h=0.04)
    widths = [np.ptp(_tolerable(rmap[:, j], deltas)) for j in range(lams.size)]
    assert widths[0] < widths[1] < widths[2]


def test_rho_curves_keys_and_zoh_independent_of_delta():
    hs = np.linspace(0.01, 0.05, 5)
    curves = rho_curves(CASE, hs, (0.0, 0.2))
    assert set(curves) == {"delta1=0", "delta1=0.2", "zoh"}
    assert_allclose(curves["zoh"], spectral_radius(CASE.system("qdc_zoh", 0.7), hs))


def test_h_max_does_not_depend_on_a_diagonal_scaling_of_states_and_inputs():
    """The paper's 'dimensionless' variables are unstated; a diagonal rescaling is harmless."""
    s = [np.diag([1 / 400.0, 1 / 2.0]), np.diag([1 / 400.0, 1 / 2.0])]  # x_new = S x
    d = [np.diag([1e-4, 0.25]), np.diag([1e-4, 0.5])]  # u_new = D u
    p = CASE.plant
    si = [np.linalg.inv(m) for m in s]
    scaled = LinearUnits.from_arrays(
        [[s[i] @ p.a(i, j) @ si[j] for j in range(2)] for i in range(2)],
        [s[i] @ p.b(i) @ np.linalg.inv(d[i]) for i in range(2)],
        [p.c(i) @ si[i] * 0.01 for i in range(2)],  # outputs rescaled too
    )
    gains = QDCDesign(plant=scaled).gains()
    h = find_h_max(build_lambda(scaled, gains)).h_max
    assert h == pytest.approx(H_MAX, rel=1e-6)


@pytest.mark.parametrize("h", [0.0, -0.02, [0.01, 0.0]])
def test_non_positive_update_period_is_refused(h):
    system = CASE.system("qdc")
    with pytest.raises(ValueError, match=r"\bh\b.*> 0"):
        spectral_radius(system, h)
    if np.ndim(h) == 0:
        with pytest.raises(ValueError, match=r"\bh\b"):
            test_matrix(system, h)


def test_search_config_is_validated():
    with pytest.raises(ValidationError, match="h_hi"):
        UpdatePeriodConfig(h_hi=0.0)
    with pytest.raises(ValueError, match="h_hi = 5.0 exceeds"):
        CASE.h_max("qdc", config=UpdatePeriodConfig(h_hi=5.0))
    with pytest.raises(ValidationError, match="n_grid"):
        UpdatePeriodConfig(n_grid=1)
