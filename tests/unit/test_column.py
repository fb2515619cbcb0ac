"""The column of seed 003 (appendix C), its steady state (Table 3.2) and its reduced model (4.3)."""

from __future__ import annotations

import control  # noqa: TID253 - not a node; balred uses slycot, a dev dependency
import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from scipy.linalg import solve_continuous_lyapunov
from scipy.optimize import fsolve

from plants.column import (
    APPENDIX_E_A,
    APPENDIX_E_B,
    APPENDIX_E_C,
    FITTED_PARAMS,
    SECTION_631_SPREAD,
    TABLE_3_2_X,
    TABLE_3_2_Y,
    THESIS_A_M,
    THESIS_B_M,
    THESIS_C_M,
    THESIS_PARAMS,
    Column,
    ColumnParams,
    PerturbedReducedPlant,
    appendix_g_signs,
    balanced_reduction,
    printed_model_rhs,
)
from plants.integrate import rk4

TAB = np.array(TABLE_3_2_X)
EIG_THESIS = np.array([-6.5832, -0.4606])  # section 4.3.1
COLUMN = Column(FITTED_PARAMS)
X_FIT = COLUMN.steady_state()
U_FIT = COLUMN.nominal_input()


def _vle(x):
    return 5.68 * x / (1.0 + 4.68 * x)


def _c6_rhs(x, lr, vb, *, lf, vf, xf, d=None, b=None, md=14.03, m=5.80, mb=24.88):
    """The per-tray list of appendix C.6 written out stage by stage, without the class."""
    y = _vle(np.asarray(x, dtype=float))
    yf = _vle(xf)
    d = vb + vf - lr if d is None else d
    b = lr + lf - vb if b is None else b
    dx = np.zeros(16)
    dx[15] = ((vb + vf) * y[14] - lr * x[15] - d * x[15]) / md  # condenser, n = 16
    for n in range(10, 16):  # trays 9 .. 14
        i = n - 1
        dx[i] = ((vb + vf) * (y[i - 1] - y[i]) + lr * (x[i + 1] - x[i])) / m
    dx[8] = (vf * yf + vb * y[7] - (vb + vf) * y[8] + lr * (x[9] - x[8])) / m  # tray 8, n = 9
    dx[7] = (vb * (y[6] - y[7]) + lr * x[8] + lf * xf - (lr + lf) * x[7]) / m  # tray 7, n = 8
    for n in range(2, 8):  # trays 1 .. 6
        i = n - 1
        dx[i] = (vb * (y[i - 1] - y[i]) + (lr + lf) * (x[i + 1] - x[i])) / m
    dx[0] = ((lr + lf) * x[1] - vb * y[0] - b * x[0]) / mb  # reboiler, n = 1
    return dx


def _steady(f, x0=TAB):
    x = fsolve(f, x0, xtol=1e-13)
    assert np.max(np.abs(f(x))) < 1e-10
    return x


# -- the model ----------------------------------------------------------------------------------
def test_rhs_matches_appendix_c6_written_out():
    rng = np.random.default_rng(3)
    p = FITTED_PARAMS
    for _ in range(5):
        x = np.clip(TAB + rng.normal(scale=0.05, size=16), 0.001, 0.999)
        u = U_FIT + rng.normal(scale=3.0, size=2)
        want = _c6_rhs(x, u[0], u[1], lf=p.L_F, vf=p.V_F, xf=p.x_F)
        assert_allclose(COLUMN.rhs(0.0, x, u), want, rtol=1e-12, atol=1e-12)


def test_table_3_2_vapour_is_the_vle_of_its_liquid():
    assert_allclose(_vle(TAB), TABLE_3_2_Y, atol=1e-4)
    assert FITTED_PARAMS.y_F == pytest.approx(0.6672, abs=1e-4)  # printed y_F, flash (C.35)


def test_fitted_steady_state_matches_table_3_2():
    assert np.max(np.abs(X_FIT - TAB)) <= 0.01
    assert np.max(np.abs(X_FIT - TAB)) == pytest.approx(0.0035, abs=2e-4)
    x_d, x_b = COLUMN.outputs(X_FIT)
    assert x_d >= 0.98 and x_b <= 0.02  # eq. (3.1)-(3.2)
    assert_allclose(COLUMN.rhs(0.0, X_FIT, U_FIT), 0.0, atol=1e-10)


