"""The WNCSCA core (seed 000, III.E) without the bus: judging a proposal's delays (steps 1-2),
the delay bounds at the benchmark periods, the paper's successive approximation of the sampling
periods (step 3) on the worked example, and the coordinator's modes, set points and proposals.

Every expectation is computed independently of the code under test: hand-made bounds and paths,
hand-known sums, and overshoots re-simulated by a fresh :class:`LoopModel`.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from agents.wncsca.bounds import DelayBound, clear_cache, delay_bounds
from agents.wncsca.decision import ProposalError, control_path_delays, decide
from agents.wncsca.paper import successive_approximation
from bus_schemas.errors import SchemaError
from core.time import to_ticks
from runtime.direct import coordinator, loop_model
from scenario import load_scenario
from tests.agent_requests import ask_mode, ask_setpoint, offer, proposal_body, typed_paths
from tests.conftest import SCENARIOS

WNCS = SCENARIOS / "jcstr_wncs.yaml"
LIMIT = 25.0  # %, the scenario's overshoot_limit (seed 000, III.C)
EXAMPLE = {"level": 0.17, "temperature": 0.10}  # III.E worked example, pu
BENCHMARK = {"level": 0.1, "temperature": 0.1}  # tau_s of both loops in jcstr_wncs.yaml
PAPER_TAU_D_LEVEL = 0.253  # pu, III.C: the level loop's largest delay at the benchmark period

# hand-made bounds for the decision tests (no simulation)
BOUNDS = {
    "level": DelayBound("level", 0.25, 24.9),
    "temperature": DelayBound("temperature", 0.15, 24.8),
}


def est(timestamps: Any = None, ping: Any = None, hops: Any = None) -> dict[str, Any]:
    return {"timestamps": timestamps, "ping": ping, "hops": hops}


def path(hops_estimate: Any = None, hops: int = 2, **others: Any) -> dict[str, Any]:
    return {"hops": hops, "estimates": est(hops=hops_estimate, **others)}


def good_paths(level: float = 0.2, temperature: float = 0.1) -> dict[str, Any]:
    return {"level.sensor": path(level, 3), "temperature.sensor": path(temperature, 2)}


# --------------------------------------------------------------------------------------------
# III.E steps 1-2: decision.decide / control_path_delays
# --------------------------------------------------------------------------------------------


def test_accept_when_every_delay_is_below_its_bound():
    d = decide(7, typed_paths(good_paths(0.2, 0.1)), BOUNDS, "hops")
    assert d.verdict == "accept"
    assert d.proposal == 7
    assert d.delays == pytest.approx({"level": 0.2, "temperature": 0.1})
    assert d.bounds == {"level": 0.25, "temperature": 0.15}
    assert d.estimates_used == {"level.sensor": "hops", "temperature.sensor": "hops"}
    assert d.offending == ()


def test_a_delay_equal_to_its_bound_is_rejected():
    # III.E step 2: accept if the delays are *less than* tau_d-max
    d = decide(1, typed_paths(good_paths(0.25, 0.1)), BOUNDS, "hops")
    assert d.verdict == "reject"
    assert d.offending == ("level",)


def test_reject_names_each_offending_loop_with_its_delay_and_bound():
    d = decide(3, typed_paths(good_paths(0.3, 0.2)), BOUNDS, "hops")
    assert d.verdict == "reject"
    assert d.offending == ("level", "temperature")
    level = [r for r in d.reasons if r.startswith("level")]
    temperature = [r for r in d.reasons if r.startswith("temperature")]
    assert len(level) == 1 and "0.3" in level[0] and "0.25" in level[0]
    assert len(temperature) == 1 and "0.2" in temperature[0] and "0.15" in temperature[0]
    assert d.delays == pytest.approx({"level": 0.3, "temperature": 0.2})

    only_level = decide(4, typed_paths(good_paths(0.3, 0.1)), BOUNDS, "hops")
    assert only_level.verdict == "reject"
    assert only_level.offending == ("level",)
    assert not any("temperature" in r for r in only_level.reasons)


@pytest.mark.parametrize("down", ["level.sensor", "level.actuator"])
def test_a_path_that_is_down_rejects_its_loop(down):
    paths = {
        "level.sensor": path(0.05, 1),
        "level.actuator": path(0.05, 1),
        "temperature.sensor": path(0.1, 2),
    }
    paths[down] = {"hops": -1, "estimates": est()}
    d = decide(5, typed_paths(paths), BOUNDS, "hops")
    assert d.verdict == "reject"
    assert d.offending == ("level",)
    assert len(d.reasons) == 1 and d.reasons[0].startswith("level") and "down" in d.reasons[0]
    assert "level" not in d.delays  # no delay for a loop without a route
    assert d.delays["temperature"] == pytest.approx(0.1)

    delays, _ = control_path_delays(typed_paths(paths), ("level", "temperature"), "hops")
    assert delays["level"] is None
    assert delays["temperature"] == pytest.approx(0.1)


@pytest.mark.parametrize(
    ("preferred", "estimates", "value", "used"),
    [
        ("hops", est(0.12, 0.13, 0.14), 0.14, "hops"),
        ("timestamps", est(0.12, 0.13, 0.14), 0.12, "timestamps"),
        ("ping", est(0.12, 0.13, 0.14), 0.13, "ping"),
        # fallback order: timestamps, ping, hops (after the preferred one)
        ("timestamps", est(None, 0.13, 0.14), 0.13, "ping"),
        ("timestamps", est(None, None, 0.14), 0.14, "hops"),
        ("ping", est(0.12, None, 0.14), 0.12, "timestamps"),
        ("hops", est(None, 0.13, None), 0.13, "ping"),
        ("hops", est(0.12, 0.13, None), 0.12, "timestamps"),
        ("hops", {"ping": 0.13}, 0.13, "ping"),  # an estimate left out is missing too
    ],
)
def test_estimate_preference_and_fallback(preferred, estimates, value, used):
    paths = {
        "level.sensor": {"hops": 3, "estimates": estimates},
        "temperature.sensor": path(0.1, 2),
    }
    d = decide(0, typed_paths(paths), BOUNDS, preferred)
    assert d.verdict == "accept"
    assert d.delays["level"] == pytest.approx(value)
    assert d.estimates_used["level.sensor"] == used


def test_sensor_and_actuator_paths_add_up():
    paths = {
        "level.sensor": path(0.1, 2),
        "level.actuator": {"hops": 2, "estimates": est(ping=0.12)},  # falls back to ping
        "temperature.sensor": path(0.1, 2),
    }
    d = decide(0, typed_paths(paths), BOUNDS, "hops")
    assert d.verdict == "accept"
    assert d.delays["level"] == pytest.approx(0.22)
    assert d.estimates_used == {
        "level.sensor": "hops",
        "level.actuator": "ping",
        "temperature.sensor": "hops",
    }
    # each path alone is below the bound 0.25, their sum is not
    paths["level.sensor"] = path(0.15, 2)
    d = decide(1, typed_paths(paths), BOUNDS, "hops")
    assert d.verdict == "reject"
    assert d.offending == ("level",)
    assert d.delays["level"] == pytest.approx(0.27)


def test_wired_loops_need_no_path():
    paths = {"temperature.sensor": path(0.1, 2)}
    d = decide(0, typed_paths(paths), BOUNDS, "hops", wired={"level": 0.05})
    assert d.verdict == "accept"
    assert d.delays == pytest.approx({"level": 0.05, "temperature": 0.1})
    # a wired delay is judged against its bound like any other
    d = decide(0, typed_paths(paths), BOUNDS, "hops", wired={"level": 0.3})
    assert d.verdict == "reject"
    assert d.offending == ("level",)
    # without ``wired`` the level loop has no sensor path: refused
    assert decide(0, typed_paths(paths), BOUNDS, "hops").verdict == "refuse"


def _malformed(edit) -> dict[str, Any]:
    paths = good_paths()
    edit(paths)
    return paths


REFUSALS = {
    "negative delay": (
        _malformed(lambda p: p.update({"level.sensor": path(-0.1, 3)})),
        "paths.level.sensor.estimates.hops",
    ),
    "negative other estimate": (
        _malformed(lambda p: p.update({"level.sensor": path(0.1, 3, ping=-0.01)})),
        "paths.level.sensor.estimates.ping",
    ),
    "non-numeric delay": (
        _malformed(lambda p: p.update({"level.sensor": path("0.1", 3)})),
        "paths.level.sensor.estimates.hops",
    ),
    "boolean delay": (
        _malformed(lambda p: p.update({"level.sensor": path(True, 3)})),
        "paths.level.sensor.estimates.hops",
    ),
    "NaN delay": (
        _malformed(lambda p: p.update({"temperature.sensor": path(math.nan, 2)})),
        "paths.temperature.sensor.estimates.hops",
    ),
    "unknown loop": (
        _malformed(lambda p: p.update({"pressure.sensor": path(0.1, 1)})),
        "paths.pressure.sensor",
    ),
    "unknown direction": (
        _malformed(lambda p: p.update({"level.middle": path(0.1, 1)})),
        "paths.level.middle",
    ),
    "missing estimates": (
        _malformed(lambda p: p.update({"level.sensor": {"hops": 3}})),
        "paths.level.sensor.estimates",
    ),
    "missing hops": (
        _malformed(lambda p: p.update({"level.sensor": {"estimates": est(hops=0.1)}})),
        "paths.level.sensor.hops",
    ),
    "float hops": (
        _malformed(lambda p: p.update({"level.sensor": path(0.1, 3.0)})),
        "paths.level.sensor.hops",
    ),
    "entry not a mapping": (
        _malformed(lambda p: p.update({"level.sensor": 0.1})),
        "paths.level.sensor",
    ),
    "routed path without estimate": (
        _malformed(lambda p: p.update({"level.sensor": {"hops": 3, "estimates": est()}})),
        "paths.level.sensor.estimates",
    ),
    "paths not a mapping": ([("level.sensor", path(0.1))], "paths"),
    "paths missing": (None, "paths"),
    "no sensor path": (
        {"level.actuator": path(0.1, 1), "temperature.sensor": path(0.1, 2)},
        "paths",
    ),
}


SEMANTIC = {"unknown loop", "unknown direction", "routed path without estimate", "no sensor path"}
"""The refusals only the agent can make (it knows the loops); the others are the schema's."""


