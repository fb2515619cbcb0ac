"""The chance method's parts (issue 14): delay distributions, the linear Monte Carlo against the
direct engine, the probability estimates, the jitter margin's closed form, and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.stats  # noqa: TID253 - not a node: imports what it uses at the top
from pydantic import ValidationError

from agents.wncsca.chance import (
    ChanceModel,
    LoopLaw,
    _Uniforms,
    probability_interval,
    risk_index,
)
from agents.wncsca.config import WncscaConfig
from agents.wncsca.decision import control_path_delays
from agents.wncsca.jitter import FREQUENCIES, delay_variation, jitter_margin
from bus_schemas import DelayDistribution
from bus_schemas.errors import SchemaError
from gateway import distribution
from gateway.delay_models import ConstantDelay, ExponentialDelay
from gateway.paths import Hop, Route
from runtime.direct import loop_model
from scenario import load_scenario
from tests.agent_requests import typed_paths
from tests.conftest import SCENARIOS


def _route(*hops: Hop) -> Route:
    return Route(tuple(hops))


def test_the_predicted_loss_is_the_closed_form_and_the_delays_are_whole_attempts():
    """Two constant hops (0.05 per attempt), PRR 0.9 and 0.8, 2 retries: every delivered delay
    is 0.05 x (attempts on hop 1 + attempts on hop 2), the loss ``1 - prod(1 - q^3)``."""
    route = _route(
        Hop("a", "b", 0.9, ConstantDelay(delay=0.05), 2),
        Hop("b", "c", 0.8, ConstantDelay(delay=0.05), 2),
    )
    d = distribution.predict(route, 0, np.random.default_rng(1))
    assert d.loss == pytest.approx(1 - (1 - 0.1**3) * (1 - 0.2**3), rel=1e-12)
    attempts = np.asarray(d.delays) / 0.05
    assert np.allclose(attempts, np.rint(attempts), atol=1e-9)
    assert d.delays[0] == pytest.approx(0.10) and d.delays[-1] <= 0.30 + 1e-12
    # P(both hops first time | delivered) = 0.9 x 0.8 / P(delivered): the share at 0.10
    p_fast = 0.9 * 0.8 / ((1 - 0.1**3) * (1 - 0.2**3))
    at_min = float(np.interp(0.10 + 1e-9, d.delays, d.probabilities))
    sigma = math.sqrt(p_fast * (1 - p_fast) / distribution.PREDICTION_PACKETS)
    assert abs(at_min - p_fast) < 4 * sigma + 0.025  # the quantile grid's step is 0.025


def test_the_predicted_quantiles_of_an_exponential_hop_are_its_closed_form():
    """One hop, PRR 1: delay = base + Exp(mean), quantile ``base - mean ln(1 - p)``."""
    route = _route(Hop("a", "b", 1.0, ExponentialDelay(base=0.03, mean=0.02), 0))
    d = distribution.predict(route, 0, np.random.default_rng(7))
    assert d.loss == 0.0
    for p in (0.25, 0.5, 0.75, 0.9, 0.95):
        exact = 0.03 - 0.02 * math.log(1 - p)
        # sampling error of a quantile: sqrt(p (1 - p) / n) / density at it
        density = math.exp(-(exact - 0.03) / 0.02) / 0.02
        se = math.sqrt(p * (1 - p) / distribution.PREDICTION_PACKETS) / density
        assert distribution.quantile(d, p) == pytest.approx(exact, abs=4 * se + 2e-6)
    assert distribution.mean(d) == pytest.approx(0.05, rel=0.03)


def test_the_measured_distribution_counts_what_a_path_carried():
    carried = [(0, 100_000), (10, None), (20, 170_020), (30, None), (40, 50_040)]
    d = distribution.measured(carried)
    assert d is not None and d.source == "measured" and d.count == 5
    assert d.loss == pytest.approx(2 / 5)
    assert d.delays[0] == pytest.approx(0.05) and d.delays[-1] == pytest.approx(0.17)
    assert sum(d.counts) == 3
    assert distribution.measured([(0, None)]) is None


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"delays": (-0.01, 0.1)}, "delays.0"),
        ({"probabilities": (0.0, 1.5)}, "probabilities"),
        ({"probabilities": (-0.5, 1.0)}, "probabilities"),
        ({"loss": 1.2}, "loss"),
        ({"loss": -0.1}, "loss"),
        ({"delays": (0.2, 0.1)}, "delays"),
    ],
)
def test_a_malformed_distribution_is_refused_naming_the_field(change, field):
    good = {"source": "model", "probabilities": (0.0, 1.0), "delays": (0.1, 0.2), "loss": 0.0}
    DelayDistribution.model_validate({**good, "count": 1})
    with pytest.raises(ValidationError) as err:
        DelayDistribution.model_validate({**good, "count": 1, **change})
    assert field in str(err.value)


def test_a_proposal_with_a_bad_distribution_is_refused_naming_path_and_field():
    entry = {
        "hops": 2,
        "route": ["s", "r", "gw"],
        "estimates": {"hops": 0.1},
        "distribution": {
            "source": "model",
            "probabilities": [0.0, 1.0],
            "delays": [0.1, -0.2],
            "loss": 0.0,
            "count": 10,
        },
    }
    with pytest.raises(SchemaError) as err:  # the agent node refuses it with these problems
        typed_paths({"level.sensor": entry})
    assert err.value.problems[0].startswith("paths.level.sensor.distribution"), err.value.problems


@pytest.mark.parametrize("confidence", [0.0, 1.0, 1.5, -0.1])
def test_a_confidence_outside_the_open_unit_interval_is_refused(confidence):
    with pytest.raises(ValidationError, match="confidence"):
        WncscaConfig(confidence=confidence)


def test_the_clopper_pearson_interval_and_the_exceedances_allowed():
    assert risk_index(400, 0.95) == 20 and risk_index(256, 0.95) == 12
    lo, hi = probability_interval(20, 20)
    assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / 20), rel=1e-9)
    lo, hi = probability_interval(90, 100)
    assert lo == pytest.approx(scipy.stats.beta.ppf(0.025, 90, 11), rel=1e-12)
    assert hi == pytest.approx(scipy.stats.beta.ppf(0.975, 91, 10), rel=1e-12)


def test_the_jitter_margin_of_an_integrator_loop_is_one_over_its_gain():
    """``L = k / s`` (Kao-Lincoln): ``w |T| = w k / sqrt(w^2 + k^2)`` rises to ``k``."""
    for k in (0.5, 2.0, 10.0):
        s = 1j * FREQUENCIES
        T = (k / s) / (1 + k / s)
        assert jitter_margin(T, FREQUENCIES) == pytest.approx(1 / k, rel=1e-6)


def test_the_jitter_margin_of_a_first_order_loop_with_a_pole_has_its_closed_form():
    """``L = k / (s (s + a))``: the supremum of ``w |T|`` by brute force on a dense grid of its
    closed form ``w k / |k - w^2 + j a w|``, against the module's."""
    k, a = 4.0, 1.0
    w = FREQUENCIES
    T = k / ((1j * w) * (1j * w + a) + k)
    dense = np.linspace(0.01, 100, 2_000_001)
    peak = np.max(dense * k / np.abs(k - dense**2 + 1j * a * dense))
    assert jitter_margin(T, w) == pytest.approx(1 / peak, rel=1e-4)


