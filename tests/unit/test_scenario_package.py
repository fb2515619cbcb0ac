"""The scenario package's seams (issue 34, item 3): the schema's static node-config union is the
node-kind registry's, and every graph check names the dotted path of what it refuses."""

from __future__ import annotations

import inspect
import typing

import pytest

from core.errors import ConfigError
from scenario import NODE_KINDS, NodeConfig, load_scenario
from scenario.checks import GRAPH_CHECKS
from tests.conftest import BENCHMARK, SCENARIOS, write_variant


def _members(union: object) -> tuple[type, ...]:
    annotated, *meta = typing.get_args(union)
    return typing.get_args(annotated)


def test_the_static_node_config_union_is_the_registrys():
    registry = NODE_KINDS.union()
    assert _members(NodeConfig) == _members(registry)
    static_tag = typing.get_args(NodeConfig)[1].discriminator
    assert static_tag == typing.get_args(registry)[1].discriminator == "kind"


def test_every_kind_of_the_registry_has_its_kind_literal():
    for name, kind in NODE_KINDS.kinds.items():
        assert typing.get_args(kind.config.model_fields["kind"].annotation) == (name,)


@pytest.mark.parametrize(
    ("base", "edit", "message"),
    [
        (
            BENCHMARK,
            lambda d: d["loops"]["level"].update(controller="ghost"),
            "loops.level.controller: unknown node 'ghost'",
        ),
        (
            BENCHMARK,
            lambda d: d["loops"]["level"].update(sensor="Q"),
            "loops.level.sensor: plant 'reactor' has no output 'Q'",
        ),
        (
            BENCHMARK,
            lambda d: (
                d["clock"].update(may_drop=["ghost"])
                if "clock" in d
                else d.update(clock={"may_drop": ["ghost"]})
            ),
            "clock.may_drop[0]: unknown node 'ghost'",
        ),
        (
            BENCHMARK,
            lambda d: d["setpoints"].append({"t": 99.0, "loop": "level", "value": 0.7}),
            "setpoints[2].t: 99.0 is after end_time",
        ),
        (
            SCENARIOS / "jcstr_wncs.yaml",
            lambda d: d["modes"].append({"t": 1.0, "mode": "party"}),
            "mode: unknown mode 'party'",
        ),
    ],
)
def test_a_graph_check_names_the_dotted_path(tmp_path, base, edit, message):
    path = write_variant(tmp_path, base, "bad.yaml", edit)
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("(", r"\(")):
        load_scenario(path)


def test_the_checks_are_one_function_per_concern_each_short():
    for check in GRAPH_CHECKS:
        lines = len(inspect.getsource(check).splitlines())
        assert lines <= 80, (check.__name__, lines)