@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_malformed_proposals_are_refused_naming_the_field(case):
    paths, field = REFUSALS[case]
    try:
        typed = typed_paths(paths)
    except SchemaError as err:  # what the agent node refuses the proposal with (on_invalid)
        assert case not in SEMANTIC, err.problems
        assert any(p.startswith(field) for p in err.problems), err.problems
        return
    assert case in SEMANTIC
    d = decide(9, typed, BOUNDS, "hops")
    assert d.verdict == "refuse", d
    assert d.proposal == 9
    assert len(d.reasons) == 1
    assert field in d.reasons[0], d.reasons[0]
    assert d.offending == () and d.delays == {}
    if case == "no sensor path":
        assert "level" in d.reasons[0]
    with pytest.raises(ProposalError, match=r"paths"):
        control_path_delays(typed, ("level", "temperature"), "hops")


# --------------------------------------------------------------------------------------------
# III.E step 2: the delay bounds at the benchmark periods
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def wncs():
    return load_scenario(WNCS)


@pytest.fixture(scope="module")
def fixed_cfg(wncs):
    return wncs.nodes["wncsca"].model_copy(update={"phase": "fixed"})


def test_delay_bounds_are_checked_within_the_limit_and_violated_one_step_above(wncs, fixed_cfg):
    clear_cache()
    bounds = delay_bounds(loop_model(wncs, fixed_cfg))
    assert set(bounds) == {"level", "temperature"}
    fresh = loop_model(wncs, fixed_cfg)
    res = fixed_cfg.delay_resolution
    for loop, bound in bounds.items():
        d = bound.tau_d_max
        assert bound.loop == loop
        assert 0 < d < fixed_cfg.max_delay
        at = fresh.evaluate({}, {loop: d}).overshoot_pct[loop]
        above = fresh.evaluate({}, {loop: d + res}).overshoot_pct[loop]
        assert at <= LIMIT, (loop, d, at)
        assert above > LIMIT, (loop, d + res, above)
        assert bound.overshoot_pct == pytest.approx(at, abs=1e-9)
    # III.C: the level loop tolerates about 0.253 pu at the benchmark period
    assert bounds["level"].tau_d_max == pytest.approx(PAPER_TAU_D_LEVEL, abs=0.002)


