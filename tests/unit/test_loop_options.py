"""Two options the agent's replays need, open to every scenario (issue 35, item 4): a controller
designed on other parameters than its plant's (``feedforward_params``), and a sensor whose first
sample is not at 0 (``loops.<l>.sample_offset``)."""

from __future__ import annotations

import pytest

from core.errors import ConfigError
from core.time import to_ticks
from plants import registry
from runtime.direct import simulate
from scenario import Scenario, load_scenario
from tests.conftest import SCENARIOS, write_variant

BENCHMARK = SCENARIOS / "jcstr_benchmark.yaml"


def test_a_controller_computes_its_feedforward_on_its_own_parameters(tmp_path):
    def edit(data: dict) -> None:
        data["nodes"]["temperature_controller"]["feedforward_params"] = {"U": 0.15}

    s = load_scenario(write_variant(tmp_path, BENCHMARK, "design.yaml", edit))
    params = dict(s.plant("reactor").params)
    setpoints = {"level": 0.70, "temperature": 52.0}
    y_bar = {"H": 0.70, "T": 52.0}
    got = s.feedforward("temperature").u_bar(setpoints)
    _, u_design = registry.build("jcstr", {**params, "U": 0.15}).equilibrium(y_bar)
    _, u_plant = registry.build("jcstr", params).equilibrium(y_bar)
    assert got == pytest.approx(float(u_design[1])) and got != pytest.approx(float(u_plant[1]))
    assert s.feedforward("level").u_bar(setpoints) == pytest.approx(float(u_plant[0]))


def test_feedforward_parameters_the_plant_does_not_have_are_refused_naming_where(tmp_path):
    def edit(data: dict) -> None:
        data["nodes"]["temperature_controller"]["feedforward_params"] = {"Uu": 0.15}

    with pytest.raises(ConfigError) as err:
        load_scenario(write_variant(tmp_path, BENCHMARK, "bad.yaml", edit))
    assert "nodes.temperature_controller.feedforward_params" in str(err.value)
    assert "Uu" in str(err.value)


def test_a_sensor_samples_from_its_offset_on():
    data = load_scenario(BENCHMARK).model_dump()
    data["end_time"], data["setpoints"] = 1.0, []
    data["loops"]["level"]["sample_offset"] = 0.03
    rec = simulate(Scenario.model_validate(data))
    period = to_ticks(data["loops"]["level"]["tau_s"])
    level = rec.loops["level"].t_sampled
    assert level[:3] == [to_ticks(0.03) + k * period for k in range(3)]
    assert rec.loops["temperature"].t_sampled[0] == 0  # the others as before
