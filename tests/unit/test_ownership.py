"""Key ownership (issue 19): every message every scenario publishes comes from an owner of its
key, as :func:`runtime.ownership.publishers` derives them from the scenario."""

from __future__ import annotations

from pathlib import Path

import pytest
import zenoh

from core.time import to_ticks
from runtime.direct import behaviour_of
from runtime.engine import DirectEngine, Message
from runtime.ownership import CLOCK, owners_of, publishers, readers
from scenario import load_scenario

SCENARIOS = sorted((Path(__file__).resolve().parents[2] / "scenarios").glob("*.yaml"))
OWN_RUN = {"jcstr_fouling", "tank_wsn_chance"}
"""Scenarios whose publishers are checked on the run their own test makes (a long agent run:
``tests/integration/test_wncsca_fouling.py``, ``tests/integration/test_wncsca_laws.py``), not run
again here."""


def _published(path: Path, end_time: float) -> set[tuple[str, str]]:
    scenario = load_scenario(path)
    scenario = scenario.model_copy(update={"end_time": min(scenario.end_time, end_time)})
    seen: set[tuple[str, str]] = set()

    def record(messages: list[Message]) -> None:
        seen.update((m.key, m.src) for m in messages)

    engine = DirectEngine(
        {n: behaviour_of(scenario, n) for n in sorted(scenario.nodes)},
        end=to_ticks(scenario.end_time),
        max_microsteps=scenario.clock.max_microsteps,
        on_round=record,
    )
    engine.run()
    return seen


@pytest.mark.slow
@pytest.mark.parametrize(
    "path", [p for p in SCENARIOS if p.stem not in OWN_RUN], ids=lambda p: p.stem
)
def test_every_published_message_comes_from_an_owner_of_its_key(path):
    table = publishers(load_scenario(path))
    seen = _published(path, end_time=float("inf"))
    assert seen, "the scenario published nothing"
    strays = sorted((key, src) for key, src in seen if src not in owners_of(table, key))
    assert strays == []


def test_owners_of_a_small_scenario_by_hand():
    table = publishers(load_scenario(SCENARIOS[0].parent / "jcstr_benchmark.yaml"))
    assert owners_of(table, "clock/tick") == frozenset()
    assert CLOCK in owners_of(table, "ops/setpoint/level")
    assert table["historian"] == ()
    for key, owners in table.items():
        assert all(not p.startswith("clock/") for p in owners), key


@pytest.mark.slow
@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_every_subscription_falls_inside_its_nodes_read_grant(path):
    """What the router lets a node read (:func:`runtime.ownership.readers`) includes every key
    expression its behaviour subscribes to, as zenoh's access control matches them (a rule
    must include the subscription's whole key expression)."""
    scenario = load_scenario(path)
    table = readers(scenario)
    for name in sorted(scenario.nodes):
        for pattern in behaviour_of(scenario, name).patterns:
            sub = zenoh.KeyExpr(f"w/r/{pattern}")
            assert any(zenoh.KeyExpr(f"w/r/{g}").includes(sub) for g in table[name]), (
                name,
                pattern,
            )