def test_steady_state_closes_the_overall_balances():
    """Independent check: total and light-key balances around the whole column."""
    p = FITTED_PARAMS
    fl = COLUMN.flows(U_FIT)
    assert fl["D"] + fl["B"] == pytest.approx(p.F, rel=1e-12)
    x_d, x_b = COLUMN.outputs(X_FIT)
    assert fl["D"] * x_d + fl["B"] * x_b == pytest.approx(p.L_F * p.x_F + p.V_F * p.y_F, rel=1e-9)


def test_no_printed_set_reproduces_table_3_2():
    """Eq. (3.3) as printed, the appendix flows, and the appendix flows with the printed D, B."""
    dev_printed = np.max(np.abs(_steady(lambda z: printed_model_rhs(0.0, z)) - TAB))
    dev_appendix = np.max(np.abs(Column(THESIS_PARAMS).steady_state() - TAB))
    p = THESIS_PARAMS
    x_db = _steady(
        lambda z: _c6_rhs(z, p.L, p.V, lf=p.L_F, vf=p.V_F, xf=p.x_F, d=92.7597, b=110.9235)
    )
    dev_db = np.max(np.abs(x_db - TAB))
    assert dev_printed == pytest.approx(0.157, abs=0.002)
    assert dev_appendix == pytest.approx(0.168, abs=0.002)
    assert dev_db == pytest.approx(0.077, abs=0.002)


def test_printed_numeric_model_differs_from_c28_c33_with_its_own_flows():
    """The coefficients of eq. (3.3) against those C.28-C.33 give with the appendix flows."""
    p = THESIS_PARAMS
    fl = Column(p).flows(Column(p).nominal_input())
    assert fl["V_rect"] == pytest.approx(164.6291, abs=1e-4)
    assert fl["L_strip"] == pytest.approx(179.8871, abs=1e-4)
    # condenser: printed L + D = 168.3977, derived L + D = V + V_F
    assert p.L + fl["D"] == pytest.approx(164.6291, abs=1e-4)
    assert p.L + 92.7597 == pytest.approx(168.3977, abs=1e-4)
    # n = 9: printed 156.38 and 59.95; n = 8: printed 188.59 and 33.99
    assert p.V_F * p.y_F == pytest.approx(65.73, abs=0.01)
    assert p.L_F * p.x_F == pytest.approx(27.20, abs=0.01)
    # reboiler B, and the printed D + B against the feed
    assert fl["B"] == pytest.approx(113.7732, abs=1e-4)
    assert 92.7597 + 110.9235 - p.F == pytest.approx(0.9189, abs=1e-4)


def test_fitted_flows_agree_with_the_printed_distillate():
    """The fit's D is within 0.1 % of the printed D = 92.7597 (the appendix flows give 88.99)."""
    assert COLUMN.flows(U_FIT)["D"] == pytest.approx(92.7597, rel=1e-3)
    assert Column(THESIS_PARAMS).flows((75.6380, 66.1139))["D"] == pytest.approx(88.9911, 1e-6)


def test_fitted_flows_are_a_least_squares_optimum():
    def sse(lr, vb):
        x = COLUMN.steady_state(np.array([lr, vb]), X_FIT)
        return float(np.sum((x - TAB) ** 2))

    best = sse(*U_FIT)
    for dl, dv in ((0.05, 0), (-0.05, 0), (0, 0.05), (0, -0.05), (0.05, 0.05), (-0.05, -0.05)):
        assert sse(U_FIT[0] + dl, U_FIT[1] + dv) > best


def test_rk4_transient_settles_at_the_steady_state():
    x = np.full(16, 0.5)
    x = rk4(COLUMN.rhs, 0.0, x, 60.0, U_FIT, max_step=0.01)
    assert_allclose(x, X_FIT, atol=1e-5)


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(5)
    x = np.clip(X_FIT + rng.normal(scale=0.02, size=16), 0.001, 0.999)
    u = U_FIT + rng.normal(scale=2.0, size=2)
    jx, ju = COLUMN.jacobian(x, u)
    h = 1e-6
    fd_x = np.column_stack(
        [
            (COLUMN.rhs(0, x + h * ej, u) - COLUMN.rhs(0, x - h * ej, u)) / (2 * h)
            for ej in np.eye(16)
        ]
    )
    fd_u = np.column_stack(
        [
            (COLUMN.rhs(0, x, u + h * ej) - COLUMN.rhs(0, x, u - h * ej)) / (2 * h)
            for ej in np.eye(2)
        ]
    )
    assert_allclose(jx, fd_x, atol=1e-6)
    assert_allclose(ju, fd_u, atol=1e-7)


