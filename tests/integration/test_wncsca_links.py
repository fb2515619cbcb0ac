"""The coordination agent governing the update period of linked controllers (seed 001) over the
bus: it analyses the controllers' own linearized loop, assigns margin x h_max at t = 0, and the
controllers follow; the run then equals the direct engine's run at the assigned period."""

from __future__ import annotations

import itertools
import sqlite3

import pytest

from agents.update_period.analysis import CSTRRecycleCase
from agents.update_period.delay import DelayedUpdates, find_h_range
from controllers.qdc.model import closed_loop_matrices
from controllers.qdc.network import QDCNetwork
from core.errors import ConfigError
from core.record import summarize
from core.time import to_ticks, to_units
from runtime.direct import simulate
from runtime.launcher import launch
from scenario import load_scenario
from tests.conftest import SCENARIOS, write_variant
from tests.integration.test_column_mrac_bus import assert_traces_equal

AGENT = SCENARIOS / "cstr_recycle_qdc_agent.yaml"
QDC = SCENARIOS / "cstr_recycle_qdc.yaml"


def _end(t: float):
    def edit(d):
        d["end_time"] = t

    return edit


def test_agent_assigns_margin_times_h_max_and_the_run_follows(tmp_path):
    path = write_variant(tmp_path, AGENT, "agent.yaml", _end(0.3))
    scenario = load_scenario(path)
    assert all(lk.period == 0.05 for lk in scenario.links.values())  # unsafe as written
    res = launch(path, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    # independent: the paper's test on the analysis' own CSTR case (same design settings)
    h_max = CSTRRecycleCase().h_max("qdc").h_max
    (decision,) = [d for d in res.summary["wncsca"]["decisions"] if d["subject"] == "links"]
    assert decision["verdict"] == "accept" and decision["t"] == 0.0
    (group,) = decision["links"]
    assert group["h_max"] == pytest.approx(h_max, rel=1e-6)
    assert group["h"] == pytest.approx(0.9 * h_max, rel=1e-6)
    assert 0 < group["rho"] < 1
    h_ticks = to_ticks(group["h"])

    # the controllers followed: the same run as the scenario written with that period
    def at_assigned(d):
        d["end_time"] = 0.3
        for link in d["links"].values():
            link["period"] = to_units(h_ticks)

    direct = summarize(simulate(load_scenario(write_variant(tmp_path, QDC, "d.yaml", at_assigned))))
    assert_traces_equal(res.summary, direct)
    assert res.summary["network"]["links"]["x1"]["delivered"] == 0.3 // to_units(h_ticks) + 1


def test_linked_controllers_need_the_agents_links_setting(tmp_path):
    def no_links(d):
        del d["nodes"]["wncsca"]["links"]

    with pytest.raises(ConfigError, match=r"nodes.unit1.loops: .*links: in nodes.wncsca"):
        load_scenario(write_variant(tmp_path, AGENT, "a.yaml", no_links))

    def no_scenario_links(d):
        d["nodes"]["wncsca"]["links"] = {"margin": 0.9}

    wncs = SCENARIOS / "jcstr_wncs.yaml"
    with pytest.raises(ConfigError, match="nodes.wncsca.links: the scenario has no links"):
        load_scenario(write_variant(tmp_path, wncs, "b.yaml", no_scenario_links))

    def bad_margin(d):
        d["nodes"]["wncsca"]["links"] = {"margin": 1.2}

    with pytest.raises(ConfigError, match="margin"):
        load_scenario(write_variant(tmp_path, AGENT, "c.yaml", bad_margin))


def test_agent_follows_a_changing_wsn(tmp_path):
    """cstr_recycle_qdc_wncs.yaml, its events moved earlier: at every proposal (start, relay r
    down, r back up) the agent sets h = margin x h_max(d) for the proposal's link delay, and the
    controllers transmit at that period from their next send."""

    def early(d):
        d["end_time"] = 0.3
        d["nodes"]["wsn"]["events"] = [
            {"t": 0.1, "event": {"type": "node_down", "node": "r"}},
            {"t": 0.2, "event": {"type": "node_up", "node": "r"}},
        ]

    path = write_variant(tmp_path, SCENARIOS / "cstr_recycle_qdc_wncs.yaml", "w.yaml", early)
    res = launch(path, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    w = res.summary["wncsca"]
    case = CSTRRecycleCase()
    system = DelayedUpdates(*closed_loop_matrices(case.plant, QDCNetwork(case.plant, case.gains)))
    decisions = [d for d in w["decisions"] if d["subject"] == "proposal"]
    assert [(d["t"], d["verdict"]) for d in decisions] == [
        (0.0, "accept"),
        (0.1, "accept"),
        (0.2, "accept"),
    ]
    periods = []
    for prop, dec in zip(w["proposals"], decisions, strict=True):
        delay = max(prop["estimates"][f"{n}.link"]["hops"] for n in ("x1", "x2"))
        want = 0.8 * find_h_range(system, delay).h_max
        (group,) = dec["links"]
        assert group["delay"] == pytest.approx(delay)
        assert group["h"] == pytest.approx(want, rel=1e-6)
        periods.append(to_ticks(group["h"]))
    assert periods[1] < periods[0] == periods[2]  # the slow route needs more frequent updates
    with sqlite3.connect(tmp_path / "run" / "history.sqlite") as conn:
        sends = [t for (t,) in conn.execute("SELECT t FROM messages WHERE key = 'link/x1/tx'")]
    gaps = {(a, b - a) for a, b in itertools.pairwise(sends)}
    assert (0, to_ticks(0.05)) not in gaps  # the scenario's unsafe period was never used
    for start, period in zip((0, to_ticks(0.1), to_ticks(0.2)), periods, strict=True):
        later = [g for a, g in gaps if a >= start + period]
        assert period in later


def test_a_sampled_analysis_needs_one_sampling_period(tmp_path):
    def two_periods(d):
        d["nodes"]["wncsca"]["links"] = {"analysis": "sampled"}
        d["loops"]["t2"]["tau_s"] = 0.001

    with pytest.raises(ConfigError, match=r"nodes.wncsca.links: links.analysis: sampled needs one"):
        load_scenario(write_variant(tmp_path, AGENT, "s.yaml", two_periods))
