"""Seed 004's PI-P cascade on the platform: measurement-only loops (``actuator: null``), the
``pip_cascade`` law, the exact sampled model its settings are tuned on, and refusals naming file
and field."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from controllers.cascade.law import ROUTINE_CASCADE, cascade_variant
from controllers.cascade.model import PIPCascade, PIPCascadeConfig
from controllers.pi import PI, PIConfig
from core.errors import ConfigError
from core.record import summarize
from core.time import to_units
from plants.cascade.plant import CascadeCTParams, sampled
from runtime.direct import simulate
from scenario import load_scenario, parse_scenario
from tests.conftest import SCENARIOS, load_yaml, write_variant

ROUTINE = SCENARIOS / "cascade_routine.yaml"
GAINS = {"Kc1": 1.5, "Ti1": 20.0, "Kc2": 3.0}


def _variant(end_time: float = 200.0, secondary: str = "y2", gains=None) -> dict:
    data = cascade_variant(
        load_yaml(ROUTINE),
        loop="temperature",
        secondary=secondary,
        gains=gains or GAINS,
        secondary_loop="jacket",
    )
    data["end_time"] = end_time
    return data


def test_pip_cascade_moves_only_the_primary_input_as_the_sampled_law_does():
    """The moves of the run are PIPCascade's on the recorded samples (r1 = 0); the jacket loop is
    sampled and delivered but never moved; nothing else of the scenario changed."""
    scenario = parse_scenario(_variant())
    assert scenario.loops["jacket"].has_sensor and not scenario.loops["jacket"].has_actuator
    rec = simulate(scenario)
    t1, j = rec.loops["temperature"], rec.loops["jacket"]
    assert t1.t == j.t == j.t_sampled and len(t1.t) == 201
    assert all(u is None for u in j.u) and j.lost_moves == 0
    law = PIPCascade(PIPCascadeConfig(primary="y1", secondary="y2", **GAINS))
    expected = [
        law.step(to_units(t), {"y1": y1, "y2": y2})
        for t, y1, y2 in zip(t1.t, t1.y, j.y, strict=True)
    ]
    np.testing.assert_allclose(t1.u, expected, rtol=0, atol=1e-15)
    _, y2_true = rec.plants["reactor"].signal("y2")
    np.testing.assert_array_equal(j.y, y2_true[: len(j.y)])  # noise-free secondary, 1-min grid
    base = simulate(load_scenario(ROUTINE).model_copy(update={"end_time": 200.0}))
    assert base.loops["temperature"].t == t1.t
    assert summarize(rec)["loops"]["jacket"]["overshoot_pct"] is None


@pytest.mark.parametrize("law", ["pi", "pip_y2", "pip_y3"])
def test_sampled_model_equals_the_direct_engine(law):
    """plants.cascade.plant.sampled (exact, what the settings are tuned on) against the plant node's
    RK4 (max_step 0.125): the same measured y1 to 1e-6 over 300 min, under either controller."""
    if law == "pi":
        data = load_yaml(ROUTINE)
        data["end_time"] = 300.0
        pi = PI(PIConfig(Kp=2.06, Ki=0.05722, integration="backward", feedforward="none"))

        def step(t, y):
            return pi.step(t, y[0], 0.0)
    else:
        index = 1 if law == "pip_y2" else 2
        gains = GAINS if index == 1 else {**GAINS, "Kc2": 0.8}  # 3 is unstable on the fast flow
        data = _variant(300.0, secondary=f"y{index + 1}", gains=gains)
        pip = PIPCascade(PIPCascadeConfig(primary="y1", secondary="s", **gains))

        def step(t, y):
            return pip.step(t, {"y1": y[0], "s": y[index]})

    data["nodes"].pop("monitor", None)
    scenario = parse_scenario(data)
    direct = np.array(simulate(scenario).loops["temperature"].y)
    params = CascadeCTParams(**data["nodes"]["reactor"]["params"])
    model = sampled(params, 1.0, 301)
    rng = scenario.sensor_rng("reactor", "y1")  # the plant node's noise, draw for draw
    x = np.zeros(model.phi.shape[0])
    ys = []
    for k in range(301):
        y = model.c @ x
        y[0] += 0.0067 * rng.standard_normal()
        ys.append(y[0])
        x = model.phi @ x + model.gam * step(float(k), y) + model.dist[k]
    assert np.std(direct) > 0.05
    np.testing.assert_allclose(ys, direct, rtol=0, atol=1e-6)


def test_sampled_model_refuses_a_period_between_knots():
    with pytest.raises(ValueError, match="not a whole number of noise_period"):
        sampled(CascadeCTParams(), 0.3, 10)


def test_shipped_settings_cover_both_scenarios_and_secondaries():
    assert set(ROUTINE_CASCADE) == {"cascade_routine", "cascade_routine_primary"}
    for by_secondary in ROUTINE_CASCADE.values():
        assert set(by_secondary) == {"y2", "y3"}
        for gains in by_secondary.values():
            parse_scenario(_variant(10.0, gains=gains))


def _jacket(d, **fields):
    d["loops"]["jacket"] = {
        "plant": "reactor",
        "sensor": "y2",
        "actuator": None,
        "controller": "temperature_controller",
        "network": "network",
        "tau_s": 1.0,
        "setpoint": 0.0,
        **fields,
    }


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        # a measurement-only loop of a single-loop controller
        (lambda d: d["loops"]["temperature"].update(actuator=None),
         "loops.temperature.actuator: null (a measurement-only loop) is allowed only for a loop "
         "of a multi-loop controller"),
        (lambda d: d["loops"]["temperature"].update(sensor=None, actuator=None, tau_s=None),
         "loops.temperature: Value error, actuator: a loop without a sensor must move an input"),
    ],
)  # fmt: skip
def test_measurement_only_loops_are_refused_where_no_law_takes_them(tmp_path, edit, expected):
    path = write_variant(tmp_path, ROUTINE, "bad.yaml", edit)
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    assert f"{path}: " in str(err.value), str(err.value)
    assert expected.replace("Value error, ", "") in str(err.value), str(err.value)


def test_measurement_only_loop_of_a_law_that_does_not_take_one_is_refused(tmp_path):
    """The MRAC moves an input for every loop: actuator: null names the loop's field."""

    def edit(d):
        d["loops"]["x2"]["actuator"] = None

    path = write_variant(tmp_path, SCENARIOS / "column_mrac.yaml", "bad.yaml", edit)
    with pytest.raises(ConfigError, match=r"bad\.yaml: line \d+: loops\.x2\.actuator: null \("):
        load_scenario(path)


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda d: d["loops"]["jacket"].update(tau_a=0.5),
         "loops.jacket: tau_a: a measurement-only loop (actuator: null) moves nothing"),
        (lambda d: d["loops"]["jacket"].update(actuator="u"),
         "nodes.temperature_controller.law.pip_cascade: loops[1]: the secondary loop 'jacket' "
         "must measure and move nothing"),
        (lambda d: d["loops"]["temperature"].update(actuator=None),
         "nodes.temperature_controller.loops: every loop is measurement-only"),
        (lambda d: d["nodes"]["temperature_controller"].update(loops=["temperature"]),
         "nodes.temperature_controller.controller: loops: a PI-P cascade takes two loops"),
        (lambda d: d["nodes"]["temperature_controller"]["law"].update(Ti1=0.0),
         "nodes.temperature_controller.controller.law.pip_cascade.Ti1: Input should be greater"),
    ],
)  # fmt: skip
def test_bad_cascade_input_is_refused_naming_file_and_field(tmp_path, edit, expected):
    path = tmp_path / "bad.yaml"
    data = _variant(10.0)
    edit(data)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    assert f"{path}: " in str(err.value) and expected in str(err.value), str(err.value)
