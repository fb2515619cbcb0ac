"""Quasi-decentralized output-feedback control (seed 001 eq. (2)-(4), section V): gains, structure,
bad input, and the non-linear closed loop around the maximum update period."""

from __future__ import annotations

import control  # noqa: TID253 - not a node: imports what it uses at the top
import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from scipy.integrate import solve_ivp
from scipy.linalg import block_diag, expm
from scipy.signal import place_poles  # noqa: TID253 - not a node: imports what it uses at the top

from agents.update_period.analysis import CSTRRecycleCase
from controllers.qdc.design import LinearUnits, QDCDesign, observer_gain
from controllers.qdc.model import closed_loop_matrices, simulate_linear, simulate_nonlinear
from controllers.qdc.network import CentralizedNetwork, NetworkConfig, QDCNetwork

CASE = CSTRRecycleCase()
PLANT = CASE.plant
GAINS = CASE.gains


def _abar(i, j):
    return PLANT.a(i, j) + PLANT.b(i) @ GAINS.K[i][j]


# -- gains (section V) ---------------------------------------------------------------------------


def test_controller_gains_place_poles_and_cancel_coupling():
    for i in range(2):
        ab = _abar(i, i)
        assert_allclose(np.sort(np.linalg.eigvals(ab).real), [-5.0, -1.0], atol=1e-9)
        # the documented choice: Abar_i = diag(-5, -1) in (T_i, CA_i) coordinates
        assert_allclose(ab, np.diag([-5.0, -1.0]), atol=1e-9)
        assert_allclose(_abar(i, 1 - i), 0.0, atol=1e-9)  # Abar_ij = A_ij + B_i K_ij = O


def test_diagonal_design_is_what_place_poles_returns_for_square_b():
    for i in range(2):
        k_place = -place_poles(PLANT.a(i, i), PLANT.b(i), [-5.0, -1.0]).gain_matrix
        assert_allclose(GAINS.K[i][i], k_place, rtol=1e-9, atol=1e-9)
    placed = CASE.design.model_copy(update={"controller_method": "place"}).gains()
    for i in range(2):
        assert_allclose(placed.K[i][i], GAINS.K[i][i], rtol=1e-9, atol=1e-9)


def test_observer_gains_place_minus_50_and_minus_25():
    for i in range(2):
        a, c = PLANT.a(i, i), PLANT.c(i)
        ev = np.sort(np.linalg.eigvals(a - GAINS.L[i] @ c).real)
        assert_allclose(ev, [-50.0, -25.0], rtol=1e-9)
        # one output: the gain is unique; python-control's place on the dual gives the same
        assert_allclose(GAINS.L[i], control.place(a.T, c.T, [-50.0, -25.0]).T, rtol=1e-8)


def test_observer_gain_allows_repeated_poles_and_refuses_unobservable():
    a, c = PLANT.a(0, 0), PLANT.c(0)
    L = observer_gain(a, c, [-30.0, -30.0])
    assert_allclose(np.linalg.eigvals(a - L @ c), [-30.0, -30.0], atol=1e-5)
    with pytest.raises(ValueError, match="observable"):
        observer_gain(np.diag([1.0, 2.0]), np.array([[1.0, 0.0]]), [-1.0, -2.0])


def test_continuous_communication_loop_is_stable():
    """Section V: 'when the estimates are communicated continuously ... stabilize the plant'."""
    A, B, C = PLANT.full()
    K, L = GAINS.full_K(), GAINS.full_L()
    # eq. (3): observer with A_ij xbar_j; closed loop (x, xbar)
    acl = np.block([[A, B @ K], [L @ C, A - L @ C + B @ K]])
    ev = np.linalg.eigvals(acl)
    assert np.max(ev.real) < 0
    # separation: controller poles and the (coupled) observer error poles
    sep = np.concatenate([np.linalg.eigvals(A + B @ K), np.linalg.eigvals(A - L @ C)])
    assert_allclose(np.sort_complex(ev), np.sort_complex(sep), rtol=1e-7, atol=1e-7)


# -- eq. (4) structure ---------------------------------------------------------------------------


