"""The fast and chance methods judge seed 002's non-linear PI (issue 35, item 7).

``scenarios/tank_wsn_chance.yaml``: the tank of seed 002 and its feedback-linearizing PI
(``law: nlpi``) on a jittery, lossy two-hop WSN under the default agent (``method: chance``).
The methods execute the law as it is and linearise only the plant (:mod:`agents.wncsca.laws`),
so each prediction is checked here against the direct engine, which shares none of that code
(RK4 on the tank's non-linear right-hand side, the controller node's law):

* the chance method's realizations (random delays per sample, losses, step phases) replayed on
  the non-linear tank give the linear Monte Carlo's overshoots to the tank's linearisation error
  (measured 0.05-0.3 points on the 50 -> 100 mm step);
* the fast method's prediction is the non-linear tank's overshoot at every period and delay;
* the scenario runs: the agent accepts the proposal with periods whose stated probability is at
  least the confidence, and the steps that follow keep the limit (and every message comes from
  an owner of its key: ``tests/unit/test_ownership.py`` leaves this scenario to this run).
"""

from __future__ import annotations

import numpy as np
import pytest

from agents.wncsca.chance import ChanceModel, LoopLaw
from agents.wncsca.config import WncscaConfig
from agents.wncsca.fast import LinearPredictor
from core.record import loop_metrics
from runtime.direct import loop_model, simulate
from runtime.ownership import owners_of, publishers
from runtime.scale import scale_scenario
from scenario import Scenario, load_scenario
from tests.conftest import SCENARIOS

TANK = SCENARIOS / "tank_wsn_chance.yaml"
LINEARISATION = 0.5
"""Points of overshoot the tank's linearisation may cost on its steps (measured at most 0.3)."""


def _model(**update):
    scenario = load_scenario(TANK)
    agent = scenario.nodes["wncsca"]
    return loop_model(scenario, type(agent).model_validate({**agent.model_dump(), **update}))


def test_the_chance_realizations_replayed_on_the_nonlinear_tank_agree():
    model = ChanceModel(
        _model(realizations=16, checks=8),
        {"level": LoopLaw((0.0, 0.5, 0.9, 1.0), (0.2, 0.35, 0.6, 0.9), loss=0.05)},
    )
    periods, delays = {"level": 0.3}, {"level": 0.45}
    linear = model.samples(periods, delays)[:, 0]
    out = model.check(periods, delays)
    nonlinear = np.array(out["nonlinear_overshoot_pct"]["level"])
    paired = np.array(out["linear_overshoot_pct"]["level"])
    assert out["checks"] == 8
    assert np.abs(nonlinear - paired).max() < LINEARISATION, (nonlinear, paired)
    assert len(set(np.round(linear, 2))) > 8  # the realizations differ
    assert nonlinear.min() > 1.0  # steps that overshoot: a comparison of something


def test_a_drawn_tank_gets_the_law_designed_on_it_and_the_replays_agree():
    """With ``b`` and ``a'`` uncertain, each draw's law is designed on the drawn tank (the law
    takes them from its plant, as the controller node does): gains per realization."""
    uncertain = {"tank": {"uncertainty": {"a_prime": {"rel_sd": 0.2}, "b": {"rel_sd": 0.1}}}}
    model = ChanceModel(
        _model(realizations=40, checks=8, model=uncertain),
        {"level": LoopLaw((0.0, 0.5, 0.9, 1.0), (0.2, 0.35, 0.6, 0.9), loss=0.05)},
    )
    law = model.linear.control["level"]
    draws = model.linear.draw_of
    for r in (0, 7, 23):
        tank = model.linear.params_of(r)["tank"]
        assert law.kl[r] == pytest.approx(tank["a_prime"] / tank["b"], rel=1e-12)  # eq. (11)
    assert len(set(np.asarray(law.kp)[draws].round(9))) > 10
    out = model.check({"level": 0.3}, {"level": 0.45})
    nonlinear = np.array(out["nonlinear_overshoot_pct"]["level"])
    paired = np.array(out["linear_overshoot_pct"]["level"])
    assert np.abs(nonlinear - paired).max() < LINEARISATION, (nonlinear, paired)


@pytest.mark.parametrize("delay", [0.0, 0.4])
def test_the_fast_prediction_is_the_nonlinear_tanks_overshoot(delay):
    model = _model(method="fast", phase="fixed")
    periods = np.array([0.05, 0.2, 0.5, 1.0, 2.0])
    predicted = LinearPredictor(model, {"level": delay}).overshoots("level", periods[:, None])
    checked = [
        model.evaluate({"level": h}, {"level": delay}).overshoot_pct["level"] for h in periods
    ]
    np.testing.assert_allclose(predicted, checked, atol=LINEARISATION)
    assert max(checked) - min(checked) > 2.0, checked  # the period matters: not a flat comparison


def test_the_fast_method_closes_a_trains_other_nonlinear_pi_loops_by_their_tangents():
    """Three tanks in series, each with its NL PI started bumpless (``u_start``): the fast
    method predicts a loop with the others closed by their laws' linear forms (Pade delays);
    the non-linear train's overshoots agree where the Pade closure holds (periods to 1 s)."""
    scenario = Scenario.model_validate(scale_scenario(3, plant="tank_train", per_gateway=3))
    model = loop_model(scenario, WncscaConfig(method="fast", phase="fixed"))
    loops = model.loops
    periods = np.array([0.05, 0.5, 1.0])
    rows = np.stack([periods] * len(loops), axis=1)
    for delay in (0.0, 0.3):
        delays = {n: delay for n in loops}
        runs = [model.evaluate(dict.fromkeys(loops, h), delays).overshoot_pct for h in periods]
        for n in loops:
            predicted = LinearPredictor(model, delays).overshoots(n, rows)
            checked = [run[n] for run in runs]
            np.testing.assert_allclose(predicted, checked, atol=0.15, err_msg=f"{n} {delay}")


def test_the_default_agent_judges_the_tanks_nonlinear_pi_and_the_steps_keep_the_limit():
    scenario = load_scenario(TANK)
    seen: set[tuple[str, str]] = set()
    rec = simulate(scenario, observe=lambda messages: seen.update((m.key, m.src) for m in messages))
    # every message from an owner of its key (the ownership test's check, on this run)
    table = publishers(scenario)
    assert seen and [(k, src) for k, src in seen if src not in owners_of(table, k)] == []
    decision = next(d for d in rec.wncsca["decisions"] if d["subject"] == "proposal")
    assert decision["verdict"] == "accept", decision["reasons"]
    assigned = next(r for r in rec.wncsca["rates"] if r.get("assignment"))
    guarantee = assigned["assignment"]["guarantee"]
    agent = scenario.nodes["wncsca"]
    assert guarantee["probability"]["level"]["p"] >= agent.confidence
    steps = loop_metrics(rec, "level")["steps"]
    assert [(s["from"], s["to"]) for s in steps] == [(50.0, 100.0), (100.0, 60.0)]
    assert all(s["overshoot_pct"] <= agent.overshoot_limit + 1.0 for s in steps), steps
    for d in rec.wncsca["decisions"]:
        if d["subject"] == "setpoint":
            assert d["verdict"] == "accept", d["reasons"]
