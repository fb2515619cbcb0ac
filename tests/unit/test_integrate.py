"""The fixed-step RK4 integrator against scipy's adaptive solver."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from plants.integrate import integrator_of, rk4, rk4_tuple
from plants.jcstr import BENCHMARK_PARAMS, JCSTR

PLANT = JCSTR(BENCHMARK_PARAMS)


def test_rk4_matches_solve_ivp_on_the_jcstr():
    x0 = np.array([0.66, 50.0, 143.0])
    u = np.array([1.2, 0.8])
    ours = rk4(PLANT.rhs, 0.0, x0, 1.0, u, max_step=0.005)
    ref = solve_ivp(lambda t, x: PLANT.rhs(t, x, u), (0, 1.0), x0, rtol=1e-11, atol=1e-12).y[:, -1]
    assert_allclose(ours, ref, rtol=1e-8)


def test_rk4_is_exact_for_linear_time():
    f = lambda t, x, u: np.array([u[0]])  # noqa: E731
    assert_allclose(rk4(f, 0.3, np.array([1.0]), 1.1, np.array([2.0]), max_step=0.1), [2.6])


def test_empty_segment_returns_the_state():
    x0 = np.array([0.7, 52.0, 140.0])
    x = rk4(PLANT.rhs, 1.0, x0, 1.0, np.array([1.0, 0.5]), max_step=0.005)
    assert np.array_equal(x, x0) and x is not x0


def test_tuple_integrator_is_bit_identical_to_the_numpy_one():
    x0 = (0.66, 50.0, 143.0)
    u = (9.0, 0.8)
    a = rk4(PLANT.rhs, 0.1, np.array(x0), 0.87, np.array(u), max_step=0.005)
    b = rk4_tuple(PLANT.rhs_tuple, 0.1, x0, 0.87, u, max_step=0.005)
    assert a.tolist() == list(b)  # exactly, not approximately: engines must agree bit for bit
    step = integrator_of(PLANT)
    assert step(0.1, np.array(x0), 0.87, np.array(u), max_step=0.005).tolist() == list(b)


def test_tuple_integrator_is_bit_identical_for_every_dimension():
    """The written-out loops (one per state dimension) do numpy's operations in numpy's order."""

    def rhs(t, x, u):  # only + and *: numpy and Python floats round alike
        return -0.3 * x + 0.2 * np.roll(x, 1) * np.roll(x, -1) + u[0] + 0.01 * t

    def rhs_tuple(t, x, u):
        n = len(x)
        return tuple(
            -0.3 * x[i] + 0.2 * x[i - 1] * x[(i + 1) % n] + u[0] + 0.01 * t for i in range(n)
        )

    rng = np.random.default_rng(7)
    for dim in (1, 2, 3, 5, 14):
        x0 = rng.uniform(-2.0, 2.0, dim)
        t1 = 0.2 + rng.uniform(0.0, 0.1)  # not a whole number of steps
        a = rk4(rhs, 0.2, x0, 0.2 + t1, np.array([0.4]), max_step=0.013)
        b = rk4_tuple(rhs_tuple, 0.2, tuple(x0.tolist()), 0.2 + t1, (0.4,), max_step=0.013)
        assert a.tolist() == list(b), dim
    assert rk4_tuple(rhs_tuple, 0.0, (), 1.0, (0.4,), max_step=0.1) == ()