def test_zero_order_hold_freezes_the_neighbour_models():
    net = QDCNetwork(PLANT, GAINS, scheme="zoh")
    for i in range(2):
        for sl in net._xhat[i].values():
            assert_allclose(net.F[sl, :], 0.0)
            assert_allclose(net.G[sl, :], 0.0)
    # ... while the model scheme runs Atil_j = Abar_j on the neighbour's model
    net = QDCNetwork(PLANT, GAINS)
    sl = net._xhat[0][1]
    assert_allclose(net.F[sl, sl], _abar(1, 1), atol=1e-9)


def test_update_replaces_each_model_with_the_transmitted_estimate():
    net = QDCNetwork(PLANT, GAINS)
    rng = np.random.default_rng(3)
    z = rng.normal(size=net.nz)
    z1 = net.update_from(z, np.zeros(4))
    xbar = net.estimates(z)
    assert_allclose(net.estimates(z1), xbar)  # the observers are not reset
    assert_allclose(z1[net._xhat[0][1]], xbar[1])  # unit 1's model of unit 2 <- xbar_2
    assert_allclose(z1[net._xhat[1][0]], xbar[0])


@pytest.mark.parametrize(
    "make",
    [
        lambda: QDCNetwork(PLANT, GAINS),
        lambda: QDCNetwork(PLANT, GAINS, feedback="state"),
        lambda: CentralizedNetwork(PLANT, GAINS),
        lambda: CentralizedNetwork(PLANT, GAINS, observer="plant"),
    ],
    ids=["qdc-output", "qdc-state", "centralized", "centralized-plant-observer"],
)
def test_exact_models_and_exact_estimates_reproduce_the_ideal_loop_for_any_period(make):
    """With exact models, estimates equal to the state never drift from it, so even a period
    three times h_max gives x(t) = expm((A + B K) t) x0, the ideal (decoupled) closed loop."""
    net = make()
    x0 = np.array([2.0, -0.05, -1.0, 0.03])
    h = 3.0 * CASE.h_max().h_max
    run = simulate_linear(PLANT, net, h, x0, 6, z0=net.initial_state(x0))
    ideal = block_diag(_abar(0, 0), _abar(1, 1))
    for k, t in enumerate(run.t):
        assert_allclose(run.x[k], expm(ideal * t) @ x0, rtol=1e-7, atol=1e-9)


def test_linear_simulation_matches_solve_ivp_of_the_controller_equations():
    """The exact sampled run against a direct integration of plant + eq. (4) with resets."""
    A, B, _ = PLANT.full()
    model = CASE.model(0.2)
    net = QDCNetwork(PLANT, GAINS, model=model)
    h = 0.03
    x0 = np.array([1.0, 0.02, -0.5, 0.0])
    run = simulate_linear(PLANT, net, h, x0, 10)
    x, z = x0.copy(), net.update_from(net.initial_state(), x0)

    def f(t, w):
        xx, zz = w[:4], w[4:]
        m = net.M @ xx
        return np.concatenate([A @ xx + B @ net.control(zz, m), net.derivative(zz, m)])

    for k in range(1, 11):
        sol = solve_ivp(f, (0, h), np.concatenate([x, z]), rtol=1e-11, atol=1e-13)
        x, z = sol.y[:4, -1], sol.y[4:, -1]
        z = net.update_from(z, x)
        assert_allclose(x, run.x[k], rtol=1e-6, atol=1e-9)


def test_closed_loop_matrices_shapes():
    net = QDCNetwork(PLANT, GAINS)
    acl, rcl = closed_loop_matrices(PLANT, net)
    assert acl.shape == rcl.shape == (4 + net.nz, 4 + net.nz)
    assert net.nz == 2 * 2 + 2 * 2  # two observers, one neighbour model in each unit


# -- bad input -----------------------------------------------------------------------------------


def _units(b1):
    a = np.array([[0.0, 1.0], [-2.0, -3.0]])
    return LinearUnits.from_arrays(
        [[a, a], [a, a]], [b1, np.eye(2)], [np.array([[1.0, 0.0]]), np.array([[1.0, 0.0]])]
    )


