"""Tanks in series (plants/tank_train.py): seed 002's tank, eq. (3), with a share c of each
tank's outflow feeding the next: equilibrium, linearization and coupling against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from scipy.integrate import solve_ivp
from scipy.optimize import root

from plants import linearization
from plants.integrate import integrator_of, rk4
from plants.registry import build
from plants.tank import SIM_PARAMS, Tank
from plants.tank_train import TankTrain, TankTrainParams

B, A, C = 2.0, 0.5, 0.5  # seed 002 eq. (22); half of each outflow feeds the next tank
LEVELS = [60.0, 70.0, 80.0, 90.0, 100.0, 60.0]  # mm
N = len(LEVELS)
TRAIN = TankTrain(TankTrainParams(n=N, b=B, a_prime=A, c=C))
Y_BAR = {f"h{i}": h for i, h in enumerate(LEVELS)}


def closed_form_u(levels, b=B, a=A, c=C):
    """u_i* = (a' sqrt(h_i) - c a' sqrt(h_{i-1})) / b, h_{-1} = 0."""
    return [
        (a * math.sqrt(h) - (c * a * math.sqrt(levels[i - 1]) if i else 0.0)) / b
        for i, h in enumerate(levels)
    ]


def test_names_and_registry():
    plant = build("tank_train", {"n": 3, "b": B, "a_prime": A, "c": C})
    assert isinstance(plant, TankTrain)
    assert plant.state_names == ("h0", "h1", "h2") == plant.output_names
    assert plant.input_names == ("u0", "u1", "u2")
    assert TRAIN.state_names[-1] == f"h{N - 1}"


def test_rhs_is_the_model_equation():
    rng = np.random.default_rng(1)
    x = rng.uniform(10.0, 150.0, N)
    u = rng.uniform(0.5, 3.0, N)
    expected = [
        B * u[i] + (C * A * math.sqrt(x[i - 1]) if i else 0.0) - A * math.sqrt(x[i])
        for i in range(N)
    ]
    assert_allclose(TRAIN.rhs(0.0, x, u), expected, rtol=1e-13, atol=1e-13)
    assert TRAIN.rhs(0.0, x, u).tolist() == list(TRAIN.rhs_tuple(0.0, x.tolist(), u.tolist()))


def test_without_coupling_it_is_n_independent_tanks():
    loose = TankTrain(TankTrainParams(n=N, b=B, a_prime=A, c=0.0))
    tank = Tank(SIM_PARAMS)
    x = np.array(LEVELS)
    u = np.linspace(0.5, 3.0, N)
    for i in range(N):
        assert loose.rhs(0, x, u)[i] == tank.rhs(0, x[i : i + 1], np.array([u[i], 0.0]))[0]


def test_equilibrium_is_the_closed_form_and_solves_rhs_zero():
    x_bar, u_bar = TRAIN.equilibrium(Y_BAR)
    assert x_bar.tolist() == LEVELS
    assert_allclose(u_bar, closed_form_u(LEVELS), rtol=1e-14)
    assert_allclose(TRAIN.rhs(0.0, x_bar, u_bar), 0.0, atol=1e-12)
    # independent: the pumps that make every derivative zero, by a root solve from elsewhere
    sol = root(lambda u: TRAIN.rhs(0.0, x_bar, u), np.full(N, 2.0), tol=1e-14)
    assert sol.success
    assert_allclose(u_bar, sol.x, rtol=1e-10)
    # a tank downstream of a fuller one needs less pump than alone (the inflow helps)
    alone = [A * math.sqrt(h) / B for h in LEVELS]
    assert u_bar[0] == pytest.approx(alone[0]) and all(u_bar[1:] < alone[1:])


def test_equilibrium_refuses_missing_or_negative_levels_and_a_pump_below_its_range():
    with pytest.raises(ValueError, match="h5"):
        TRAIN.equilibrium({k: v for k, v in Y_BAR.items() if k != "h5"})
    with pytest.raises(ValueError, match=">= 0"):
        TRAIN.equilibrium({**Y_BAR, "h2": -1.0})
    # h_1 < c^2 h_0: the upstream inflow alone would overfill tank 1 (u_1* < 0 = u_min)
    with pytest.raises(ValueError, match="u1"):
        TRAIN.equilibrium({**Y_BAR, "h0": 100.0, "h1": 24.0})
    TRAIN.equilibrium({**Y_BAR, "h0": 100.0, "h1": 25.0})  # exactly c^2 h_0: u_1* = 0
    capped = TankTrain(TankTrainParams(n=2, b=B, a_prime=A, c=C, u_max=2.0))
    with pytest.raises(ValueError, match="pump range"):
        capped.equilibrium({"h0": 100.0, "h1": 50.0})  # u_0* = 2.5 > 2


def test_the_generic_equilibrium_takes_the_closed_form():
    x0, u0 = np.full(N, 50.0), np.ones(N)
    x_bar, u_bar = linearization.equilibrium(TRAIN, Y_BAR, x0, u0, range(N))
    assert_allclose(u_bar, closed_form_u(LEVELS), rtol=1e-14)


def test_linearization_is_the_closed_form_and_matches_finite_differences():
    x_bar, u_bar = TRAIN.equilibrium(Y_BAR)
    A_, B_ = TRAIN.jacobians(x_bar, u_bar)
    expected = np.zeros((N, N))
    for i, h in enumerate(LEVELS):
        expected[i, i] = -A / (2.0 * math.sqrt(h))  # the tank's own tangent
        if i:
            expected[i, i - 1] = C * A / (2.0 * math.sqrt(LEVELS[i - 1]))  # from upstream
    assert_allclose(A_, expected, rtol=1e-14)
    assert_allclose(B_, B * np.eye(N))
    fd_a, fd_b, fd_c = linearization.jacobians(TRAIN, x_bar, u_bar)  # central differences
    assert_allclose(A_, fd_a, rtol=1e-6, atol=1e-10)
    assert_allclose(B_, fd_b, rtol=1e-6, atol=1e-10)
    assert_allclose(fd_c, np.eye(N), atol=1e-9)
    sys = TRAIN.linearize(x_bar, u_bar)
    assert sys.input_labels == list(TRAIN.input_names)
    assert sys.output_labels == list(TRAIN.output_names)
    assert_allclose(sys.A, A_)
    # lower triangular: the poles are the tanks' own, -a'/(2 sqrt(h_i))
    assert_allclose(np.sort(np.linalg.eigvals(A_).real), np.sort(np.diag(expected)))
    with pytest.raises(ValueError, match="h3"):
        TRAIN.jacobians(np.array([*LEVELS[:3], 0.0, *LEVELS[4:]]), u_bar)


def test_a_saturated_pump_has_no_input_gain():
    capped = TankTrain(TankTrainParams(n=2, b=B, a_prime=A, c=C, u_max=2.0))
    _, B_ = capped.jacobians(np.array([50.0, 50.0]), np.array([3.0, 1.0]))
    assert B_[0, 0] == 0.0 and B_[1, 1] == B
    x = np.array([50.0, 50.0])
    assert (
        capped.rhs(0, x, np.array([3.0, -1.0])).tolist()
        == capped.rhs(0, x, np.array([2.0, 0.0])).tolist()
    )


def _open_loop(u: np.ndarray, t_end: float = 20.0) -> np.ndarray:
    step = integrator_of(TRAIN)
    x0, _ = TRAIN.equilibrium(Y_BAR)
    return step(0.0, x0, t_end, u, max_step=0.05)


@pytest.mark.parametrize("k", [0, 2, N - 1])
def test_a_pump_moves_its_tank_and_every_tank_downstream_and_none_upstream(k):
    x0, u_bar = TRAIN.equilibrium(Y_BAR)
    assert_allclose(_open_loop(u_bar), x0, atol=1e-9)  # at rest it stays
    u = u_bar.copy()
    u[k] += 0.5
    x = _open_loop(u)
    assert x[:k].tolist() == _open_loop(u_bar)[:k].tolist()  # upstream: not a bit changes
    assert np.all(x[k:] > x0[k:] + 1e-6)  # the tank and all downstream rise
    # the first-order reach of the step: the tank rises most, then less and less downstream
    rise = x[k:] - x0[k:]
    assert np.all(np.diff(rise) < 0)


def test_open_loop_matches_an_adaptive_solver():
    _, u_bar = TRAIN.equilibrium(Y_BAR)
    u = u_bar + np.linspace(-0.3, 0.4, N)
    x_rk4 = _open_loop(u, t_end=30.0)

    def f(t, h):
        return [
            B * u[i] + (C * A * math.sqrt(h[i - 1]) if i else 0.0) - A * math.sqrt(h[i])
            for i in range(N)
        ]

    ref = solve_ivp(f, (0.0, 30.0), LEVELS, rtol=1e-11, atol=1e-11)
    assert_allclose(x_rk4, ref.y[:, -1], rtol=1e-7)


def test_an_empty_tank_cannot_drain_sends_nothing_downstream_and_never_gives_nan():
    plant = TankTrain(TankTrainParams(n=3, b=B, a_prime=A, c=C, u_min=-1.0))
    for h in (0.0, -1e-6):
        d = plant.rhs(0, np.array([h, 40.0, 40.0]), np.array([-1.0, 1.0, 1.0]))
        assert d[0] == 0.0  # draining an empty tank: nothing happens
        assert d[1] == pytest.approx(B * 1.0 - A * math.sqrt(40.0))  # no inflow from it
        d = plant.rhs(0, np.array([40.0, h, 40.0]), np.array([1.0, 0.0, 1.0]))
        assert d[1] == pytest.approx(C * A * math.sqrt(40.0))  # filled from upstream only
    assert plant.outputs(np.array([-1e-6, 3.0, 0.0])).tolist() == [0.0, 3.0, 0.0]
    x = np.array([1.0, 1.0, 1.0])
    for k in range(40):  # pumps off: all drain to empty and stay there, finite
        x = rk4(plant.rhs, k * 1.0, x, (k + 1) * 1.0, np.zeros(3), max_step=0.05)
        assert np.all(np.isfinite(x)) and np.all(x > -1e-4)
    assert_allclose(plant.outputs(x), 0.0, atol=1e-4)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"n": 0}, "n"),
        ({"c": 1.0}, "c"),
        ({"c": -0.1}, "c"),
        ({"b": 0.0}, "b"),
        ({"a_prime": -0.5}, "a_prime"),
        ({"u_min": 1.0, "u_max": 0.5}, "u_min"),
        ({"gain": 1.0}, "gain"),
    ],
)
def test_bad_parameters_are_refused_naming_the_field(kwargs, field):
    with pytest.raises(ValidationError, match=field):
        TankTrainParams(**{"n": 3, "b": B, "a_prime": A, "c": C, **kwargs})
