"""Scenario validation: bad files are refused with the file and the field named."""

from __future__ import annotations

import pytest

from core.errors import ConfigError
from scenario import load_scenario
from tests.conftest import BENCHMARK, write_variant


def _nodes(d):
    return d["nodes"]


CASES = [
    (
        "unknown_kind",
        lambda d: _nodes(d)["network"].update(kind="teleporter"),
        "nodes.network",
        "teleporter",
    ),
    (
        "missing_field",
        lambda d: _nodes(d)["reactor"]["params"].pop("V_j"),
        "params.V_j",
        "Field required",
    ),
    (
        "negative_tau_s",
        lambda d: d["loops"]["level"].update(tau_s=-0.1),
        "loops.level.tau_s",
        "greater than 0",
    ),
    (
        "unknown_setpoint_loop",
        lambda d: d["setpoints"].append({"t": 1.0, "loop": "flow", "value": 1.0}),
        "setpoints[2].loop",
        "unknown loop 'flow'",
    ),
    (
        "unknown_plant_model",
        lambda d: _nodes(d)["reactor"].update(model="boiler"),
        "nodes.reactor",
        "unknown plant model 'boiler'",
    ),
    (
        "bad_sensor",
        lambda d: d["loops"]["level"].update(sensor="pressure"),
        "loops.level.sensor",
        "no output 'pressure'",
    ),
    (
        "controller_is_plant",
        lambda d: d["loops"]["level"].update(controller="reactor"),
        "loops.level.controller",
        "is a plant",
    ),
    (
        "extra_field",
        lambda d: d["loops"]["level"].update(tau_x=1.0),
        "loops.level.tau_x",
        "Extra inputs",
    ),
    ("reserved_name", lambda d: _nodes(d).update(clock={"kind": "operator"}), "nodes", "reserved"),
    (  # a bus identity's name: the node would take over its credentials and grants
        "identity_name",
        lambda d: _nodes(d).update(threads={"kind": "operator"}),
        "nodes",
        "reserved",
    ),
    (
        "unreachable_setpoint",
        lambda d: d["setpoints"].append({"t": 3.0, "loop": "temperature", "value": 1000.0}),
        "setpoints[2]: feedforward",
        "T_jin",
    ),
    ("x0_incomplete", lambda d: _nodes(d)["reactor"]["x0"].pop("T_j"), "x0", "expected exactly"),
    (
        "input_range_unknown_input",
        lambda d: _nodes(d)["reactor"]["input_range"].update(F_in=[0, 1]),
        "input_range.F_in",
        "not an input",
    ),
    (
        "input_range_empty",
        lambda d: _nodes(d)["reactor"]["input_range"].update(F_out=[5, 5]),
        "input_range.F_out",
        "must be below",
    ),
    (
        "u0_outside_input_range",
        lambda d: _nodes(d)["reactor"]["input_range"].update(F_out=[0, 5]),
        "u0.F_out",
        "outside input_range.F_out",
    ),
    (
        "input_range_nan",
        lambda d: _nodes(d)["reactor"]["input_range"].update(F_out=[float("nan"), 20]),
        "input_range.F_out.0",
        "not a finite number",
    ),
    (
        "infinite_gain",  # infinity means "no limit" only in limits
        lambda d: _nodes(d)["reactor"]["x0"].update(T=float("inf")),
        "x0.T",
        "not a finite number",
    ),
]


@pytest.mark.parametrize("name, edit, field, fragment", CASES, ids=[c[0] for c in CASES])
def test_bad_scenario_names_file_and_field(tmp_path, name, edit, field, fragment):
    path = write_variant(tmp_path, BENCHMARK, f"{name}.yaml", edit)
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    msg = str(info.value)
    assert str(path) in msg and field in msg and fragment in msg, msg


def test_not_yaml_and_missing_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("nodes: [unclosed")
    with pytest.raises(ConfigError, match=r"bad\.yaml: line 1, column 17: not valid YAML"):
        load_scenario(bad)
    with pytest.raises(ConfigError, match="nope.yaml: cannot read"):
        load_scenario(tmp_path / "nope.yaml")


def test_with_loops_revalidates():
    s = load_scenario(BENCHMARK)
    s2 = s.with_loops(tau_s={"level": 0.25}, tau_d={"level": 0.17})
    assert (s2.loops["level"].tau_s, s2.loops["level"].tau_d) == (0.25, 0.17)
    assert s.loops["level"].tau_s == 0.1
    with pytest.raises(ValueError):
        s.with_loops(tau_s={"level": -1.0})


def test_an_actuator_range_may_be_open_ended():
    reactor = load_scenario(BENCHMARK).nodes["reactor"]
    assert reactor.input_range == {"F_out": (0.0, float("inf")), "F_jin": (0.0, float("inf"))}