def test_non_square_b_is_refused_when_k_ij_must_cancel_the_coupling():
    with pytest.raises(ValidationError, match=r"plant\.B\[0\].*square.*cancel_coupling"):
        QDCDesign(plant=_units(np.array([[1.0], [0.5]])))


def test_singular_b_is_refused():
    with pytest.raises(ValidationError, match=r"plant\.B\[0\] is singular"):
        QDCDesign(plant=_units(np.array([[1.0, 2.0], [2.0, 4.0]])))


def test_non_square_b_is_accepted_without_cancellation_with_place():
    design = QDCDesign(
        plant=_units(np.array([[1.0], [0.5]])),
        controller_method="place",
        cancel_coupling=False,
        controller_poles=((-1.0, -2.0), (-1.0, -2.0)),
    )
    g = design.gains()
    assert g.K[0][1].shape == (1, 2) and not np.any(g.K[0][1])


@pytest.mark.parametrize("bad", [((-50.0, 3.0), (-50.0, -25.0)), ((-50.0, -25.0), (0.0, -25.0))])
def test_observer_poles_outside_the_left_half_plane_are_refused(bad):
    with pytest.raises(ValidationError, match="observer_poles"):
        QDCDesign.model_validate({**CASE.design.model_dump(), "observer_poles": bad})


def test_controller_poles_and_pole_counts_are_checked():
    data = CASE.design.model_dump()
    with pytest.raises(ValidationError, match="controller_poles"):
        QDCDesign.model_validate({**data, "controller_poles": ((-5.0, 1.0), (-5.0, -1.0))})
    with pytest.raises(ValidationError, match="observer_poles needs one pole per state"):
        QDCDesign.model_validate({**data, "observer_poles": ((-50.0,), (-50.0, -25.0))})
    with pytest.raises(ValidationError, match="extra"):
        QDCDesign.model_validate({**data, "gain": 1.0})


@pytest.mark.parametrize("h", [0.0, -0.01])
def test_non_positive_update_period_is_refused(h):
    with pytest.raises(ValidationError, match="h"):
        NetworkConfig(h=h)
    net = QDCNetwork(PLANT, GAINS)
    with pytest.raises(ValidationError, match=r"\bh\b"):
        simulate_linear(PLANT, net, h, np.ones(4), 3)
    with pytest.raises(ValidationError, match=r"\bh\b"):
        simulate_nonlinear(CASE.plant_nl, CASE.x_s, CASE.u_s, net, h, CASE.x_s, 1.0)


def test_bad_shapes_are_refused():
    with pytest.raises(ValidationError, match=r"A\[0\]\[1\]"):
        LinearUnits.from_arrays(
            [[np.eye(2), np.eye(3)], [np.eye(2), np.eye(2)]],
            [np.eye(2), np.eye(2)],
            [np.ones((1, 2)), np.ones((1, 2))],
        )


# -- the non-linear plant (eq. (10)) under the networked controllers -----------------------------


@pytest.mark.parametrize("scheme", ["model", "zoh"])
def test_nonlinear_closed_loop_converges_below_and_leaves_bound_above_h_max(scheme):
    """Eq. (10) with local observers/controllers exchanging estimates every h: 1 K initial
    deviations on both temperatures; bound 20 K (checked at the update instants)."""
    arch = "qdc" if scheme == "model" else "qdc_zoh"
    h_max = CASE.h_max(arch).h_max
    net = QDCNetwork(PLANT, GAINS, scheme=scheme)
    x0 = CASE.x_s + np.array([1.0, 0.0, -1.0, 0.0])
    ok = simulate_nonlinear(
        CASE.plant_nl, CASE.x_s, CASE.u_s, net, 0.9 * h_max, x0, 12.0, bound=20.0
    )
    assert not ok.left_bound
    dev = np.max(np.abs(ok.x - CASE.x_s), axis=1)
    assert dev[-1] < 1e-3 * dev[0]
    assert np.max(dev) < 5.0
    bad = simulate_nonlinear(
        CASE.plant_nl, CASE.x_s, CASE.u_s, net, 1.2 * h_max, x0, 12.0, bound=20.0
    )
    assert bad.left_bound
    assert np.max(np.abs(bad.x[-1] - CASE.x_s)) > 20.0
