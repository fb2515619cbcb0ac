"""The agent's batched non-linear checks (agents/wncsca/batch.py) and the fast method on N loops
(issue 20, item 5).

The batch must give the engine's numbers: each trial of the batch is compared with the same trial
run alone on the ``direct`` engine (:meth:`LoopModel.evaluate`, one closed-loop simulation per
phase), and each plant's ``rhs_batch`` with its scalar right-hand side. The fast method's answers
on the N-loop problems (``runtime/agent_problems.py``) must equal the paper method's within 5 %
per loop period, and not depend on whether its checks are batched.
"""

from __future__ import annotations

import numpy as np
import pytest

from agents.wncsca.batch import BatchTrials
from agents.wncsca.fast import fast_periods
from agents.wncsca.paper import successive_approximation
from runtime.agent_problems import jcstr_loops
from runtime.direct import loop_model
from scenario import load_scenario
from tests.conftest import SCENARIOS

ROWS = {  # columns: level0, tank1, temperature0 (the model's loop order)
    "benchmark": [0.1, 0.1, 0.1],
    "near the answer": [0.275, 0.278, 0.138],
    "long": [0.31, 0.45, 0.2],
    "uneven": [0.173, 0.05, 0.451],
    "period = delay": [0.17, 0.17, 0.1],
}


@pytest.mark.parametrize("phase", ["worst", "fixed"])
def test_batch_equals_one_engine_trial_at_a_time(phase):
    """Every row, all in one batch, against the engine running each trial alone (a reactor
    with two loops and a tank, every step phase): the same overshoots to the last bit."""
    scenario, delays = jcstr_loops(3, phase=phase)
    model = loop_model(scenario)
    assert model.loops == ("level0", "tank1", "temperature0")
    batch = BatchTrials(model)
    assert batch.available, batch.reason
    rows = np.array(list(ROWS.values()))
    batched = batch.overshoots(rows, delays)
    for row, got in zip(rows, batched, strict=True):
        ev = model.evaluate(dict(zip(model.loops, row, strict=True)), delays)
        expected = [ev.overshoot_pct[n] for n in model.loops]
        assert got.tolist() == expected, (row, got, expected)
    n_phases = 4 if phase == "worst" else 1
    assert batch.items == len(rows) * 2 * n_phases  # one trial per plant, row and phase
    again = batch.overshoots(rows[:2], delays)  # memoised per plant
    assert batch.items == len(rows) * 2 * n_phases
    np.testing.assert_array_equal(again, batched[:2])


def test_batch_sees_delays_and_zero_delay():
    scenario, delays = jcstr_loops(3)
    model = loop_model(scenario)
    batch = BatchTrials(model)
    row = np.array([ROWS["near the answer"]])
    for d in (delays, {n: 0.0 for n in delays}, {**delays, "level0": 0.3}):
        ev = model.evaluate(dict(zip(model.loops, row[0], strict=True)), d)
        assert batch.overshoots(row, d)[0].tolist() == [ev.overshoot_pct[n] for n in model.loops]


def test_rhs_batch_is_the_scalar_rhs_element_by_element():
    rng = np.random.default_rng(20)
    scenario, _ = jcstr_loops(3)
    for plant in ("reactor0", "tank1"):
        model = scenario.nodes[plant].build()
        n = 50
        x = [rng.uniform(-0.1, 2.0, n) for _ in model.state_names]
        if plant == "reactor0":
            x[1], x[2] = rng.uniform(40, 60, n), rng.uniform(100, 200, n)
        u = [rng.uniform(-0.5, 12.0, n) for _ in model.input_names]
        p = [np.full(n, v) for v in model.batch_params()]
        got = np.array(type(model).rhs_batch(p, x, u))
        scalar = getattr(model, "rhs_tuple", None)
        for i in range(n):
            xi = np.array([c[i] for c in x])
            ui = np.array([c[i] for c in u])
            want = scalar(0.0, tuple(xi), tuple(ui)) if scalar else model.rhs(0.0, xi, ui)
            assert got[:, i].tolist() == list(want), (plant, i)


def test_unbatchable_models_say_why():
    model = loop_model(load_scenario(SCENARIOS / "tank_sim.yaml"))  # a non-linear PI law
    batch = BatchTrials(model)
    assert not batch.available and "'nlpi'" in batch.reason
    with pytest.raises(ValueError, match="unavailable"):
        batch.overshoots(np.array([[0.1]]), {})


def test_problem_builder():
    for n in (1, 2, 5, 10):
        scenario, delays = jcstr_loops(n)
        assert len(scenario.loops) == n == len(delays)
        assert len(scenario.setpoints) == n
        plants = {lp.plant for lp in scenario.loops.values()}
        assert len(plants) == (n + 1) // 2
    with pytest.raises(ValueError, match="at least one"):
        jcstr_loops(0)


