"""The true plant drifts (issue 35, item 1): a scheduled or injected change of one of its
physical parameters, at once or as a ramp, on the plant node alone.

Checked on the tank of seed 002 under its non-linear PI (``dh/dt = b u - a' sqrt(h)``): at rest
on a set point ``r`` the loop holds ``u = a' sqrt(r) / b`` with the *true* ``a'``, so the move
after a drift of ``a'`` is the closed form at the new value, and during a ramp the plant's
parameter takes the stated steps. A drift at ``t = 0`` is the plant built with the new value
(the law designed on the nominal tank in both).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bus_schemas import Drift, InjectRequest, keys
from core.errors import ConfigError
from core.time import to_ticks
from plants.behaviour import PlantBehaviour
from runtime.direct import simulate
from runtime.inject import build_request, interpreter
from scenario import load_scenario, views
from tests.conftest import SCENARIOS, write_variant

TANK = SCENARIOS / "tank_sim.yaml"
B = 2.0  # the tank's b in the scenario file


def _tank(tmp_path, drifts: list, name: str = "drift.yaml", **params):
    def edit(data: dict) -> None:
        data["drifts"] = drifts
        data["nodes"]["tank"]["params"].update(params)
        data["disturbances"] = []
        data["setpoints"] = data["setpoints"][:1]  # 50 mm from 0 s, held
        law = data["nodes"]["level_controller"]["law"]
        law.update(b=B, a_prime=0.5)  # designed on the nominal tank, whatever the plant is

    return load_scenario(write_variant(tmp_path, TANK, name, edit))


def _u_at(rec, t: float) -> float:
    lp = rec.loops["level"]
    k = int(np.searchsorted(np.asarray(lp.t), to_ticks(t), side="right")) - 1
    return float(lp.u[k])


def test_a_drift_at_the_start_is_the_plant_built_with_the_new_value(tmp_path):
    drifted = simulate(
        _tank(tmp_path, [{"t": 0.0, "plant": "tank", "param": "a_prime", "value": 0.6}])
    )
    built = simulate(_tank(tmp_path, [], "built.yaml", a_prime=0.6))
    assert np.array_equal(drifted.plants["tank"].x, built.plants["tank"].x)


def test_after_a_drift_the_loop_holds_the_closed_form_of_the_new_parameter(tmp_path):
    """Set point 50 mm from 0 s; a' ramps 0.5 -> 0.7 over 10 s from 60 s (20 steps)."""
    drift = {"t": 60.0, "plant": "tank", "param": "a_prime", "value": 0.7, "over": 10.0}
    rec = simulate(_tank(tmp_path, [drift]))
    before, after = _u_at(rec, 59.9), _u_at(rec, 149.9)
    assert before == pytest.approx(0.5 * math.sqrt(50.0) / B, rel=1e-3)
    assert after == pytest.approx(0.7 * math.sqrt(50.0) / B, rel=1e-3)
    plain = simulate(_tank(tmp_path, [], "plain.yaml"))
    assert _u_at(plain, 149.9) == pytest.approx(before, rel=1e-3)  # without it: unchanged


def test_a_ramp_takes_its_steps_and_a_later_drift_replaces_it():
    """a' 0.5 -> 0.9 over 4 s in 4 steps: 0.6, 0.7, 0.8, 0.9 at 1, 2, 3, 4 s; a drift to 0.55 at
    2.5 s replaces the rest of the ramp."""
    plant = PlantBehaviour("tank", views.plant_spec(load_scenario(TANK), "tank"))
    plant.current_key = keys.drift("tank")
    plant._on_drift(None, Drift(param="a_prime", value=0.9, over=to_ticks(4.0), steps=4))
    seen, rounds = [], iter(range(1, 10**6))
    for t in (1.0, 2.0, 2.5, 3.0, 4.0):
        while plant.next_time is not None and plant.next_time <= to_ticks(t):
            plant.begin_round(next(rounds), plant.next_time)  # the samplers' rounds too
            plant.end_round()
        if t == 2.5:
            plant.begin_round(next(rounds), to_ticks(t))
            plant._on_drift(None, Drift(param="a_prime", value=0.55))
            plant.end_round()
        seen.append(plant.params["a_prime"])
        assert plant.model.params.a_prime == plant.params["a_prime"]  # the model rebuilt
    assert seen == pytest.approx([0.6, 0.7, 0.55, 0.55, 0.55])


def test_a_drift_the_plant_refuses_is_dropped_with_its_reason(caplog):
    behaviour = PlantBehaviour("tank", views.plant_spec(load_scenario(TANK), "tank"))
    behaviour.current_key = keys.drift("tank")
    behaviour._on_drift(None, Drift(param="nope", value=1.0))
    behaviour._on_drift(None, Drift(param="a_prime", value=-1.0))
    assert behaviour.dropped_invalid[keys.drift("tank")] == 2
    assert behaviour.params["a_prime"] == 0.5 and "_ramps" in vars(behaviour)


@pytest.mark.parametrize(
    "drift, where",
    [
        ({"t": 1.0, "plant": "nope", "param": "b", "value": 1.0}, "drifts[0].plant"),
        ({"t": 1.0, "plant": "tank", "param": "c", "value": 1.0}, "drifts[0].param: 'c' is not"),
        ({"t": 1.0, "plant": "tank", "param": "b", "value": -1.0}, "drifts[0].value: the plant"),
        ({"t": 999.0, "plant": "tank", "param": "b", "value": 1.0}, "drifts[0].t: 999.0 is after"),
    ],
)
def test_a_bad_drift_is_refused_on_load(tmp_path, drift, where):
    with pytest.raises(ConfigError) as info:
        _tank(tmp_path, [drift])
    assert where in str(info.value), str(info.value)


def test_overlapping_drifts_of_one_parameter_are_refused(tmp_path):
    ramp = {"t": 10.0, "plant": "tank", "param": "b", "value": 1.5, "over": 10.0}
    with pytest.raises(ConfigError, match=r"drifts\[1\].t: a drift of tank.b is still under way"):
        _tank(tmp_path, [ramp, {**ramp, "t": 15.0}])


def test_an_injected_drift_is_checked_then_stamped_for_the_plant(tmp_path):
    request = build_request("drift", ["tank", "a_prime=0.6", "over=5"], run_dir=None, network=None)
    assert request.drift == {
        "plant": "tank",
        "param": "a_prime",
        "value": 0.6,
        "over": to_ticks(5.0),
        "steps": 20,
    }
    key, body = interpreter(load_scenario(TANK))(request)
    assert key == keys.drift("tank") and body == Drift(
        param="a_prime", value=0.6, over=to_ticks(5.0), steps=20
    )
    for words, fragment in [
        (["a_prime=0.6"], "usage"),
        (["tank", "a_prime=x"], "not a finite number"),
        (["tank", "a_prime=0.6", "over=-1"], "over must be >= 0"),
    ]:
        with pytest.raises(ConfigError, match=fragment):
            build_request("drift", words, run_dir=None, network=None)
    with pytest.raises(ValueError, match="exactly one of event, mode, setpoint, drift"):
        InjectRequest(mode="x", drift={"plant": "tank"})
