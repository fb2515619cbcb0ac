"""A stretch of the run as the agent saw it, and what its replay takes (issue 35, items 3-4):
trial time, the settling, the run's own sampling grid, each sample's delay, the lost and the
off-grid ones; and the model watch's CUSUM and how it reads a window's steps. Every expected
value is worked out by hand from the window's definition (``agents/wncsca/window.py``)."""

from __future__ import annotations

import numpy as np
import pytest

from agents.wncsca.config import WatchConfig
from agents.wncsca.identification import ClosedLoopExperiment
from agents.wncsca.watch import Score, StepFit, Watch, _steps
from agents.wncsca.window import Window
from core.time import to_ticks, to_units

BASE = {"level": 0.70, "temperature": 52.0}


def _window() -> Window:
    """Replayed from 20 (settled there), samples kept from 20.9, compared from 21 to 22; the
    temperature moved at 20.5 (before the compared part), the level steps at 21. Level every
    0.1 on the phase 0.03; temperature every 0.2 on the phase 0."""
    w = Window(
        t0=20.0,
        since=21.0,
        kept=20.9,
        end=22.0,
        base=BASE,
        changes=((20.5, "temperature", 53.0), (21.0, "level", 0.75)),
        periods={"level": 0.1, "temperature": 0.2},
    )
    w.record("level", 0.69, to_ticks(20.83), to_ticks(20.9))  # before kept: not kept
    w.record("level", 0.69, to_ticks(20.93), to_ticks(21.0))  # kept, not compared
    for k, t in enumerate((21.03, 21.13, 21.33, 21.43)):  # 21.23 lost
        w.record("level", 0.70 + 0.01 * k, to_ticks(t), to_ticks(t) + to_ticks(0.02 * (k + 1)))
    w.record("level", 0.71, to_ticks(21.05), to_ticks(21.1))  # off the grid (another period)
    w.record("temperature", 52.5, to_ticks(21.2), to_ticks(21.25))
    w.record("level", 0.72, to_ticks(22.03), to_ticks(22.1))  # after the end: not kept
    return w


def test_the_replay_runs_in_trial_time_after_the_model_settles_on_the_runs_grid():
    w = _window()
    assert w.phase("level") == to_ticks(0.03) % to_ticks(0.1)
    assert w.off_grid == 1 and w.delivered() == 6
    seen = w.seen({"level": 0.17}, settle=8.0)  # trial time = run time - 20 + 8
    assert seen.steps == (
        (0.0, "level", 0.70),
        (0.0, "temperature", 52.0),
        (8.5, "temperature", 53.0),
        (9.0, "level", 0.75),
    )
    assert seen.end_time == pytest.approx(10.0)
    assert seen.offsets == {"level": pytest.approx(0.03)}  # temperature's grid is the trial's
    assert seen.delays == {"level": 0.17, "temperature": 0.0}
    level = seen.traces["level"]
    assert len(level) == 100  # 0.03, 0.13, ..., 9.93
    delays = [to_ticks(0.07)] + [to_ticks(0.02 * k) for k in (1, 2, 3, 4)]
    median = to_units(int(np.median(delays)))
    assert set(level[:89]) == {median}  # settling and before kept: the median delay
    assert level[89:95] == [
        pytest.approx(0.07),  # 20.93: kept for its delay
        pytest.approx(0.02),
        pytest.approx(0.04),
        None,  # 21.23 was lost
        pytest.approx(0.06),
        pytest.approx(0.08),
    ]
    assert set(level[95:]) == {None}  # nothing delivered after 21.43
    t, y = seen.samples["level"]
    assert t == pytest.approx([9.03, 9.13, 9.33, 9.43]) and y == [0.70, 0.71, 0.72, 0.73]
    assert seen.samples["temperature"] == ([pytest.approx(9.2)], [52.5])
    assert len(seen.traces["temperature"]) == 50
    assert seen.traces["temperature"][46] == pytest.approx(0.05)  # 9.2 in trial time


def test_a_window_at_the_runs_start_is_replayed_as_it_ran():
    w = Window(t0=0.0, end=1.0, base=BASE, changes=(), periods={"level": 0.25, "temperature": 0.5})
    w.record("level", 0.7, 0, 3)
    w.record("level", 0.71, to_ticks(0.5), to_ticks(0.5) + 7)
    seen = w.seen({})
    assert seen.offsets == {} and seen.end_time == 1.0
    assert seen.traces["level"] == [to_units(3), None, to_units(7), None]
    assert seen.traces["temperature"] == [None, None]


def _score(z: float) -> Score:
    return Score((), 0, {}, {}, 0.0, 0.0, 1.0, z)


ZS = (1.0, -3.0, 2.0, 3.0, 1.6, 0.2, 9.0, 6.0)


def test_the_watch_is_a_one_sided_cusum_that_starts_again_after_a_flag():
    watch = Watch(WatchConfig(allowance=0.5, threshold=5.0))
    expected, flags = [], []
    s = 0.0
    for z in ZS:
        s = max(0.0, s + z - 0.5)
        flag = s > 5.0
        expected.append(0.0 if flag else s)
        flags.append(flag)
        s = 0.0 if flag else s
    got = [(watch.update(_score(z)), watch.cusum) for z in ZS]
    assert [f for f, _ in got] == flags == [False, False, False, False, True, False, True, True]
    assert [c for _, c in got] == pytest.approx(expected)
    assert watch.windows == len(ZS)


def test_a_ramp_is_one_step_from_its_first_move_to_its_last_value():
    moves = tuple((22.4 + 0.075 * k, "temperature", 56.0 - 0.5 * k) for k in range(1, 9))
    w = Window(
        t0=20.0,
        since=21.8,
        end=30.0,
        base={"level": 0.75, "temperature": 56.0},
        changes=((21.8, "level", 0.70), *moves),
        periods={"level": 0.175, "temperature": 0.075},
    )
    exp = ClosedLoopExperiment(
        steps=(
            (0.0, "level", 0.75),
            (0.0, "temperature", 56.0),
            *((t - 12.0, loop, v) for t, loop, v in w.changes),
        ),
        end_time=18.0,
        periods=w.periods,
        delays={},
        traces={},
        samples={},
    )
    got = _steps(w, exp)
    assert [(t, loop, a, b) for t, loop, a, b, _, _ in got] == [
        (21.8, "level", 0.75, 0.70),
        (pytest.approx(22.475), "temperature", 56.0, 52.0),
    ]
    assert got[1][4] == pytest.approx(22.475 - 12.0) and got[1][5] == pytest.approx(23.0 - 12.0)
    fit = StepFit("temperature", 56.0, 52.0, 22.475, 18.0, 16.0, 15.0)
    assert "overshot 18.0 % in its delivered samples" in fit.describe()
