"""``Behaviour.every`` returns a :class:`core.behaviour.Timer` (issue 34, item 6): it fires at
start and every period to its end, and a retimed one keeps its last firing's phase, each checked
against the instants written out by hand."""

from __future__ import annotations

from core.behaviour import Behaviour


class _Ticker(Behaviour):
    def __init__(self, period: int, *, end: int | None = None) -> None:
        super().__init__("ticker")
        self.fired: list[int] = []
        self.timer = self.every(period, lambda: self.fired.append(self.now), end=end)


def _run_to(b: _Ticker, t_end: int, changes: dict[int, int] | None = None) -> None:
    """Advance ``b`` round by round to its timers (as an engine would), retiming it at the
    instants of ``changes`` (``t -> new period``) before its timers there."""
    changes = dict(changes or {})
    r = b.round + 1
    while True:
        due = [t for t in (b.next_time, *changes) if t is not None and t <= t_end]
        if not due:
            return
        t = min(due)
        b.begin_round(r, t)
        if t in changes:
            b.timer.retime(changes.pop(t))
        b.end_round()
        r += 1


def test_a_timer_fires_at_start_and_every_period_to_its_end():
    b = _Ticker(30, end=100)
    _run_to(b, 1_000)
    assert b.fired == [0, 30, 60, 90]
    assert b.next_time is None  # nothing after its end


def test_a_longer_period_counts_from_the_last_firing():
    b = _Ticker(10)
    _run_to(b, 60, changes={25: 30})  # fired at 20; the next a new period after it: 50
    assert b.fired == [0, 10, 20, 50]


def test_a_shorter_period_that_has_passed_fires_now():
    b = _Ticker(40)
    _run_to(b, 100, changes={55: 10})  # fired at 40; 40 + 10 has passed: now, then every 10
    assert b.fired == [0, 40, 55, 65, 75, 85, 95]


def test_a_change_before_a_firing_in_its_instant_moves_it():
    b = _Ticker(10)
    _run_to(b, 45, changes={20: 15})  # messages come before timers: 20 is moved to 10 + 15
    assert b.fired == [0, 10, 25, 40]


def test_a_timer_retimed_in_the_instant_it_fired_waits_a_new_period():
    b = _Ticker(10)
    _run_to(b, 20)
    b.begin_round(b.round + 1, 20)  # a microstep at the same instant, after the firing
    assert b.timer.retime(15)
    b.end_round()
    _run_to(b, 60)
    assert b.fired == [0, 10, 20, 35, 50]


def test_the_same_period_changes_nothing_and_a_cancelled_timer_fires_no_more():
    b = _Ticker(10)
    assert not b.timer.retime(10)
    _run_to(b, 25)
    b.timer.cancel()
    _run_to(b, 100)
    assert b.fired == [0, 10, 20]
