"""``bus_schemas.keys.intersects`` (how the direct engine routes) against zenoh's own matching."""

from __future__ import annotations

import inspect
import itertools

import zenoh

from bus_schemas import keys
from runtime.direct import behaviour_of
from scenario import load_scenario
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


def test_every_key_is_data_under_one_root_or_the_clocks_or_liveliness():
    """The historian records ``keys.data_all()`` instead of ``**``: a key builder whose keys fell
    outside every data root would silently go unrecorded. Each builder's key, with names filled
    in, is under exactly one data root, or is the clock's or a liveliness token."""
    builders = [
        getattr(keys, name)
        for name in keys.__all__
        if callable(getattr(keys, name))
        and name not in {"check_name", "intersects", "full", "relative", "run_prefix", "data_all"}
    ]
    assert len(builders) >= 25
    for build in builders:
        n = len(inspect.signature(build).parameters)
        key = build(*[f"x{i}" for i in range(n)])
        roots = [p for p in keys.data_all() if keys.intersects(p, key)]
        control = key.split("/")[0] in {"clock", "alive"}
        assert len(roots) + control == 1, (build.__name__, key, roots)