def test_delay_bounds_are_cached(wncs, fixed_cfg):
    model = loop_model(wncs, fixed_cfg)
    first = delay_bounds(model)
    sims = model.simulations
    assert delay_bounds(model) is first
    assert model.simulations == sims  # nothing simulated again
    assert delay_bounds(loop_model(wncs, fixed_cfg)) is first  # cached per plant model
    clear_cache()
    again = delay_bounds(model)
    assert again is not first
    assert {n: b.tau_d_max for n, b in again.items()} == {n: b.tau_d_max for n, b in first.items()}
    # a tighter limit is another cache entry, with smaller bounds
    tight = delay_bounds(loop_model(wncs, fixed_cfg.model_copy(update={"overshoot_limit": 20.0})))
    assert tight is not again
    for loop in again:
        assert tight[loop].tau_d_max < again[loop].tau_d_max


# --------------------------------------------------------------------------------------------
# III.E step 3: successive approximation on the worked example
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def example(wncs, fixed_cfg):
    model = loop_model(wncs, fixed_cfg)
    return model, successive_approximation(model, EXAMPLE)


def _searches(trace) -> list[list[Any]]:
    """The trace's single-loop searches: consecutive trials of one loop in one alternation."""
    groups: list[list[Any]] = []
    for t in trace:
        if t.loop is None:
            continue
        if groups and (groups[-1][0].alternation, groups[-1][0].loop) == (t.alternation, t.loop):
            groups[-1].append(t)
        else:
            groups.append([t])
    return groups