def test_linearize_is_stable_with_outputs_x_d_x_b():
    sys = COLUMN.linearize(X_FIT, U_FIT)
    assert sys.nstates == 16 and sys.ninputs == 2 and sys.noutputs == 2
    assert np.max(np.linalg.eigvals(sys.A).real) < 0
    assert_allclose(sys.C @ X_FIT, COLUMN.outputs(X_FIT))
    # at steady state the condenser does not see L (total condenser, L + D = V + V_F)
    assert sys.B[-1, 0] == 0.0 and abs(sys.B[-1, 1]) < 1e-12
    assert COLUMN.state_names[0] == "x1" and COLUMN.input_names == ("L", "V")
    assert COLUMN.output_names == ("x_D", "x_B")


def test_equilibrium_returns_the_inputs_of_a_steady_state():
    u = U_FIT + np.array([1.5, -0.8])
    x = COLUMN.steady_state(u)
    xd, xb = COLUMN.outputs(x)
    x_bar, u_bar = COLUMN.equilibrium({"x_D": xd, "x_B": xb})
    assert_allclose(u_bar, u, rtol=1e-8)
    assert_allclose(x_bar, x, atol=1e-9)
    with pytest.raises(ValueError, match="missing"):
        COLUMN.equilibrium({"x_D": 0.99})


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"M": -1.0}, "M"),
        ({"alpha": 0.9}, "alpha"),
        ({"x_F": 1.2}, "x_F"),
        ({"L": 200.0}, "L and V"),  # D < 0
        ({"V": 200.0}, "L and V"),  # B < 0
        ({"feed_stage": 15}, "feed_stage"),
    ],
)
def test_bad_parameters_are_refused_naming_the_field(change, field):
    data = FITTED_PARAMS.model_dump() | change
    with pytest.raises(ValidationError, match=field):
        ColumnParams(**data)


# -- the reduced model of section 4.3 -----------------------------------------------------------
def _signed_like(r, c_ref):
    """The reduced model with its states' signs chosen to match ``c_ref`` (states are +-)."""
    s = np.diag([np.sign(r.C[1, 0] * c_ref[1, 0]), np.sign(r.C[0, 1] * c_ref[0, 1])])
    return s @ r.A @ s, s @ r.B, r.C @ s


def test_residualizing_appendix_e_reproduces_the_thesis_reference_model():
    r = balanced_reduction(APPENDIX_E_A, APPENDIX_E_B, APPENDIX_E_C, 2, "matchdc")
    a, b, c = _signed_like(r, THESIS_C_M)
    assert_allclose(a, THESIS_A_M, atol=2e-4)
    assert_allclose(b, THESIS_B_M, atol=1e-4)
    assert_allclose(c, THESIS_C_M, atol=1e-4)
    assert_allclose(np.sort(r.eigenvalues().real), EIG_THESIS, rtol=1e-3)


def test_truncating_appendix_e_as_the_text_says_does_not():
    r = balanced_reduction(APPENDIX_E_A, APPENDIX_E_B, APPENDIX_E_C, 2, "truncate")
    ev = np.sort(r.eigenvalues().real)
    assert_allclose(ev, [-9.845, -0.4988], rtol=1e-3)
    assert abs(ev[0] / EIG_THESIS[0] - 1) > 0.4  # 50 % off


def test_thesis_model_is_balanced_with_appendix_e_hankel_values():
    wc = solve_continuous_lyapunov(THESIS_A_M, -THESIS_B_M @ THESIS_B_M.T)
    wo = solve_continuous_lyapunov(THESIS_A_M.T, -THESIS_C_M.T @ THESIS_C_M)
    assert_allclose(wc, wo, atol=2e-6)
    assert abs(wc[0, 1]) < 2e-6
    hsv = balanced_reduction(APPENDIX_E_A, APPENDIX_E_B, APPENDIX_E_C, 2).hsv
    assert_allclose(np.diag(wc), hsv[:2], rtol=5e-3)


