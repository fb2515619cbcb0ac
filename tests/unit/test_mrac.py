"""The MRAC of seed 003 (chapters 4-5): compatibility condition, adaptation laws, thesis's test."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from scipy.linalg import expm

from controllers.mrac import (
    MRAC,
    THESIS_A0,
    THESIS_B0,
    THESIS_Q,
    MRACConfig,
    MRACDivergenceError,
    compatibility_theta,
    continuous_loop_rhs,
    lyapunov_Q,
    psi,
    theta_dot,
)
from plants.column import (
    THESIS_A_M,
    THESIS_B_M,
    THESIS_C_M,
    PerturbedReducedPlant,
    appendix_g_signs,
)
from plants.integrate import rk4

T = 0.1
UC = np.array([0.5, 0.1])  # Fig. 7.26-7.27
# Table G.4, k = 0: the thesis's initial theta
THETA0_G4 = np.array([0.372, -0.511, 0.281, -0.310, 1.044, -0.043, 0.000, 1.007])
# Table G.1 (x1, x2, xm1, xm2) and Table G.4 (theta) at a few steps
G1 = {
    1: (-0.005938, -0.000402, -0.005232, -0.000386),
    10: (-0.006511, -0.011823, -0.006369, -0.011576),
    50: (-0.003254, -0.030814, -0.003639, -0.030590),
    100: (-0.003393, -0.033212, -0.003197, -0.033668),
}
G4 = {
    20: (0.371, -0.511, 0.281, -0.309, 1.022, -0.047, 0.027, 1.012),
    85: (0.371, -0.512, 0.281, -0.309, 1.003, -0.051, 0.022, 1.011),
    100: (0.371, -0.511, 0.281, -0.311, 1.022, -0.047, 0.003, 1.007),
}
G3_RMS = (4.7578e-4, 3.4793e-4)  # RMS (6.1) of the 101 rows of Table G.3


def _random_plant(rng):
    return (
        THESIS_A_M + rng.normal(scale=0.3, size=(2, 2)),
        THESIS_B_M + rng.normal(scale=0.02, size=(2, 2)),
    )


def _thesis_loop(gamma, plant, steps, *, signs=None, T=T, uc=UC, **kw):
    ctrl = MRAC(MRACConfig(gamma=gamma, T=T, A0=THESIS_A0, B0=THESIS_B0, **kw))
    x = np.zeros(2)
    xs, es, ths = [], [], []
    for k in range(steps + 1):
        u = ctrl.step(k * T, x, uc)
        xs.append(x)
        es.append(ctrl.e.copy())
        ths.append(ctrl.theta.copy())
        if k < steps:
            if signs is not None:
                plant.set_signs(signs[k])
            x = plant.euler_step(x, u, T)
    return np.array(xs), np.array(es), np.array(ths), ctrl


# -- compatibility condition (4.13)-(4.14) / (5.7) ----------------------------------------------
def test_compatibility_theta_gives_perfect_model_following():
    rng = np.random.default_rng(0)
    for _ in range(10):
        a, b = _random_plant(rng)
        th = compatibility_theta(a, b, THESIS_A_M, THESIS_B_M)
        lmat, mmat = th[:4].reshape(2, 2), th[4:].reshape(2, 2)
        assert_allclose(a - b @ lmat, THESIS_A_M, atol=1e-12)
        assert_allclose(b @ mmat, THESIS_B_M, atol=1e-12)


def test_eq_4_14_written_out_with_the_theta8_sign_corrected():
    rng = np.random.default_rng(1)
    a, b = _random_plant(rng)
    (a11, a12), (a21, a22) = a
    (b11, b12), (b21, b22) = b
    det = b11 * b22 - b12 * b21
    eq_4_14 = np.array(
        [
            (b22 * (a11 + 6.7941) - b12 * (a21 - 1.4686)) / det,
            (b22 * (a12 + 0.9095) - b12 * (a22 + 0.2497)) / det,
            (-b21 * (a11 + 6.7941) + b11 * (a21 - 1.4686)) / det,
            (-b21 * (a12 + 0.9095) + b11 * (a22 + 0.2497)) / det,
            (0.0021 * b12 - 0.1461 * b22) / det,
            (0.0281 * b12 + 0.2073 * b22) / det,
            (-0.0021 * b11 + 0.1461 * b21) / det,
            -(0.0281 * b11 + 0.2073 * b21) / det,  # printed without the minus sign
        ]
    )
    assert_allclose(compatibility_theta(a, b, THESIS_A_M, THESIS_B_M), eq_4_14, rtol=1e-12)


def test_thesis_initial_theta_is_the_compatibility_of_the_rounded_nominal_plant():
    th = compatibility_theta(THESIS_A0, THESIS_B0, THESIS_A_M, THESIS_B_M)
    assert_allclose(th, THETA0_G4, atol=6e-4)
    # the printed th8 formula gives the wrong sign here
    (b11, b12), (b21, b22) = THESIS_B0
    printed_th8 = (0.0281 * b11 + 0.2073 * b21) / (b11 * b22 - b12 * b21)
    assert printed_th8 == pytest.approx(-THETA0_G4[7], abs=1e-3)
    # with the reference model as nominal plant, theta0 = (L, M) = (0, I)
    th_m = compatibility_theta(THESIS_A_M, THESIS_B_M, THESIS_A_M, THESIS_B_M)
    assert_allclose(th_m, [0, 0, 0, 0, 1, 0, 0, 1], atol=1e-12)


def test_singular_b_is_refused_naming_b():
    b_sing = np.array([[0.1, 0.2], [0.05, 0.1]])
    with pytest.raises(ValueError, match="B is singular"):
        compatibility_theta(THESIS_A_M, b_sing, THESIS_A_M, THESIS_B_M)
    with pytest.raises(ValidationError, match="B0"):
        MRACConfig(gamma=1.0, T=T, B0=tuple(map(tuple, b_sing)))


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"gamma": -1.0}, "gamma"),
        ({"T": 0.0}, "T"),
        ({"T": -0.1}, "T"),
        ({"T": 0.5}, "T = 0.5"),  # forward-Euler reference model (5.3) unstable
        ({"P": ((1.0, 2.0), (2.0, 1.0))}, "P must be symmetric positive definite"),
        ({"theta0": (1.0, 2.0)}, "theta0"),
        ({"A_m": ((1.0, 0.0), (0.0, -1.0))}, "A_m must be stable"),
        ({"measurement": "output", "C_m": ((1.0, 2.0), (2.0, 4.0))}, "C_m"),
        ({"gamma": 1.0, "extra": 1}, "extra"),
    ],
)
def test_bad_configuration_is_refused_naming_the_field(kw, field):
    data = {"gamma": 1.0, "T": T} | kw
    with pytest.raises(ValidationError, match=field):
        MRACConfig(**data)


# -- error equation and adaptation laws ---------------------------------------------------------
def test_psi_satisfies_the_error_equation_4_16_and_the_printed_one_does_not():
    rng = np.random.default_rng(2)
    a, b = _random_plant(rng)
    th0 = compatibility_theta(a, b, THESIS_A_M, THESIS_B_M)
    th = th0 + rng.normal(scale=0.3, size=8)
    x, uc = rng.normal(size=2), rng.normal(size=2)
    lmat, mmat = th[:4].reshape(2, 2), th[4:].reshape(2, 2)
    want = (a - b @ lmat - THESIS_A_M) @ x + (b @ mmat - THESIS_B_M) @ uc  # (4.16)
    assert_allclose(psi(x, uc, b) @ (th - th0), want, atol=1e-12)
    # (4.17) prints psi[1, 1] = -b22 x2: a change of theta2 alone then moves e2 by b22, not b21
    d2 = np.eye(8)[1]
    x1 = np.array([1.0, 1.0])
    bm = THESIS_B_M
    want2 = -bm @ np.array([[0.0, 1.0], [0.0, 0.0]]) @ x1  # -B dL x with dL = [[0, 1], [0, 0]]
    assert_allclose(psi(x1, uc, bm) @ d2, want2, atol=1e-15)
    printed = psi(x1, uc, bm)
    printed[1, 1] = -bm[1, 1] * x1[1]
    assert abs(printed[1] @ d2 - want2[1]) > 5 * abs(want2[1])


def test_theta_dot_is_eq_4_22_and_its_expansion_4_23():
    rng = np.random.default_rng(3)
    x, e, uc = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
    g = 7.0
    p = np.array([[2.0, 0.3], [0.3, 1.0]])
    assert_allclose(
        theta_dot(x, e, uc, gamma=g, B=THESIS_B_M, P=p), -g * psi(x, uc, THESIS_B_M).T @ p @ e
    )
    (b11, b12), (b21, b22) = THESIS_B_M
    s1, s2 = b11 * e[0] + b21 * e[1], b12 * e[0] + b22 * e[1]
    eq_4_23 = g * np.array(
        [
            s1 * x[0],
            s1 * x[1],
            s2 * x[0],
            s2 * x[1],
            -s1 * uc[0],
            -s1 * uc[1],
            -s2 * uc[0],
            -s2 * uc[1],
        ]
    )
    assert_allclose(theta_dot(x, e, uc, gamma=g, B=THESIS_B_M), eq_4_23, rtol=1e-12)


def test_discrete_update_is_eq_5_8_with_the_actual_time_step():
    """The first update uses x, e, u_c of the previous execution and dt = t_k - t_(k-1)."""
    ctrl = MRAC(MRACConfig(gamma=50.0, T=T))
    x0, uc0 = np.array([0.01, -0.02]), np.array([0.5, 0.1])
    ctrl.step(0.0, x0, uc0)
    e0 = ctrl.e.copy()
    assert_allclose(e0, x0)  # x_m(0) = 0
    th_before = ctrl.theta.copy()
    dt = 0.037  # not the nominal period
    ctrl.step(dt, np.array([0.02, 0.01]), np.array([0.4, 0.2]))
    want = th_before + dt * theta_dot(x0, e0, uc0, gamma=50.0, B=THESIS_B_M)
    assert_allclose(ctrl.theta, want, rtol=1e-12)
    # the expansion (5.9) as printed uses (b12 e1 + b22 e2) for theta6: not (5.8)
    (b11, b12), (b21, b22) = THESIS_B_M
    printed_th6 = th_before[5] - dt * 50.0 * (b12 * e0[0] + b22 * e0[1]) * uc0[1]
    assert abs(printed_th6 - ctrl.theta[5]) > 1e-6
    with pytest.raises(ValueError, match="backwards"):
        ctrl.step(0.0, x0, uc0)


def test_reference_model_discretizations():
    cfg = {"gamma": 0.0, "T": T}
    euler = MRAC(MRACConfig(**cfg))
    zoh = MRAC(MRACConfig(**cfg, reference_discretization="zoh"))
    for c in (euler, zoh):
        c.step(0.0, np.zeros(2), UC)
        c.step(0.3, np.zeros(2), UC)  # three nominal periods at once
    xm = np.zeros(2)
    for _ in range(3):  # (5.3) in steps of T
        xm = xm + T * (THESIS_A_M @ xm + THESIS_B_M @ UC)
    assert_allclose(euler.x_m, xm, rtol=1e-12)
    aug = expm(np.block([[THESIS_A_M, THESIS_B_M], [np.zeros((2, 4))]]) * 0.3)
    assert_allclose(zoh.x_m, aug[:2, 2:] @ UC, rtol=1e-12)
    # Table G.1: x_m(1) = T B_m u_c = (-0.005232, -0.000386)
    c = MRAC(MRACConfig(**cfg))
    c.step(0.0, np.zeros(2), UC)
    c.step(T, np.zeros(2), UC)
    assert_allclose(c.x_m, G1[1][2:], atol=5e-7)


def test_q_of_section_4_4_6_and_the_misprinted_eq_4_24():
    q = lyapunov_Q(THESIS_A_M)
    assert_allclose(q, THESIS_Q, atol=1e-4)
    assert np.all(np.linalg.eigvalsh(q) > 0)
    rng = np.random.default_rng(4)
    for _ in range(20):
        e = rng.normal(size=2)
        fixed = (0.7067 * e[1] - 0.7912 * e[0]) ** 2 + 12.9622 * e[0] ** 2
        assert fixed == pytest.approx(e @ q @ e, rel=2e-4, abs=1e-4)
    # (4.24) as printed: its e1 e2 coefficient is -2 (0.5591)(0.7066) = -0.790, Q's is -1.118
    assert -2 * 0.5591 * 0.7066 == pytest.approx(-0.790, abs=1e-3)
    assert 2 * q[0, 1] == pytest.approx(-1.118, abs=1e-3)
    e = np.array([1.0, 2.0])
    printed = (0.5591 * e[0] - 0.7066 * e[1]) ** 2 + 13.2756 * e[0] ** 2
    assert printed / (e @ q @ e) - 1 > 0.04


def test_output_measurement_equals_state_measurement():
    rng = np.random.default_rng(6)
    a = MRAC(MRACConfig(gamma=300.0, T=T))
    b = MRAC(MRACConfig(gamma=300.0, T=T, measurement="output", y_bar=(0.1, -0.2)))
    for k in range(30):
        x = rng.normal(scale=0.01, size=2)
        ua = a.step(k * T, x, UC)
        ub = b.step(k * T, THESIS_C_M @ x + [0.1, -0.2], UC)
        assert_allclose(ua, ub, rtol=1e-10, atol=1e-14)


# -- the analog loop (section 4.4-4.5) -----------------------------------------------------------
def test_continuous_law_makes_the_lyapunov_function_non_increasing():
    """Eq. (4.18)-(4.20) on a fixed perturbed plant without disturbance: dV/dt <= 0, e -> 0."""
    plant = PerturbedReducedPlant(np.random.default_rng(7))
    a, b = plant.A, plant.B
    gamma = 5000.0
    cfg = MRACConfig(gamma=gamma, T=T, B0=tuple(map(tuple, b)))  # the law knows the plant's B
    th0 = compatibility_theta(a, b, THESIS_A_M, THESIS_B_M)
    f = continuous_loop_rhs(a, b, cfg)
    z = np.concatenate((np.zeros(4), [0.0, 0, 0, 0, 1, 0, 0, 1]))  # start from (L, M) = (0, I)
    w = np.concatenate((UC, np.zeros(2)))
    vs, es = [], []
    for k in range(400):
        e, th = z[:2] - z[2:4], z[4:]
        vs.append(0.5 * (gamma * e @ e + (th - th0) @ (th - th0)))
        es.append(np.linalg.norm(e))
        z = rk4(f, k * 0.05, z, (k + 1) * 0.05, w, max_step=0.01)
    vs = np.array(vs)
    assert np.all(np.diff(vs) <= 1e-9 * vs[0])
    assert es[-1] < 0.1 * max(es)


# -- the thesis's test (section 6.3.1, appendix G) ----------------------------------------------
@pytest.mark.parametrize("seed", range(20))
def test_discrete_mrac_tracks_the_reference_model_on_perturbed_plants(seed):
    plant = PerturbedReducedPlant(np.random.default_rng(seed))
    _, es, ths, ctrl = _thesis_loop(1000.0, plant, 400)  # 40 h
    norm = np.linalg.norm(es, axis=1)
    assert norm[-1] <= 0.1 * norm.max()
    assert not ctrl.diverged


def test_replay_of_appendix_g_reproduces_tables_g1_g3_g4():
    """gamma = 1000, theta0 from (5.7), the plant's signs inferred from Table G.1 per step."""
    plant = PerturbedReducedPlant(np.random.default_rng(0))
    xs, es, ths, _ = _thesis_loop(1000.0, plant, 100, signs=appendix_g_signs())
    for k, row in G1.items():
        assert_allclose(xs[k], row[:2], atol=4e-5)
        assert_allclose(xs[k] - es[k], row[2:], atol=1e-6)
    for k, row in G4.items():
        assert_allclose(ths[k], row, atol=2e-3)
    rms = np.linalg.norm(es, axis=0) / np.sqrt(len(es))
    assert_allclose(rms, G3_RMS, rtol=0.03)
    # ... while gamma = 100 does not reproduce Table G.4
    plant = PerturbedReducedPlant(np.random.default_rng(0))
    _, _, ths100, _ = _thesis_loop(100.0, plant, 100, signs=appendix_g_signs())
    assert np.max(np.abs(ths100[85] - G4[85])) > 0.02


