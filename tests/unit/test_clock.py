"""The clock's round logic (DESIGN section 3), sparse rounds and the real-time pacer."""

from __future__ import annotations

import json
import sqlite3

import pytest

from bus_schemas import Done
from core.errors import ProtocolError
from core.rounds import Participation
from kernel.clock import SYNC_ROUNDS, Pacer, RoundPlanner
from runtime.launcher import launch
from tests.conftest import SCENARIOS


def done(node, rnd, published=None, next_time=None):
    published = published or {}
    digests = {k: tuple(range(n)) for k, n in published.items()}  # the planner counts them
    return Done(round=rnd, node=node, published=published, digests=digests, next_time=next_time)


def test_microstep_then_next_event_then_end():
    p = RoundPlanner(["a", "b"], end=100, max_microsteps=10)
    assert (p.tick().round, p.tick().t, p.tick().expected) == (0, 0, {})
    p.advance({"a": done("a", 0, {"x/y": 2}, 50), "b": done("b", 0, {"x/y": 1}, 30)})
    t = p.tick()  # something was published: same instant, counts announced
    assert (t.round, t.t, t.expected) == (1, 0, {"x/y": 3})
    p.advance({"a": done("a", 1, {}, 50), "b": done("b", 1, {}, 30)})
    assert (p.tick().round, p.tick().t, p.tick().expected) == (2, 30, {})  # next event
    p.advance({"a": done("a", 2, {}, 50), "b": done("b", 2, {}, 130)})
    assert p.tick().t == 50
    p.advance({"a": done("a", 3, {}, None), "b": done("b", 3, {}, 130)})
    assert p.finished  # 130 is past the end


def test_zero_delay_cycle_is_an_error():
    p = RoundPlanner(["a"], end=100, max_microsteps=3)
    with pytest.raises(ProtocolError, match="microsteps"):
        for r in range(10):
            p.advance({"a": done("a", r, {"k": 1}, 10)})


def test_missing_or_wrong_round_done_is_an_error():
    p = RoundPlanner(["a", "b"], end=100, max_microsteps=3)
    with pytest.raises(ProtocolError, match=r"no Done from \['b'\]"):
        p.advance({"a": done("a", 0)})
    with pytest.raises(ProtocolError, match="round 5"):
        p.advance({"a": done("a", 0), "b": done("b", 5)})


def test_time_cannot_go_back():
    p = RoundPlanner(["a"], end=100, max_microsteps=3)
    p.advance({"a": done("a", 0, {}, 20)})
    with pytest.raises(ProtocolError, match="next_time"):
        p.advance({"a": done("a", 1, {}, 10)})


def test_pacer_targets():
    pacer = Pacer(2.0)
    assert pacer.delay(1_000_000) == pytest.approx(2.0, abs=0.05)  # 1 unit at 2 s/unit
    assert pacer.delay(0) <= 0.0


# -- sparse rounds ------------------------------------------------------------------------------


def test_a_round_ticks_only_nodes_with_a_timer_due_or_a_message_to_collect():
    p = Participation(["plant", "ctrl", "op", "historian", "new"])
    p.learn("plant", 100, ["plant/r/actuator/*", "plant/r/sampling/*"])
    p.learn("ctrl", None, ["loop/level/meas", "ops/setpoint/level"])
    p.learn("op", 180, [])
    p.learn("historian", None, ["**"])  # "new" has not said what it listens to
    assert p.of(100, {}) == {"plant"}  # only the timer
    assert p.of(50, {"loop/level/meas": 1}) == {"ctrl", "historian", "new"}
    assert p.of(100, {"plant/r/actuator/F_out": 1}) == {"plant", "historian", "new"}
    assert p.of(50, {"loop/level/meas": 0}) == set()  # nothing announced on it
    p.learn("new", 70, ["events/network"])
    assert p.of(70, {"loop/level/meas": 1}) == {"ctrl", "historian", "new"}
    p.drop("new")
    assert p.of(70, {}) == set()


def test_the_bus_engines_tick_a_node_only_when_it_has_something_to_do(tmp_path):
    """The benchmark's operator listens to nothing and publishes the set points at 1.8 and
    2.4 pu: it takes part in round 0 and those two rounds only. The historian, an observer,
    records every message of every round (the history's ticks) but answers only the sync rounds,
    one every SYNC_ROUNDS rounds."""
    result = launch(SCENARIOS / "jcstr_benchmark.yaml", tmp_path / "run", engine="threads")
    assert result.code == 0, result.error
    db = sqlite3.connect(tmp_path / "run" / "history.sqlite")
    try:
        stop = json.loads(db.execute("SELECT value FROM meta WHERE name = 'stop'").fetchone()[0])
        ticks = [json.loads(e) for (e,) in db.execute("SELECT expected FROM ticks ORDER BY round")]
    finally:
        db.close()
    taken = stop["rounds_taken"]
    assert taken["operator"] == 3
    assert taken["historian"] == len(range(0, len(ticks), SYNC_ROUNDS))  # 0 and 256 here
    assert len(ticks) == stop["round"] + 1  # it handled every round's tick nonetheless
    assert max(taken.values()) < len(ticks)  # nobody was ticked in every round
