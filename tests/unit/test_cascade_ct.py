"""The continuous-time primary/secondary process of the monitor's bus scenario."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from plants import registry
from plants.cascade.plant import CascadeCT, CascadeCTParams, step_response
from plants.integrate import integrator_of, rk4
from plants.knots import CHUNK
from scenario import load_scenario
from tests.conftest import SCENARIOS

PLANT = CascadeCT(CascadeCTParams())


def test_rhs_is_the_linear_model_plus_the_disturbance_drive():
    x = np.linspace(-1.0, 1.0, len(PLANT.state_names))
    a, b = PLANT.jacobians()
    diff = PLANT.rhs(12.3, x, np.array([0.4])) - (a @ x + b[:, 0] * 0.4)
    w1, w2, w3 = PLANT.noise(12.3)
    drive = np.zeros(len(x))
    p = PLANT.params
    drive[-3:] = [
        p.d1_std * np.sqrt(2 * p.d1_tau / p.noise_period) * w1 / p.d1_tau,
        p.d2_std * np.sqrt(2 * p.d2_tau / p.noise_period) * w2 / p.d2_tau,
        p.d3_std * np.sqrt(2 * p.d3_tau / p.noise_period) * w3 / p.d3_tau,
    ]
    assert_allclose(diff, drive, atol=1e-12)
    assert PLANT.state_names[:3] == ("y3", "y2", "z1") and PLANT.state_names[-4:] == (
        "y1",
        "n1",
        "n2",
        "n3",
    )
    ss = PLANT.linearize(x, np.array([0.0]))
    assert ss.noutputs == 3 and ss.nstates == len(x)


def test_equilibrium_and_gains():
    plant = CascadeCT(CascadeCTParams(K1=2.0, K2=0.5, K3=4.0))
    x, u = plant.equilibrium({"y1": 3.0})
    a, b = plant.jacobians()
    assert_allclose(a @ x + b[:, 0] * u[0], 0.0, atol=1e-12)
    assert u[0] == pytest.approx(3.0 / 4.0) and plant.outputs(x).tolist() == [3.0, 1.5, 3.0]


def test_disturbance_is_a_pure_function_of_time():
    """Same values whatever order rhs is evaluated in, and continuous across knots and chunks."""
    p = CascadeCTParams(seed=7)
    ts = np.r_[np.linspace(0.0, 3.0 * CHUNK * p.noise_period, 997), CHUNK * p.noise_period]
    fwd = [CascadeCT(p).noise(t) for t in ts]
    other = CascadeCT(p)
    back = [other.noise(t) for t in ts[::-1]][::-1]
    assert fwd == back
    k = CHUNK  # a chunk boundary: continuous from both sides
    left = other.noise(k * p.noise_period - 1e-9)
    right = other.noise(k * p.noise_period)
    assert_allclose(left, right, atol=1e-6)
    assert CascadeCT(CascadeCTParams(seed=8)).noise(1.1) != other.noise(1.1)


def test_tuple_integrator_is_bit_identical():
    x0 = np.linspace(-0.5, 0.5, len(PLANT.state_names))
    u = np.array([0.3])
    a = rk4(PLANT.rhs, 0.1, x0, 1.87, u, max_step=0.125)
    b = integrator_of(PLANT)(0.1, x0, 1.87, u, max_step=0.125)
    assert a.tolist() == b.tolist()


def test_disturbances_have_about_their_stated_spread():
    step = integrator_of(PLANT)
    x = np.zeros(len(PLANT.state_names))
    xs = []
    for k in range(4000):
        x = step(float(k), x, float(k + 1), np.array([0.0]), max_step=0.25)
        xs.append(x[-3:])
    std = np.std(np.array(xs)[200:], axis=0)
    assert_allclose(std, [0.2, 0.3, 0.05], rtol=0.25)  # slow drifts: few independent values
    assert std[2] == pytest.approx(0.05, rel=0.1)


def test_delays_of_the_scenario_read_off_the_step_response():
    """scenarios/cascade_routine.yaml: y2, y3 move within one sample (d2 = 1); y1 stays near 1 %
    of its gain for 4 samples and then rises (d = 4)."""
    r = step_response(CascadeCTParams(), 1.0, 6)
    assert r["y3"][0] > 0.8 and r["y2"][0] > 0.2
    assert r["y1"][3] < 0.011 < 0.03 < r["y1"][4]
    assert r["y1"][-1] < 0.1 and r["z8"][0] < 0.001


def test_registered_and_the_scenario_validates():
    assert isinstance(registry.build("cascade_ct", {"theta": 2.0, "n_lag": 4}), CascadeCT)
    sc = load_scenario(SCENARIOS / "cascade_routine.yaml")
    assert sc.nodes["reactor"].build().output_names == ("y1", "y2", "y3")
    with pytest.raises(ValueError, match="n_lag"):
        CascadeCTParams(theta=0.0, n_lag=3)
    assert CascadeCT(CascadeCTParams(theta=0.0, n_lag=0)).state_names == (
        "y3",
        "y2",
        "y1",
        "n1",
        "n2",
        "n3",
    )
