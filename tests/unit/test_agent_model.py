"""The agent's model is its own (issue 35, item 1): the agent node's ``model:`` states the
parameters it believes and their uncertainty; the true plant node keeps its own.

Everything the agent is handed (its spec, its closed-loop model, the scenario its trials run on)
is walked for the true plant's parameter: it is never there once the agent believes another
value, and the agent's trials use the believed value (its overshoots differ from the true
plant's, which they could not if the true parameter leaked through).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel

from core.errors import ConfigError
from runtime.direct import simulate
from scenario import load_scenario, views
from tests.conftest import SCENARIOS, write_variant

JITTER = SCENARIOS / "jcstr_wncs_jitter.yaml"
TRUE_U = 0.1713  # the reactor's heat-transfer coefficient in the scenario file
BELIEVED_U = 0.19  # the agent's belief, 11 % off


def _believing(tmp_path, model: dict, name: str = "belief.yaml"):
    def edit(data: dict) -> None:
        assert data["nodes"]["reactor"]["params"]["U"] == TRUE_U
        data["nodes"]["wncsca"]["model"] = model

    return write_variant(tmp_path, JITTER, name, edit)


def _values(obj: Any, seen: set[int] | None = None) -> Iterator[Any]:
    """Every value reachable from ``obj`` through our objects' fields and containers."""
    seen = set() if seen is None else seen
    if id(obj) in seen or callable(obj) and not hasattr(obj, "__dict__"):
        return
    seen.add(id(obj))
    yield obj
    if isinstance(obj, BaseModel):
        children: Any = [getattr(obj, f) for f in type(obj).model_fields]
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        children = [getattr(obj, f.name) for f in dataclasses.fields(obj)]
    elif isinstance(obj, Mapping):
        children = [*obj.keys(), *obj.values()]
    elif isinstance(obj, list | tuple | set | frozenset):
        children = list(obj)
    elif type(obj).__module__.split(".")[0] in {
        "agents",
        "scenario",
        "plants",
        "controllers",
        "gateway",
        "core",
        "runtime",
    }:
        children = list(vars(obj).values()) if hasattr(obj, "__dict__") else []
    else:
        children = []
    for child in children:
        yield from _values(child, seen)


def _holds(obj: Any, value: float) -> bool:
    for v in _values(obj):
        if isinstance(v, float) and v == value:
            return True
        if isinstance(v, np.ndarray) and v.dtype.kind == "f" and np.any(v == value):
            return True
    return False


def test_the_agent_never_holds_the_true_parameter(tmp_path):
    scenario = load_scenario(_believing(tmp_path, {"reactor": {"params": {"U": BELIEVED_U}}}))
    assert scenario.plant("reactor").params["U"] == TRUE_U  # the true plant keeps its own
    agent = views.coordinator(scenario, simulate=simulate)
    assert _holds(agent, BELIEVED_U)
    assert not _holds(agent, TRUE_U)
    trials = views.ScenarioSimulator(scenario, agent.model.trials.spec, simulate).model
    assert trials.plant("reactor").params["U"] == BELIEVED_U
    # the walk finds the true value where it is: the scenario, and an agent that knows the plant
    assert _holds(scenario, TRUE_U)
    assert _holds(views.coordinator(load_scenario(JITTER), simulate=simulate), TRUE_U)


def test_the_agent_judges_on_its_own_model(tmp_path):
    exact = views.loop_model(load_scenario(JITTER), simulate=simulate)
    off = views.loop_model(
        load_scenario(_believing(tmp_path, {"reactor": {"params": {"U": BELIEVED_U}}})),
        simulate=simulate,
    )
    periods = {"level": 0.175, "temperature": 0.075}
    a = exact.evaluate(periods, {}).overshoot_pct
    b = off.evaluate(periods, {}).overshoot_pct
    assert a["level"] == pytest.approx(b["level"], abs=0.5)  # the level barely feels U
    assert abs(a["temperature"] - b["temperature"]) > 0.1, (a, b)


def test_the_uncertainty_reaches_the_spec(tmp_path):
    model = {"reactor": {"uncertainty": {"U": {"rel_sd": 0.1}, "C_p": {"interval": [0.9, 1.1]}}}}
    scenario = load_scenario(_believing(tmp_path, model))
    plant = views.agent_spec(scenario).closed_loop.plants["reactor"]
    assert plant.params["U"] == TRUE_U  # no params: the plant's own, known up to the spread
    assert plant.uncertainty["U"].rel_sd == 0.1
    assert plant.uncertainty["C_p"].interval == (0.9, 1.1)


@pytest.mark.parametrize(
    "model, where",
    [
        ({"tank": {}}, "nodes.wncsca.model.tank: not a plant of a loop the agent judges"),
        ({"reactor": {"params": {"Q": 1.0}}}, "nodes.wncsca.model.reactor.params.Q: not a param"),
        ({"reactor": {"params": {"U": -1.0}}}, "nodes.wncsca.model.reactor: "),
        ({"reactor": {"uncertainty": {"Q": {"rel_sd": 0.1}}}}, "uncertainty.Q: not a numeric"),
        (
            {"reactor": {"uncertainty": {"U": {"interval": [0.2, 0.3]}}}},
            "uncertainty.U.interval: the believed value 0.1713 is outside",
        ),
        ({"reactor": {"uncertainty": {"U": {}}}}, "give exactly one of rel_sd or interval"),
    ],
)
def test_a_bad_model_is_refused_with_its_path(tmp_path, model, where):
    with pytest.raises(ConfigError) as info:
        load_scenario(_believing(tmp_path, model))
    assert where in str(info.value), str(info.value)
