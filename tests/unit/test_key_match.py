"""``bus_schemas.keys.intersects`` (how the direct engine routes) against zenoh's own matching."""

from __future__ import annotations

import itertools

import zenoh

from bus_schemas import keys
from runtime.direct import behaviour_of
from runtime.scenario import load_scenario
from tests.conftest import SCENARIOS

EXTRA_PATTERNS = ["**", "*", "plant/**", "**/meas", "loop/*/u", "a/**/b", "ops/setpoint/*"]
EXTRA_KEYS = ["a/b", "a/x/b", "a/x/y/b", "a", "plant", "loop/level/meas/x", "ops/setpoint/level"]


def _zenoh(pattern: str, key: str) -> bool:
    return bool(zenoh.KeyExpr(pattern).intersects(zenoh.KeyExpr(key)))


def test_intersects_agrees_with_zenoh_on_every_subscription_of_the_scenarios():
    patterns, concrete = set(EXTRA_PATTERNS), set(EXTRA_KEYS)
    for path in ("jcstr_wncs.yaml", "cstr_recycle_qdc_wsn.yaml", "cascade_routine.yaml"):
        scenario = load_scenario(SCENARIOS / path)
        for name in scenario.nodes:
            for pattern in behaviour_of(scenario, name).patterns:
                patterns.add(pattern)
                if "*" not in pattern:
                    concrete.add(pattern)
    assert len(concrete) > 20
    checked = 0
    for pattern, key in itertools.product(sorted(patterns), sorted(concrete)):
        assert keys.intersects(pattern, key) == _zenoh(pattern, key), (pattern, key)
        checked += 1
    assert checked > 500