# -- the fast method on N loops --------------------------------------------------------------


def _both(n: int):
    scenario, delays = jcstr_loops(n, os_tolerance=0.2)
    paper = successive_approximation(loop_model(scenario), delays)
    fast = fast_periods(loop_model(scenario), delays)
    return paper, fast, scenario, delays


def _assert_equal_answers(paper, fast):
    assert paper.feasible and fast.feasible, (paper.reason, fast.reason)
    off = {
        n: (fast.periods[n], p)
        for n, p in paper.periods.items()
        if abs(fast.periods[n] / p - 1.0) > 0.05
    }
    assert not off, off
    assert all(v <= 25.0 for v in fast.overshoot_pct.values())


def test_two_loops_fast_equals_paper_within_5_percent():
    paper, fast, _, _ = _both(2)
    _assert_equal_answers(paper, fast)
    assert fast.extra["batched_trials"] == 0  # one plant: engine checks, as before


@pytest.mark.slow
def test_five_loops_fast_equals_paper_within_5_percent():
    """Two reactors and a tank; the fast method's checks batched (several plants); its answer
    is the unbatched method's, and its overshoots those of a fresh engine trial."""
    paper, fast, scenario, delays = _both(5)
    _assert_equal_answers(paper, fast)
    assert fast.extra["batched_trials"] > 0 and fast.simulations == 0
    plain = fast_periods(loop_model(scenario), delays, batched=False)
    assert plain.extra["batched_trials"] == 0 and plain.simulations > 0
    assert plain.periods == fast.periods
    assert plain.overshoot_pct == fast.overshoot_pct
    fresh = loop_model(scenario).evaluate(fast.periods, delays)
    assert fresh.overshoot_pct == fast.overshoot_pct


def test_inputs_terms_held_over_a_segment_equal_the_full_rhs():
    """``rhs_batch_inputs`` with a state and a span, then ``rhs_batch_held`` at any state the
    segment can reach (the level moved by up to the span times its rate), equals ``rhs_batch``:
    for well-filled levels (where the JCSTR skips its empty-tank clamp and level floor) and for
    levels near empty (where it keeps them), so a wrong bound shows."""
    rng = np.random.default_rng(21)
    scenario, _ = jcstr_loops(3)
    for plant in ("reactor0", "tank1"):
        model = scenario.nodes[plant].build()
        kind = type(model)
        for low, levels in ((False, (0.2, 1.5)), (True, (-0.002, 0.02))):
            n = 200
            x = [rng.uniform(*levels, n) for _ in model.state_names]
            if plant == "reactor0":
                x[1], x[2] = rng.uniform(40, 60, n), rng.uniform(100, 200, n)
            u = [rng.uniform(-0.5, 12.0, n) for _ in model.input_names]
            p = [np.full(n, v) for v in model.batch_params()]
            span = np.full(n, 0.01)
            held = kind.rhs_batch_inputs(p, u, x, span)
            if plant == "reactor0":
                assert bool(held[2]) == low
            rate = np.asarray(kind.rhs_batch(p, x, u)[0])
            for c in (0.0, 0.0025, 0.005, 0.01):
                xs = [x[0] + c * rate, *x[1:]]
                got = np.array(kind.rhs_batch_held(p, xs, held))
                want = np.array(kind.rhs_batch(p, xs, u))
                np.testing.assert_array_equal(got, want)


def test_rows_ahead_ride_along_and_are_memoised():
    """Rows passed ``ahead`` are simulated only with a plant simulated anyway, in the same
    batch; asked later, they cost no batch and give a fresh engine trial's overshoots."""
    scenario, delays = jcstr_loops(3)
    model = loop_model(scenario)
    batch = BatchTrials(model)
    row = np.array([ROWS["near the answer"]])
    ahead = row.copy()
    ahead[0, 2] += 0.001  # temperature0: the reactor's plant
    batch.overshoots(row, delays, ahead)
    assert batch.batches == 2  # the reactor and the tank, as without ``ahead``
    assert batch.items == (2 + 1) * 4  # reactor: the row and the row ahead; tank: the row
    got = batch.overshoots(ahead, delays)
    assert batch.batches == 2 and batch.items == 12  # memoised: nothing simulated
    ev = model.evaluate(dict(zip(model.loops, ahead[0], strict=True)), delays)
    assert got[0].tolist() == [ev.overshoot_pct[n] for n in model.loops]
    batch.overshoots(row, delays, ahead + 0.002)  # every plant memoised: no batch at all
    assert batch.batches == 2 and batch.items == 12