def test_example_is_feasible_and_within_the_limit(example, fixed_cfg):
    _, a = example
    assert a.feasible and a.converged, a.reason
    assert a.delays == pytest.approx(EXAMPLE)
    assert set(a.periods) == {"level", "temperature"}
    for loop, value in a.overshoot_pct.items():
        assert value <= LIMIT, (loop, value)
        # each loop's search stopped within eps_OS of the limit
        assert value >= LIMIT - fixed_cfg.os_tolerance, (loop, value)


def test_example_periods_reevaluated_by_a_fresh_model(example, wncs, fixed_cfg):
    _, a = example
    fresh = loop_model(wncs, fixed_cfg).evaluate(a.periods, EXAMPLE)
    assert fresh.overshoot_pct == pytest.approx(a.overshoot_pct, abs=1e-9)
    assert all(v <= LIMIT for v in fresh.overshoot_pct.values())


def test_example_trace_doubles_then_halves(example, wncs, fixed_cfg):
    # III.E 3a: start at tau_si, double until the limit is violated, then halve the last
    # interval, keeping the acceptable half, until an acceptable trial is within eps_OS
    _, a = example
    res, eps = fixed_cfg.resolution, fixed_cfg.os_tolerance
    fresh = loop_model(wncs, fixed_cfg)
    first = a.trace[0]
    assert (first.loop, first.step) == ("temperature", "start")
    assert first.period == pytest.approx(BENCHMARK["temperature"])  # tau_si: the benchmark
    assert first.periods == pytest.approx(BENCHMARK)
    groups = _searches(a.trace)
    assert [g[0].loop for g in groups[:2]] == ["temperature", "level"]  # the paper's order
    current = dict(BENCHMARK)
    for g in groups:
        loop = g[0].loop
        ideal = BENCHMARK[loop]

        def os_at(trial, loop=loop):
            # the searched loop's overshoot, simulated afresh; also checks the trace's numbers
            value = fresh.evaluate(trial.periods, EXAMPLE).overshoot_pct[loop]
            assert value == pytest.approx(trial.overshoot_pct[loop], abs=1e-9)
            assert trial.ok == (value <= LIMIT)
            return value

        for t in g:  # the other loops stay at their latest search results
            assert t.periods[loop] == pytest.approx(t.period)
            others = {n: p for n, p in t.periods.items() if n != loop}
            assert others == pytest.approx({n: p for n, p in current.items() if n != loop})
        periods = [t.period for t in g]
        assert g[0].step == "start" and periods[0] == pytest.approx(ideal)
        lo, os_lo = periods[0], os_at(g[0])
        assert os_lo <= LIMIT  # in the example the ideal period is acceptable
        i, hi = 1, None
        while hi is None:  # p, 2p, 4p, ... until the first violation
            assert i < len(g), "the doubling never violated the limit"
            assert g[i].step == "double"
            assert periods[i] == pytest.approx(2 * lo, abs=1e-12)
            value = os_at(g[i])
            if value <= LIMIT:
                lo, os_lo = periods[i], value
            else:
                hi = periods[i]
            i += 1
        assert i < len(g), "no halving after the first violation"
        while i < len(g):  # then the midpoint of the last interval, on the period grid
            assert os_lo < LIMIT - eps  # halving goes on only while not within eps_OS
            assert g[i].step == "halve"
            assert lo < periods[i] < hi
            assert abs(periods[i] - (lo + hi) / 2) <= res / 2 + 1e-12
            value = os_at(g[i])
            if value <= LIMIT:
                lo, os_lo = periods[i], value
            else:
                hi = periods[i]
            i += 1
        assert LIMIT - eps <= os_lo <= LIMIT  # stopped within eps_OS of the limit
        kept = [t for t in g if t.period == pytest.approx(lo)]
        assert kept and all(t.ok for t in kept)  # the result is a trial checked acceptable
        current[loop] = lo
    assert a.periods == pytest.approx(current)


