"""Ticks go to the round's participants only (issue 20): a node receives the tick of a round
it takes part in, and of every SYNC_ROUNDS-th round, and no other; the historian every tick.
And a threads run whose session cannot connect fails its start at once."""

from __future__ import annotations

import json
import threading

from core.errors import ConfigError
from kernel.clock import SYNC_ROUNDS
from kernel.node import BusNode
from runtime import launcher
from runtime.launcher import launch
from tests.conftest import BENCHMARK


def test_a_node_receives_only_the_ticks_of_its_rounds_and_the_sync_ticks(tmp_path, monkeypatch):
    seen: dict[str, list[tuple[int, bool]]] = {}  # node -> (round, took part) per tick received
    lock = threading.Lock()
    original = BusNode._round_

    def spy(self, tick):
        part = tick.participants is None or self.name in tick.participants
        with lock:
            seen.setdefault(self.name, []).append((tick.round, part))
        return original(self, tick)

    monkeypatch.setattr(BusNode, "_round_", spy)
    res = launch(BENCHMARK, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    rounds = max(r for r, _ in seen["historian"]) + 1
    assert rounds > SYNC_ROUNDS  # the benchmark's 305 rounds pass one sync round
    assert [r for r, _ in seen["historian"]] == list(range(rounds))  # every tick, in order
    for name, got in seen.items():
        if name == "historian":
            continue
        received = [r for r, _ in got]
        assert received == sorted(set(received)), name  # in order, once each
        sat_out = [r for r, part in got if not part]
        assert all(r % SYNC_ROUNDS == 0 for r in sat_out), (name, sat_out)
        assert all(r in received for r in range(0, rounds, SYNC_ROUNDS)), name
    operator = seen["operator"]  # the set points at 1.8 and 2.4 pu, and round 0
    assert sum(part for _, part in operator) == 3
    assert len(operator) == 3 + sum(1 for r, part in operator if not part)
    assert len(operator) < rounds / 50


def test_a_session_that_cannot_connect_fails_the_start_at_once(tmp_path, monkeypatch):
    """The threads engine's nodes share one session (identity ``threads``): when it cannot
    connect, the start fails at once, saying so, not after the clock's start-up timeout."""
    real = launcher.open_client

    def refuse_the_nodes(endpoint, *args, **kwargs):
        if '"user": "threads"' in json.dumps(kwargs.get("settings")):
            raise ConfigError(f"no router answers at {endpoint}")
        return real(endpoint, *args, **kwargs)

    monkeypatch.setattr(launcher, "open_client", refuse_the_nodes)
    res = launch(BENCHMARK, tmp_path / "run", engine="threads")
    assert res.code == 1
    # the session's own failure, not the clock's "did not come alive within 120 s"
    assert res.error.startswith("the nodes' session failed while starting"), res.error
    assert "no router answers" in res.error
