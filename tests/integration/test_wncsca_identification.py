"""The agent identifies its own model from the loops' delivered samples (issue 35, item 3).

The true reactor's heat-transfer coefficient is 10 % above the agent's belief. An experiment
perturbs both set points with generalized binary noise over the jitter network (delays, losses,
measurement noise), on the direct engine, without an agent; the agent's closed-loop fit
(:func:`agents.wncsca.identification.identify`) from its own model, seeing only the delivered
samples and their delays, recovers U within its stated 95 % interval, states a far smaller
uncertainty than the 10 % it was off, and the fit explains the data.

The agent running the experiment itself on the bus's rules, taking the estimate and judging
again, is ``tests/integration/test_wncsca_fouling.py`` (``scenarios/jcstr_fouling.yaml``).
"""

from __future__ import annotations

import numpy as np
import pytest

from agents.identify.excitation import gbn
from agents.wncsca.identification import ClosedLoopExperiment, identify
from core.time import to_ticks, to_units
from runtime.direct import loop_model, simulate
from scenario import Scenario, load_scenario
from tests.conftest import SCENARIOS

JITTER = SCENARIOS / "jcstr_wncs_jitter.yaml"
TRUE_U, BELIEVED_U = 0.1713 * 1.1, 0.1713
END, CLOCK, PERIOD = 8.0, 0.4, 0.1


def _experiment_run(seed: int):
    data = load_scenario(JITTER).model_dump()
    del data["nodes"]["wncsca"]
    data["modes"], data["end_time"], data["seed"] = [], END, seed
    reactor = data["nodes"]["reactor"]
    reactor["params"]["U"] = TRUE_U
    reactor["noise"] = {"H": 0.002, "T": 0.05}
    rng = np.random.default_rng([seed, 35])
    n = int(END / CLOCK)
    base = {"level": 0.70, "temperature": 52.0}
    swing = {"level": gbn(n, 0.5, 0.02, rng), "temperature": gbn(n, 0.5, 1.0, rng)}
    data["setpoints"] = [
        {"t": k * CLOCK, "loop": loop, "value": base[loop] + float(swing[loop][k])}
        for k in range(1, n)
        for loop in sorted(base)
    ]
    steps = tuple((0.0, loop, v) for loop, v in sorted(base.items())) + tuple(
        (s["t"], s["loop"], s["value"]) for s in data["setpoints"]
    )
    return simulate(Scenario.model_validate(data)), steps


def _seen(rec, steps) -> ClosedLoopExperiment:
    """What the agent sees of the run: each loop's delivered samples and their delays."""
    traces, samples = {}, {}
    for loop, lp in sorted(rec.loops.items()):
        delivered = {ts: t - ts for t, ts in zip(lp.t, lp.t_sampled, strict=True)}
        count = int(END / PERIOD) + 1
        instants = [to_ticks(k * PERIOD) for k in range(count)]
        traces[loop] = [to_units(delivered[t]) if t in delivered else None for t in instants]
        samples[loop] = ([to_units(t) for t in lp.t_sampled], list(lp.y))
    return ClosedLoopExperiment(
        steps=steps,
        end_time=END,
        periods={"level": PERIOD, "temperature": PERIOD},
        delays={"level": 0.0, "temperature": 0.0},
        traces=traces,
        samples=samples,
    )


@pytest.fixture(scope="module")
def fitted():
    rec, steps = _experiment_run(seed=3)
    model = loop_model(load_scenario(JITTER))
    assert model.trials.spec.plants["reactor"].params["U"] == BELIEVED_U
    return identify(model, {"reactor": ["U"]}, _seen(rec, steps)), rec


def test_the_agent_recovers_the_true_u_within_its_stated_interval(fitted):
    fit, rec = fitted
    u, sd = fit.params["reactor"]["U"], fit.std("reactor", "U")
    assert abs(u - TRUE_U) <= 1.96 * sd, (u, sd)
    assert fit.rel_sd("reactor", "U") < 0.02  # far narrower than the 10 % it was off


def test_the_fit_explains_the_data_down_to_the_measurement_noise(fitted):
    fit, _ = fitted
    assert fit.fit_pct["temperature"] > 80 and fit.fit_pct["level"] > 50, fit.fit_pct
    assert fit.sigma["temperature"] == pytest.approx(0.05, rel=0.3), fit.sigma