def test_example_kept_results_were_ok_and_the_verify_trial_is_ok(example, wncs, fixed_cfg):
    _, a = example
    groups = _searches(a.trace)
    for g, nxt in zip(groups, [*groups[1:], None], strict=True):
        loop = g[0].loop
        # the period the search handed on: used by the next search, or the final periods
        handed = (nxt[0].periods if nxt is not None else a.periods)[loop]
        kept = [t for t in g if t.period == pytest.approx(handed)]
        assert kept, (loop, handed, [t.period for t in g])
        assert all(t.ok and t.overshoot_pct[loop] <= LIMIT for t in kept)
        assert handed == pytest.approx(max(t.period for t in g if t.ok))
    last = a.trace[-1]
    assert (last.loop, last.step, last.period) == (None, "verify", None)
    assert last.ok
    assert last.periods == pytest.approx(a.periods)
    fresh = loop_model(wncs, fixed_cfg).evaluate(last.periods, EXAMPLE)
    assert all(v <= LIMIT for v in fresh.overshoot_pct.values())


def test_a_delay_above_the_bound_is_infeasible(wncs, fixed_cfg):
    model = loop_model(wncs, fixed_cfg)
    a = successive_approximation(model, {"level": 0.4, "temperature": 0.10})
    assert a.feasible is False
    assert a.periods == pytest.approx(BENCHMARK)
    assert "level" in a.reason
    assert a.trace[-1].step == "verify" and not a.trace[-1].ok


# --------------------------------------------------------------------------------------------
# The overshoot is not monotone in the period: an assignment is safe only if it was checked
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("phase", "level", "temperature"),
    [
        ("fixed", 0.0, 0.0),
        ("fixed", 0.05, 0.14),
        ("fixed", 0.12, 0.04),
        ("fixed", 0.2, 0.1),
        ("fixed", 0.25, 0.0),
        ("fixed", 0.0, 0.16),  # temperature above its bound: shorter period found
        ("fixed", 0.26, 0.05),  # level above its bound: shorter period found
        ("worst", 0.17, 0.10),
        ("worst", 0.2, 0.14),
    ],
)
def test_assigned_periods_never_exceed_the_limit(wncs, phase, level, temperature):
    cfg = wncs.nodes["wncsca"].model_copy(update={"phase": phase})
    delays = {"level": level, "temperature": temperature}
    a = successive_approximation(loop_model(wncs, cfg), delays)
    assert a.feasible, a.reason
    assert all(p >= cfg.resolution for p in a.periods.values())
    check = loop_model(wncs, cfg).evaluate(a.periods, delays).overshoot_pct
    for loop, value in check.items():
        assert value <= LIMIT, (loop, a.periods, value)
    assert check == pytest.approx(a.overshoot_pct, abs=1e-9)


