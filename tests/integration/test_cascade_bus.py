"""Seed 004's PI-P cascade over the bus (threads engine, a real zenoh router): one controller node
measuring the reactor temperature (loop ``temperature``) and the jacket temperature (a
measurement-only loop, ``actuator: null``) and moving the coolant, equals the direct engine."""

from __future__ import annotations

import yaml

from controllers.cascade.law import ROUTINE_CASCADE, cascade_variant
from core.record import summarize
from runtime.direct import simulate
from runtime.launcher import launch
from scenario import load_scenario
from tests.conftest import SCENARIOS, load_yaml
from tests.integration.test_column_mrac_bus import assert_traces_equal


def test_pip_cascade_over_the_bus_equals_direct(tmp_path):
    data = cascade_variant(
        load_yaml(SCENARIOS / "cascade_routine.yaml"),
        loop="temperature",
        secondary="y2",
        gains=ROUTINE_CASCADE["cascade_routine"]["y2"],
        secondary_loop="jacket",
    )
    data["end_time"] = 40.0
    path = tmp_path / "cascade_pip.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    res = launch(path, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    direct = summarize(simulate(load_scenario(path)))
    assert_traces_equal(res.summary, direct)
    jacket = res.summary["loops"]["jacket"]["trace"]
    assert len(jacket["t"]) == 41 and all(u is None for u in jacket["u"])  # measured, never moved
    assert all(u is not None for u in res.summary["loops"]["temperature"]["trace"]["u"])
