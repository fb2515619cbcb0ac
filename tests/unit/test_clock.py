"""The clock's round logic (DESIGN section 3) and real-time pacer, without a bus."""

from __future__ import annotations

import pytest

from bus_schemas import Done
from core.errors import ProtocolError
from kernel.clock import Pacer, RoundPlanner


def done(node, rnd, published=None, next_time=None):
    return Done(round=rnd, node=node, published=published or {}, next_time=next_time)


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