# --------------------------------------------------------------------------------------------
# The coordinator: modes, set points, proposals (the scenario's own configuration)
# --------------------------------------------------------------------------------------------

# what the gateway publishes on net/proposal for its first configuration
GATEWAY_PATHS = {
    "level.sensor": {
        "hops": 3,
        "route": ["s_level", "r1", "r2", "gw"],
        "estimates": {"timestamps": None, "ping": 0.16, "hops": 0.17},
    },
    "temperature.sensor": {
        "hops": 2,
        "route": ["s_temp", "r2", "gw"],
        "estimates": {"timestamps": None, "ping": 0.09, "hops": 0.10},
    },
}


def proposal(pid: Any = 0, level_hops: float = 0.17) -> dict[str, Any]:
    paths = {k: {**v, "estimates": dict(v["estimates"])} for k, v in GATEWAY_PATHS.items()}
    paths["level.sensor"]["estimates"]["hops"] = level_hops
    return proposal_body(pid, paths)


def test_rates_per_mode(wncs):
    c = coordinator(wncs)
    assert c.mode == "startup"
    closed = {"level": True, "temperature": True}
    opened = {"level": False, "temperature": False}
    r = c.rates()
    assert (r["mode"], r["periods"], r["closed"]) == ("startup", BENCHMARK, closed)
    expected = {  # from scenarios/jcstr_wncs.yaml, wncsca.modes
        "steady_state": ({"level": 1.0, "temperature": 1.0}, opened),
        "fault_detection": ({"level": 0.5, "temperature": 0.5}, opened),
        "identification": ({"level": 0.05, "temperature": 0.05}, closed),
        "setpoint_change": (BENCHMARK, closed),
        "startup": (BENCHMARK, closed),
    }
    for mode, (periods, loops_closed) in expected.items():
        d = ask_mode(c, {"mode": mode})
        assert d.verdict == "accept"
        r = c.rates()
        assert r["mode"] == mode
        assert r["periods"] == pytest.approx(periods), mode
        assert r["closed"] == loops_closed, mode
    assert c.control_periods == BENCHMARK  # no mode changes the control periods


@pytest.mark.parametrize("body", [{"mode": "bogus"}, {"mode": None}, {}, "steady_state", None])
def test_unknown_mode_is_refused(wncs, body):
    c = coordinator(wncs)
    ask_mode(c, {"mode": "steady_state"})
    before = c.rates()
    d = ask_mode(c, body)
    assert d.verdict == "refuse"
    assert "mode" in d.reasons[0]
    assert c.mode == "steady_state"
    assert c.rates() == before


@pytest.mark.parametrize(
    "body",
    [
        {"value": "0.72"},
        {"value": None},
        {"value": math.nan},
        {"value": math.inf},
        {"value": True},
        {"t_apply": 10},
        {"value": 0.72, "t_apply": -1},
        {"value": 0.72, "t_apply": 16.0},
        {"value": 0.72, "t_apply": "16000000"},
        {"value": 0.72, "t_apply": True},
        [0.72],
    ],
)
def test_invalid_setpoint_is_refused(wncs, body):
    c = coordinator(wncs)
    ask_mode(c, {"mode": "steady_state"})
    now = to_ticks(10.0)
    d, value, when = ask_setpoint(c, "level", body, now)
    assert d.verdict == "refuse"
    assert value is None and when == now
    assert c.mode == "steady_state"
    assert c.rates()["closed"] == {"level": False, "temperature": False}


