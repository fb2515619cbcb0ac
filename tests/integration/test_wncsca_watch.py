"""The model watch tells a model that fits from one that does not (issue 35, item 4).

The jitter scenario's reactor runs the paper's two steps at fixed periods on the direct engine,
without an agent, with noisy sensors; the agent's model watch then scores the window after the
steps from what the network delivered (:func:`agents.wncsca.watch.score`, the window built as
the agent keeps it). On the exact plant the score is what the model's own replays make of it
(each well below the CUSUM's threshold, over network seeds); with the reactor's U 15 % below the
model's (fouling) one window is far past it.
"""

from __future__ import annotations

import numpy as np
import pytest

from agents.wncsca.watch import score
from agents.wncsca.window import Window
from runtime.direct import loop_model, simulate
from scenario import Scenario, load_scenario
from tests.conftest import SCENARIOS

pytestmark = pytest.mark.slow

JITTER = SCENARIOS / "jcstr_wncs_jitter.yaml"
U = 0.1713
NOISE = {"H": 0.002, "T": 0.05}
SIGMA = {"level": 0.002, "temperature": 0.05}
PERIODS = {"level": 0.175, "temperature": 0.075}
STEPS = ((1.8, "level", 0.75), (2.4, "temperature", 56.0))
END = 1.8 + 8.0  # the steps and the test's length after them


def _window(seed: int, u: float) -> Window:
    """The run's window after the steps as the agent keeps it (every delivered sample)."""
    data = load_scenario(JITTER).model_dump()
    del data["nodes"]["wncsca"]
    data["modes"], data["end_time"], data["seed"] = [], END, seed
    data["nodes"]["reactor"]["params"]["U"] = u
    data["nodes"]["reactor"]["noise"] = NOISE
    for loop, period in PERIODS.items():
        data["loops"][loop]["tau_s"] = period
    data["setpoints"] = [{"t": t, "loop": lp, "value": v} for t, lp, v in STEPS]
    rec = simulate(Scenario.model_validate(data))
    w = Window(
        t0=0.0,
        since=STEPS[0][0],
        end=END,
        base={"level": 0.70, "temperature": 52.0},
        changes=STEPS,
        periods=PERIODS,
    )
    for loop, lp in rec.loops.items():
        for t, ts, y in zip(lp.t, lp.t_sampled, lp.y, strict=True):
            w.record(loop, y, ts, t)
    return w


@pytest.fixture(scope="module")
def model():
    return loop_model(load_scenario(JITTER))


def _z(model, seed: int, u: float) -> float:
    s = score(model, _window(seed, u), {}, SIGMA, 0.0, 20, seed, 0)
    assert s is not None
    assert [f.loop for f in s.steps] == ["level", "temperature"]
    assert [f.t for f in s.steps] == [1.8, 2.4]
    return s.z


def test_on_the_exact_plant_the_score_is_what_the_models_replays_make_of_it(model):
    z = np.array([_z(model, seed, U) for seed in range(6)])
    assert (z < 3.0).all(), z  # one-sided: far below the CUSUM's threshold of 5
    assert abs(float(z.mean())) < 1.5, z  # centred: 3.7 standard errors of six N(0, 1)


def test_a_fouled_plant_is_far_past_the_threshold_in_one_window(model):
    z = _z(model, 0, 0.85 * U)
    assert z > 5.0 + 0.5, z  # the CUSUM flags it at once (h = 5, k = 0.5)
