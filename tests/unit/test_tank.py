"""Tank of seed 002 eq. (3): equilibrium, linearization, empty-tank guard, pump limits, params."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from plants.integrate import rk4
from plants.tank import RIG_PARAMS, RIG_U_MAX, SIM_PARAMS, Tank, TankParams

SIM = Tank(SIM_PARAMS)
RIG = Tank(RIG_PARAMS)


def test_paper_parameter_sets():
    # seed 002 eq. (22) and (24)
    assert (SIM_PARAMS.b, SIM_PARAMS.a_prime) == (2.0, 0.5)
    assert (RIG_PARAMS.b, RIG_PARAMS.a_prime) == (0.0122, 0.00497)
    assert RIG_PARAMS.u_min == 0.0 and RIG_PARAMS.u_max == RIG_U_MAX


@pytest.mark.parametrize(
    "plant, h_bar", [(SIM, 50.0), (SIM, 100.0), (SIM, 150.0), (RIG, 0.5), (RIG, 1.0)]
)
def test_equilibrium_solves_rhs_zero(plant, h_bar):
    x_bar, u_bar = plant.equilibrium({"h": h_bar})
    assert x_bar.tolist() == [h_bar]
    assert u_bar[1] == 0.0
    assert_allclose(plant.rhs(0.0, x_bar, u_bar), 0.0, atol=1e-12)
    # independent: root of the inflow/outflow balance in u
    p = plant.params
    u_root = brentq(lambda u: p.b * u - p.a_prime * math.sqrt(h_bar), 0.0, 100.0, xtol=1e-14)
    assert u_bar[0] == pytest.approx(u_root, rel=1e-10)


def test_equilibrium_values_of_the_paper_levels():
    # u_bar = a' sqrt(h) / b: 0.25 sqrt(h) on the simulated tank (h in mm)
    got = [SIM.equilibrium({"h": h})[1][0] for h in (50.0, 100.0, 150.0)]
    assert_allclose(got, [1.767767, 2.5, 3.061862], rtol=1e-6)
    got = [RIG.equilibrium({"h": h})[1][0] for h in (0.5, 1.0)]
    assert_allclose(got, [0.288059, 0.407377], rtol=1e-5)


def test_equilibrium_refuses_bad_levels_and_pump_range():
    with pytest.raises(ValueError, match="'h'"):
        SIM.equilibrium({"H": 1.0})
    with pytest.raises(ValueError, match=">= 0"):
        SIM.equilibrium({"h": -1.0})
    with pytest.raises(ValueError, match="pump range"):
        RIG.equilibrium({"h": 1000.0})  # would need u = 12.9 > 2


def test_linearization_matches_finite_differences_and_is_the_tangent():
    x = np.array([100.0])
    u = np.array([2.7, 0.3])
    A, B = SIM.jacobians(x, u)
    eps = 1e-6
    fd_a = (SIM.rhs(0, x + eps, u) - SIM.rhs(0, x - eps, u)) / (2 * eps)
    fd_b = [
        (SIM.rhs(0, x, u + d) - SIM.rhs(0, x, u - d)) / (2 * eps)
        for d in (np.array([eps, 0.0]), np.array([0.0, eps]))
    ]
    assert_allclose(A[0, 0], fd_a[0], rtol=1e-7)
    assert_allclose(B[0], [fd_b[0][0], fd_b[1][0]], rtol=1e-7)
    # a'/(2 sqrt(h)): half the "pole" a(t) = a'/sqrt(h) of eq. (4b)
    assert A[0, 0] == pytest.approx(-0.5 / (2 * 10.0))
    sys = SIM.linearize(x, u)
    assert sys.input_labels == ["u", "q_d"] and sys.output_labels == ["h"]
    assert_allclose(sys.A, A)
    with pytest.raises(ValueError, match="h=0"):
        SIM.linearize(np.array([0.0]), u)


def test_linearization_at_saturated_pump_has_no_input_gain():
    _, B = RIG.jacobians(np.array([0.5]), np.array([RIG_U_MAX + 1.0, 0.0]))
    assert B[0, 0] == 0.0


def test_pump_saturation_and_disturbance_outflow():
    x = np.array([0.5])
    assert RIG.rhs(0, x, np.array([5.0, 0.0]))[0] == RIG.rhs(0, x, np.array([RIG_U_MAX, 0.0]))[0]
    assert RIG.rhs(0, x, np.array([-1.0, 0.0]))[0] == RIG.rhs(0, x, np.array([0.0, 0.0]))[0]
    base = SIM.rhs(0, np.array([100.0]), np.array([2.5, 0.0]))[0]
    assert base == pytest.approx(0.0)
    assert SIM.rhs(0, np.array([100.0]), np.array([2.5, 0.7]))[0] == pytest.approx(-0.7)
    # one input only: no disturbance
    assert SIM.rhs(0, np.array([100.0]), np.array([2.5]))[0] == pytest.approx(0.0)


def test_empty_tank_cannot_drain_and_never_gives_nan():
    for h in (0.0, -1e-6):
        assert SIM.rhs(0, np.array([h]), np.array([0.0, 0.0]))[0] == 0.0
        assert SIM.rhs(0, np.array([h]), np.array([0.0, 1.0]))[0] == 0.0  # draw-off from empty
        assert SIM.rhs(0, np.array([h]), np.array([1.0, 0.0]))[0] == 2.0  # filling works
    assert SIM.outputs(np.array([-1e-6]))[0] == 0.0


def test_draining_to_empty_follows_torricelli_and_stays_at_zero():
    # u = 0: sqrt(h(t)) = sqrt(h0) - a' t / 2, empty at t* = 2 sqrt(h0) / a' = 40 s from 100 mm
    h0, a = 100.0, SIM_PARAMS.a_prime
    t_empty = 2 * math.sqrt(h0) / a
    x = np.array([h0])
    t = 0.0
    u = np.array([0.0, 0.0])
    for _ in range(120):
        x = rk4(SIM.rhs, t, x, t + 0.5, u, max_step=0.05)
        t += 0.5
        exact = max(math.sqrt(h0) - a * t / 2, 0.0) ** 2
        assert np.isfinite(x[0])
        assert x[0] == pytest.approx(exact, abs=2e-3)
        assert x[0] > -1e-4
    assert t > t_empty and SIM.outputs(x)[0] == pytest.approx(0.0, abs=1e-4)


def test_filling_matches_an_adaptive_solver():
    u = np.array([1.9, 0.0])
    x = np.array([0.0])
    for k in range(40):
        x = rk4(SIM.rhs, k * 1.0, x, (k + 1) * 1.0, u, max_step=0.05)
    ref = solve_ivp(
        lambda t, y: [2.0 * 1.9 - 0.5 * math.sqrt(max(y[0], 0.0))],
        (0, 40),
        [0.0],
        rtol=1e-11,
        atol=1e-11,
    )
    assert x[0] == pytest.approx(ref.y[0, -1], rel=1e-5)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"b": -2.0, "a_prime": 0.5}, "b"),
        ({"b": 2.0, "a_prime": -0.5}, "a_prime"),
        ({"b": 0.0, "a_prime": 0.5}, "b"),
        ({"b": 2.0, "a_prime": 0.5, "u_min": 1.0, "u_max": 0.5}, "u_min"),
        ({"b": 2.0, "a_prime": 0.5, "gain": 1.0}, "gain"),
    ],
)
def test_bad_parameters_are_refused_naming_the_field(kwargs, field):
    with pytest.raises(ValidationError, match=field):
        TankParams(**kwargs)


def test_params_are_frozen():
    with pytest.raises(ValidationError):
        SIM_PARAMS.b = 3.0  # type: ignore[misc]