@pytest.mark.parametrize(
    ("t_apply", "expected"),
    [(to_ticks(16.0), to_ticks(16.0)), (to_ticks(9.0), to_ticks(15.0)), (None, to_ticks(15.0))],
)
def test_valid_setpoint_closes_the_loops_first(wncs, t_apply, expected):
    c = coordinator(wncs)
    ask_mode(c, {"mode": "steady_state"})
    body = {"value": 0.72} if t_apply is None else {"value": 0.72, "t_apply": t_apply}
    d, value, when = ask_setpoint(c, "level", body, to_ticks(15.0))
    assert d.verdict == "accept"
    assert value == 0.72 and isinstance(value, float)
    assert when == expected  # max(t_apply, now)
    assert c.mode == "setpoint_change"
    r = c.rates()
    assert r["closed"] == {"level": True, "temperature": True}
    assert r["periods"] == c.control_periods
    # an integer value is passed on as a number too
    _, value, _ = ask_setpoint(c, "temperature", {"value": 58}, to_ticks(15.0))
    assert value == 58.0


def test_proposal_accepted_then_rejected_then_no_alternative(wncs):
    c = coordinator(wncs)
    neg = offer(c, "network", proposal(0))
    d = neg.decision
    assert d.verdict == "accept", d.reasons
    assert d.proposal == 0 and neg.network == "network"
    assert d.delays == pytest.approx(EXAMPLE)  # the hops estimates
    assert d.estimates_used == {"level.sensor": "hops", "temperature.sensor": "hops"}
    assigned = dict(c.control_periods)
    assert neg.assignment is not None and neg.assignment.feasible
    assert assigned == neg.assignment.periods
    assert assigned != BENCHMARK
    # the control periods are within the limit, simulated afresh (worst phase, as configured)
    check = loop_model(wncs, c.config).evaluate(assigned, EXAMPLE).overshoot_pct
    assert all(v <= LIMIT for v in check.values()), check
    # longer periods, fewer samples: the network outlives its benchmark lifetime
    assert all(assigned[n] > BENCHMARK[n] for n in assigned)
    e = neg.energy
    assert e is not None and e["ratio"] is not None
    assert e["ratio"] > 1
    assert e["lifetime_h_assigned"] > e["lifetime_h_benchmark"] > 0
    assert e["ratio"] == pytest.approx(e["lifetime_h_assigned"] / e["lifetime_h_benchmark"])
    r = c.rates()
    assert r["mode"] == "startup" and r["periods"] == assigned

    # the level path over the slow relay: 0.30 pu is above the level bound
    neg = offer(c, "network", proposal(1, level_hops=0.30))
    assert neg.decision.verdict == "reject"
    assert neg.decision.offending == ("level",)
    assert neg.assignment is None
    assert c.control_periods == assigned
    assert c.rates()["periods"] == assigned

    keep = c.on_no_alternative("network", 1)
    assert keep.verdict == "keep"
    assert "#0" in keep.reasons[0]  # the last accepted proposal
    assert c.control_periods == assigned


def test_a_rejected_configuration_run_for_want_of_an_alternative_puts_its_loops_at_risk(wncs):
    """Issue 35, item 6: the network runs proposal #1, rejected for the level's delay; the
    agent says the level is at risk, refuses its set-point steps (a temperature step still
    passes), and an accepted configuration ends the risk."""
    c = coordinator(wncs)
    offer(c, "network", proposal(0))
    assert offer(c, "network", proposal(1, level_hops=0.30)).decision.verdict == "reject"
    keep = c.on_no_alternative("network", 1)
    text = " ".join(keep.reasons)
    assert "the network runs it" in text and "no longer runs it" in text
    assert "loops at risk: level " in text and "rejected because: level" in text
    assert c.at_risk == {"network": (1, ("level",))}
    d, value, _ = ask_setpoint(c, "level", {"value": 0.72}, to_ticks(26.0))
    assert d.verdict == "refuse" and value is None
    assert "level is at risk, network runs proposal #1, which the agent rejected" in d.reasons[0]
    d, value, _ = ask_setpoint(c, "temperature", {"value": 58.0}, to_ticks(26.0))
    assert d.verdict == "accept" and value == 58.0  # its path was judged safe and runs
    assert offer(c, "network", proposal(2)).decision.verdict == "accept"
    assert c.at_risk == {}
    d, value, _ = ask_setpoint(c, "level", {"value": 0.72}, to_ticks(27.0))
    assert d.verdict == "accept" and value == 0.72