def test_the_delay_variation_adds_the_spread_the_hold_and_the_loss_bursts():
    law = LoopLaw((0.0, 0.5, 0.999, 1.0), (0.1, 0.15, 0.3, 0.4), loss=0.05)
    nominal, variation = delay_variation(law, law.mean, 0.2)
    assert nominal == pytest.approx(0.1)
    # spread to q0.999 (0.2), one period (0.2), 0.05^2 = 2.5e-3 >= 1e-3: two bursts (0.4)
    assert variation == pytest.approx(0.2 + 0.2 + 0.4)


@pytest.fixture(scope="module")
def demo_model():
    return loop_model(load_scenario(SCENARIOS / "jcstr_wncs_jitter.yaml"))


def test_the_linear_monte_carlo_equals_the_direct_engine_on_the_linear_level_loop(demo_model):
    """The JCSTR level is a linear plant: with random delays per sample, losses and step phases,
    the linear Monte Carlo and the replay of the same realizations on the direct engine give the
    same overshoot (the two share no code: modal exponentials against RK4 on the non-linear
    right-hand side, numpy PI against the controller node)."""
    cfg = demo_model.config.model_copy(update={"realizations": 16, "checks": 8})
    demo_model.config = cfg
    law = LoopLaw((0.0, 0.5, 0.9, 1.0), (0.10, 0.16, 0.26, 0.40), loss=0.05)
    model = ChanceModel(demo_model, {"level": law, "temperature": LoopLaw()})
    periods = {"level": 0.2, "temperature": 0.1}
    delays = {"level": 0.17, "temperature": 0.1}
    linear = model.samples(periods, delays)
    out = model.check(periods, delays)
    assert out["checks"] >= 4
    nonlinear = out["nonlinear_overshoot_pct"]["level"]
    assert np.allclose(nonlinear, out["linear_overshoot_pct"]["level"], atol=1e-6)
    assert len(set(np.round(linear[:, 0], 3))) > 4  # the realizations differ
    assert abs(model.offsets["level"]) < 1e-6


def test_the_quantile_estimate_is_the_distributions_quantile_for_the_paper_method():
    entry = {
        "hops": 2,
        "route": ["s", "r", "gw"],
        "estimates": {"hops": 0.1, "ping": 0.12, "timestamps": None},
        "distribution": {
            "source": "model",
            "probabilities": [0.0, 0.5, 0.9, 1.0],
            "delays": [0.05, 0.1, 0.2, 0.4],
            "loss": 0.01,
            "count": 100,
        },
    }
    delays, used = control_path_delays(
        typed_paths({"level.sensor": entry}), ("level",), "quantile", 0.95
    )
    assert used == {"level.sensor": "quantile"}
    assert delays["level"] == pytest.approx(0.2 + 0.5 * 0.2)  # halfway from q0.9 to q1
    no_dist = {k: v for k, v in entry.items() if k != "distribution"}
    delays, used = control_path_delays(
        typed_paths({"level.sensor": no_dist}), ("level",), "quantile", 0.95
    )
    assert used == {"level.sensor": "ping"} and delays["level"] == pytest.approx(0.12)
    with pytest.raises(ValidationError, match="estimate: quantile"):
        WncscaConfig(method="chance", estimate="quantile")
    WncscaConfig(method="paper", estimate="quantile")


def test_the_common_random_numbers_of_a_sample_do_not_depend_on_the_period():
    short, long_ = _Uniforms(np.random.default_rng(3), 5), _Uniforms(np.random.default_rng(3), 5)
    first = short.take(10).copy()
    assert np.array_equal(long_.take(200)[:, :10], first)
    assert np.array_equal(short.take(130)[:, :10], first)