def test_divergence_is_detected_and_reported():
    plant = PerturbedReducedPlant(np.random.default_rng(0))
    with pytest.raises(MRACDivergenceError, match=r"diverged at t = .*gamma = 100000"):
        _thesis_loop(1e5, plant, 100)
    plant = PerturbedReducedPlant(np.random.default_rng(0))
    _, es, ths, ctrl = _thesis_loop(1e5, plant, 100, on_divergence="freeze")
    assert ctrl.diverged and ctrl.divergence_time is not None
    assert "theta_bound" in ctrl.divergence_message
    assert np.all(np.isfinite(ths)) and ctrl.theta_drift <= ctrl.config.theta_bound
    frozen = ctrl.theta.copy()
    ctrl.step(200.0, np.array([0.01, 0.01]), UC)
    assert_allclose(ctrl.theta, frozen)  # no more adaptation
    ctrl.reset()
    assert not ctrl.diverged and ctrl.theta_drift == 0.0
    # below the divergence threshold (about 4600-5600 at T = 0.1 h) nothing is flagged
    plant = PerturbedReducedPlant(np.random.default_rng(0))
    assert not _thesis_loop(3000.0, plant, 100)[3].diverged


def test_irregular_sampling_still_tracks():
    """The law uses the actual time between executions (jittered periods 0.05-0.15 h)."""
    rng = np.random.default_rng(11)
    plant = PerturbedReducedPlant(np.random.default_rng(3))
    ctrl = MRAC(MRACConfig(gamma=1000.0, T=T, A0=THESIS_A0, B0=THESIS_B0))
    t, x, norms = 0.0, np.zeros(2), []
    while t < 40.0:
        u = ctrl.step(t, x, UC)
        norms.append(np.linalg.norm(ctrl.e))
        dt = rng.uniform(0.05, 0.15)
        x = rk4(plant.rhs, t, x, t + dt, u, max_step=0.01)
        t += dt
    assert norms[-1] <= 0.1 * max(norms)