def test_reject_before_any_acceptance_keeps_the_benchmark(wncs):
    c = coordinator(wncs)
    neg = offer(c, "network", proposal(4, level_hops=0.30))
    assert neg.decision.verdict == "reject"
    assert neg.decision.offending == ("level",)
    assert c.control_periods == BENCHMARK
    keep = c.on_no_alternative("network", 4)
    assert keep.verdict == "keep"
    assert "#0" not in keep.reasons[0]
    assert "benchmark" in keep.reasons[0]


@pytest.mark.parametrize(
    ("network", "body", "field"),
    [
        ("network", {"paths": GATEWAY_PATHS}, "id"),
        ("network", {"id": -1, "paths": GATEWAY_PATHS}, "id"),
        ("network", {"id": "0", "paths": GATEWAY_PATHS}, "id"),
        ("network", {"id": True, "paths": GATEWAY_PATHS}, "id"),
        ("network", {"id": 1.0, "paths": GATEWAY_PATHS}, "id"),
        ("network", [0, GATEWAY_PATHS], "id"),
        ("elsewhere", {"id": 0, "paths": GATEWAY_PATHS}, "elsewhere"),
        ("operator", {"id": 0, "paths": GATEWAY_PATHS}, "operator"),  # a node, not a gateway
        ("network", {"id": 0}, "paths"),
        (
            "network",
            {"id": 0, "paths": {**GATEWAY_PATHS, "level.sensor": path(-0.1, 3)}},
            "paths.level.sensor.estimates.hops",
        ),
    ],
)
def test_malformed_proposals_change_nothing(wncs, network, body, field):
    c = coordinator(wncs)
    ask_mode(c, {"mode": "steady_state"})
    before = c.rates()
    neg = offer(c, network, body)
    assert neg.decision.verdict == "refuse"
    assert field in neg.decision.reasons[0], neg.decision.reasons
    assert neg.assignment is None
    assert c.control_periods == BENCHMARK
    assert c.accepted == {} and c.proposal is None
    assert c.mode == "steady_state" and c.rates() == before


# --------------------------------------------------------------------------------------------
# Malformed entries that once crashed the core: the schema refuses them now
# --------------------------------------------------------------------------------------------

CRASHES = {
    # msgpack (bus_schemas.codec, raw=False) delivers a bin-type key as bytes beside str keys
    # (once: ``sorted(paths)`` raised TypeError)
    "bytes key beside str keys": (
        {**good_paths(), b"level.actuator": path(0.01, 1)},
        "paths: key b'level.actuator'",
    ),
    # (once: ``sorted(set(estimates) - set(ESTIMATES))`` raised TypeError)
    "bytes estimate name beside str": (
        {
            **good_paths(),
            "level.sensor": {"hops": 3, "estimates": {"hops": 0.1, b"x": 0.1, "y": 0.1}},
        },
        "paths.level.sensor.estimates: key b'x'",
    ),
    # (once: ``math.isfinite`` of an int too large for a float raised OverflowError)
    "huge integer delay": (
        {**good_paths(), "level.sensor": path(10**400, 3)},
        "paths.level.sensor.estimates.hops",
    ),
}


@pytest.mark.parametrize("case", sorted(CRASHES))
def test_unorderable_or_oversized_entries_are_refused(case):
    paths, field = CRASHES[case]
    with pytest.raises(SchemaError) as err:
        typed_paths(paths)
    assert any(p.startswith(field) for p in err.value.problems), err.value.problems


@pytest.mark.parametrize("route", [5, ["s_level", 3, "gw"]])
def test_a_malformed_route_does_not_crash_the_agent(wncs, route):
    c = coordinator(wncs)
    body = proposal(0)
    body["paths"]["level.sensor"]["route"] = route
    neg = offer(c, "network", body)
    if neg.decision.verdict == "refuse":
        assert c.control_periods == BENCHMARK and c.accepted == {}
    else:
        assert neg.decision.verdict == "accept" and neg.energy is None