def test_consistent_model_cannot_reproduce_the_thesis_eigenvalues():
    """Same first Hankel value (2 %), but reduced eigenvalues near (-0.91, -0.33), not 5 %."""
    jx, ju = COLUMN.jacobian(X_FIT, U_FIT)
    r = balanced_reduction(jx, ju, APPENDIX_E_C, 2, "matchdc")
    ev = np.sort(r.eigenvalues().real)
    assert_allclose(ev, [-0.915, -0.3275], rtol=5e-3)
    assert np.max(np.abs(ev / EIG_THESIS - 1)) > 0.05
    assert r.hsv[0] == pytest.approx(4.7336e-3, rel=0.03)


def test_balanced_reduction_properties():
    """Independent checks: balanced Gramians, H-infinity bound, steady-state gain of matchdc."""
    jx, ju = COLUMN.jacobian(X_FIT, U_FIT)
    c = APPENDIX_E_C
    full_dc = -c @ np.linalg.solve(jx, ju)
    for method in ("truncate", "matchdc"):
        r = balanced_reduction(jx, ju, c, 2, method)
        assert_allclose(r.W @ r.V, np.eye(2), atol=1e-10)
        bound = 2 * np.sum(r.hsv[2:])
        for w in np.logspace(-3, 3, 120):
            g = c @ np.linalg.solve(1j * w * np.eye(16) - jx, ju)
            gr = r.C @ np.linalg.solve(1j * w * np.eye(2) - r.A, r.B) + r.D
            assert np.linalg.norm(g - gr, 2) <= bound * (1 + 1e-6)
        if method == "truncate":
            wc = solve_continuous_lyapunov(r.A, -r.B @ r.B.T)
            wo = solve_continuous_lyapunov(r.A.T, -r.C.T @ r.C)
            assert_allclose(wc, np.diag(r.hsv[:2]), rtol=1e-6, atol=1e-12)
            assert_allclose(wo, np.diag(r.hsv[:2]), rtol=1e-6, atol=1e-12)
        else:
            assert_allclose(r.dc_gain(), full_dc, rtol=1e-8)
    with pytest.raises(ValueError, match="stable"):
        balanced_reduction(-jx, ju, c, 2)


def test_balanced_truncation_agrees_with_python_control_balred():
    jx, ju = COLUMN.jacobian(X_FIT, U_FIT)
    sys = control.ss(jx, ju, APPENDIX_E_C, 0)
    ours = balanced_reduction(jx, ju, APPENDIX_E_C, 2, "truncate")
    theirs = control.balred(sys, 2, method="truncate")
    assert_allclose(np.sort(np.linalg.eigvals(theirs.A).real), np.sort(ours.eigenvalues().real))


# -- the plant of section 6.3.1 ------------------------------------------------------------------
def test_perturbed_plant_moves_each_element_by_half_its_spread():
    plant = PerturbedReducedPlant(np.random.default_rng(0))
    for name, nominal, now in (("A", THESIS_A_M, plant.A), ("B", THESIS_B_M, plant.B)):
        assert_allclose(np.abs(now - nominal), SECTION_631_SPREAD[name] / 2, rtol=1e-12)
    a0 = plant.A.copy()
    x1 = plant.euler_step(np.array([0.1, -0.2]), np.array([0.5, 0.1]), 0.1)
    assert_allclose(x1, [0.1, -0.2] + 0.1 * (a0 @ [0.1, -0.2] + plant.B @ [0.5, 0.1]))
    moving = PerturbedReducedPlant(np.random.default_rng(0), redraw="every_step")
    draws = set()
    for _ in range(20):
        moving.euler_step(np.zeros(2), np.zeros(2), 0.1)
        draws.add(tuple(np.sign(moving.A - THESIS_A_M).ravel()))
    assert len(draws) > 5


def test_appendix_g_signs_and_the_fig_6_11_plant():
    signs = appendix_g_signs()
    assert signs.shape == (100, 8) and set(np.unique(signs)) == {-0.5, 0.5}
    # Fig. 6.11 prints A = [-0.4591 -0.0645 1.5436 -0.2397] (digits lost) and
    # B = [-0.1391 0.2173 -0.0022 -0.0296]: all-+ A, and B signs (+, +, -, -)
    plant = PerturbedReducedPlant(np.random.default_rng(0))
    plant.set_signs([0.5] * 4 + [0.5, 0.5, -0.5, -0.5])
    assert_allclose(plant.A.ravel(), [-6.4591, -0.8645, 1.5436, -0.2397], atol=1e-12)
    assert_allclose(plant.B.ravel(), [-0.1391, 0.2173, -0.0022, -0.0296], atol=1e-12)
