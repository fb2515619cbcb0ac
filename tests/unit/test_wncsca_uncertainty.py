"""The model's uncertainty inside the chance method's guarantee (issue 35, item 2).

The draws follow the stated beliefs (closed forms of the truncated normal and the uniform), a
robust model spans its box's corners, each realization of the linear Monte Carlo runs on its own
parameter set (checked against a Monte Carlo built on that set as the agent's exact model: the
same uniforms, so realization by realization), and the non-linear check replays a realization
with its parameters (checked against a direct-engine trial on a scenario written with them).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.stats  # noqa: TID253 - not a node: imports what it uses at the top

from agents.wncsca.chance import ChanceModel, LinearMonteCarlo, LoopLaw
from agents.wncsca.config import ParameterUncertainty
from agents.wncsca.uncertainty import CORNER_SD, TRUNCATE_SD, model_draws
from core.errors import ConfigError
from runtime.direct import loop_model
from scenario import load_scenario
from tests.conftest import SCENARIOS, write_variant

JITTER = SCENARIOS / "jcstr_wncs_jitter.yaml"
U, C_P = 0.1713, 1.0


def _scenario(tmp_path, model: dict, name: str = "u.yaml", **agent):
    def edit(data: dict) -> None:
        data["nodes"]["wncsca"]["model"] = model
        data["nodes"]["wncsca"].update(agent)

    return load_scenario(write_variant(tmp_path, JITTER, name, edit))


def _draws(tmp_path, model: dict, **agent):
    m = loop_model(_scenario(tmp_path, model, **agent))
    return model_draws(m.trials.spec, m.config, seed=0), m


def test_relative_draws_are_a_truncated_normal_and_intervals_uniform(tmp_path):
    model = {
        "reactor": {
            "uncertainty": {"U": {"rel_sd": 0.1}, "C_p": {"interval": [0.8, 1.1]}},
        }
    }
    draws, _ = _draws(tmp_path, model, model_draws=1000)
    assert draws.mode == "probability" and len(draws.sets) == 1000
    u = np.array([s["reactor"]["U"] for s in draws.sets]) / U - 1.0
    cp = np.array([s["reactor"]["C_p"] for s in draws.sets])
    a = TRUNCATE_SD
    sd = 0.1 * math.sqrt(scipy.stats.truncnorm.var(-a, a))
    assert np.max(np.abs(u)) <= 0.1 * a + 1e-12
    assert abs(np.mean(u)) < 4 * sd / math.sqrt(1000)
    assert np.std(u) == pytest.approx(sd, rel=0.1)
    assert cp.min() >= 0.8 and cp.max() <= 1.1
    assert scipy.stats.kstest(cp, "uniform", args=(0.8, 0.3)).pvalue > 1e-3
    again, _ = _draws(tmp_path, model, model_draws=1000)
    assert again.sets == draws.sets  # seeded: the same draws every time


def test_a_robust_model_spans_the_corners_of_its_box(tmp_path):
    model = {"reactor": {"uncertainty": {"U": {"rel_sd": 0.1}, "C_p": {"interval": [0.8, 1.1]}}}}
    draws, _ = _draws(tmp_path, model, uncertainty="robust")
    assert draws.mode == "robust"
    corners = {(round(s["reactor"]["U"], 12), s["reactor"]["C_p"]) for s in draws.sets}
    lo, hi = U * (1 - CORNER_SD * 0.1), U * (1 + CORNER_SD * 0.1)
    expected = {(round(a, 12), b) for a in (lo, hi) for b in (0.8, 1.1)}
    assert corners == expected


def test_without_uncertainty_there_is_one_set_the_model_itself(tmp_path):
    draws, _ = _draws(tmp_path, {"reactor": {"params": {"U": 0.18}}})
    assert draws.exact and draws.sets == ({},)


def test_each_realization_runs_on_its_own_parameter_set(tmp_path):
    """Realization ``r`` of the Monte Carlo over draws equals realization ``r`` of a Monte Carlo
    whose exact model has set ``r mod M`` as its parameters (same seed: same uniforms)."""
    model = {"reactor": {"uncertainty": {"U": {"rel_sd": 0.1}}}}
    m = loop_model(_scenario(tmp_path, model, model_draws=3))
    draws = model_draws(m.trials.spec, m.config, seed=5)
    laws = {"level": LoopLaw(), "temperature": LoopLaw((0.0, 1.0), (0.0, 0.04), 0.02)}
    periods, delays = {"level": 0.2, "temperature": 0.1}, {"level": 0.1, "temperature": 0.08}
    mixed = LinearMonteCarlo(m, laws, 12, seed=5, draws=draws).overshoots(periods, delays)
    for k, params in enumerate(draws.sets):
        exact = loop_model(
            _scenario(tmp_path, {"reactor": {"params": params["reactor"]}}, f"d{k}.yaml")
        )
        alone = LinearMonteCarlo(exact, laws, 12, seed=5).overshoots(periods, delays)
        rows = np.arange(12) % 3 == k
        assert np.allclose(mixed[rows], alone[rows], rtol=1e-9, atol=1e-9)
        assert not np.allclose(mixed[~rows, 1], alone[~rows, 1], rtol=1e-6)  # sets differ


def test_the_check_replays_a_realization_with_its_parameters(tmp_path):
    model = {"reactor": {"uncertainty": {"U": {"interval": [0.15, 0.2]}}}}
    m = loop_model(_scenario(tmp_path, model, model_draws=4, realizations=16, checks=4))
    chance = ChanceModel(m, {"level": LoopLaw(), "temperature": LoopLaw()})
    periods, delays = {"level": 0.2, "temperature": 0.1}, {"level": 0.1, "temperature": 0.08}
    out = chance.check(periods, delays)
    r = int(np.argsort(chance.samples(periods, delays)[:, 1])[-1])  # any realization will do
    traces, phases = chance.linear.traces(periods, delays, r)
    params = chance.linear.params_of(r)
    assert params["reactor"]["U"] != U
    rec = m.trials.run_replay(periods, delays, traces, phases, 64, params)
    # the same trial written by hand: a scenario that believes the drawn U exactly
    exact = loop_model(_scenario(tmp_path, {"reactor": {"params": params["reactor"]}}, "x.yaml"))
    again = exact.trials.run_replay(periods, delays, traces, phases, 64)
    assert m.overshoots_of(rec) == exact.overshoots_of(again)
    assert out["checks"] >= 2 and all(math.isfinite(v) for v in out["offsets"].values())


def test_uncertainty_widens_the_risk_and_the_decision_says_what_it_assumed(tmp_path):
    """At the same periods, a 10 % belief about U puts the temperature's risk overshoot above
    the exact model's (the tail now holds plants with a weaker jacket)."""
    periods, delays = {"level": 0.175, "temperature": 0.075}, {"level": 0.17, "temperature": 0.1}
    laws = {"level": LoopLaw(), "temperature": LoopLaw((0.0, 1.0), (0.0, 0.06), 0.0)}
    exact = ChanceModel(loop_model(load_scenario(JITTER)), laws)
    unsure = ChanceModel(
        loop_model(_scenario(tmp_path, {"reactor": {"uncertainty": {"U": {"rel_sd": 0.1}}}})),
        laws,
    )
    a = exact.evaluate(periods, delays).overshoot_pct["temperature"]
    b = unsure.evaluate(periods, delays).overshoot_pct["temperature"]
    assert b > a + 0.5, (a, b)
    assert unsure.draws.describe().startswith("model uncertainty reactor.U +-10 % (1 sd)")
    assert unsure.fingerprint != exact.fingerprint


def test_uncertainty_under_a_method_that_takes_the_model_as_exact_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="the paper method takes the model as exact"):
        _scenario(tmp_path, {"reactor": {"uncertainty": {"U": {"rel_sd": 0.1}}}}, method="paper")


def test_a_bad_uncertainty_is_refused():
    with pytest.raises(ValueError, match="exactly one of rel_sd or interval"):
        ParameterUncertainty(rel_sd=0.1, interval=(0.1, 0.2))
    with pytest.raises(ValueError, match="low"):
        ParameterUncertainty(interval=(0.2, 0.1))
