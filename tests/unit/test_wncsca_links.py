"""The agent's update-period governance of linked controllers (agents/wncsca/links.py)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError

from agents.update_period.analysis import CSTRRecycleCase
from agents.update_period.delay import DelayedUpdates, find_h_range
from agents.update_period.sampled import SampledQDC, find_h_max_sampled
from agents.wncsca.config import LinksConfig, WncscaConfig
from agents.wncsca.links import judge_links, link_groups
from controllers.qdc.model import closed_loop_matrices
from controllers.qdc.network import QDCNetwork
from runtime.direct import coordinator as build_coordinator
from scenario import load_scenario
from tests.agent_requests import offer, proposal_body
from tests.conftest import SCENARIOS, write_variant

CASE = CSTRRecycleCase()
H_MAX = CASE.h_max("qdc").h_max


class _Law:
    def __init__(self, delta1: float = 0.0, scheme: str = "model") -> None:
        net = QDCNetwork(CASE.plant, CASE.gains, model=CASE.model(delta1), scheme=scheme)
        self.matrices = closed_loop_matrices(CASE.plant, net)

    def closed_loop(self):
        return self.matrices


def _links(**links):
    return {n: SimpleNamespace(from_=a, to=b) for n, (a, b) in links.items()}


def _no_tau_s(controller: str) -> float:
    raise AssertionError("the spectral-radius analysis needs no sampling period")


def _group(delta1: float = 0.0, scheme: str = "model"):
    law = _Law(delta1, scheme)
    (g,) = link_groups(_links(x1=("u1", "u2"), x2=("u2", "u1")), lambda c: law, tau_s=_no_tau_s)
    return g


def test_groups_join_linked_controllers_and_name_their_links():
    laws = {c: _Law() for c in ("a", "b", "c", "d")}
    groups = link_groups(
        _links(l1=("a", "b"), l2=("b", "a"), l3=("c", "d")), lambda c: laws[c], tau_s=_no_tau_s
    )
    assert [(g.controllers, g.links) for g in groups] == [
        (("a", "b"), ("l1", "l2")),
        (("c", "d"), ("l3",)),
    ]


def test_no_delay_assigns_the_margin_times_the_papers_h_max():
    v = judge_links(_group(), {}, LinksConfig(margin=0.9))
    assert v.verdict == "accept"
    assert v.h_max == pytest.approx(H_MAX, abs=1e-7)
    assert v.h == pytest.approx(0.9 * H_MAX, abs=1e-7)
    assert v.periods == {"x1": v.h, "x2": v.h}
    assert v.rho < 1
    assert "h_max" in v.reasons[0]


def test_zero_order_hold_and_mismatch_give_their_own_h_max():
    for delta1, scheme, arch in ((0.0, "zoh", "qdc_zoh"), (0.3, "model", "qdc")):
        v = judge_links(_group(delta1, scheme), {}, LinksConfig())
        assert v.h_max == pytest.approx(CASE.h_max(arch, delta1).h_max, abs=1e-7)


def test_a_link_delay_shortens_the_period_and_too_long_a_delay_is_rejected():
    g = _group()
    short = judge_links(g, {"x1": 0.002, "x2": 0.005}, LinksConfig())
    assert short.verdict == "accept" and short.delay == 0.005
    assert short.h < 0.9 * H_MAX and short.h > 0.005
    bad = judge_links(g, {"x1": 0.06}, LinksConfig())
    assert bad.verdict == "reject" and bad.h is None
    assert "no update period" in bad.reasons[0] and "x1" in bad.reasons[0]
    assert math.isnan(bad.as_dict()["h_max"] or math.nan)


def test_a_law_without_closed_loop_or_with_another_design_is_refused():
    with pytest.raises(ValueError, match="nodes.u1.law: .*closed_loop"):
        link_groups(_links(x1=("u1", "u2")), lambda c: object(), tau_s=_no_tau_s)
    laws = {"u1": _Law(0.0), "u2": _Law(0.3)}
    with pytest.raises(ValueError, match="nodes.u2.law: describes another networked loop"):
        link_groups(_links(x1=("u1", "u2")), lambda c: laws[c], tau_s=_no_tau_s)


def test_links_config_is_validated():
    with pytest.raises(ValidationError, match="margin"):
        WncscaConfig(links={"margin": 1.5})
    with pytest.raises(ValidationError, match="analysis"):
        WncscaConfig(links={"analysis": "simulation"})
    assert WncscaConfig(links={}).links.margin == 0.9


def test_delayed_updates_refuse_mismatched_shapes():
    with pytest.raises(ValueError, match="square"):
        DelayedUpdates(np.eye(3), np.eye(2))


# -- the coordinator: proposals of a gateway carrying links ---------------------------------------

WNCS_QDC = SCENARIOS / "cstr_recycle_qdc_wncs.yaml"


def _link_path(delay, hops=2):
    return {"hops": hops, "route": [], "estimates": {"hops": delay}}


@pytest.fixture(scope="module")
def coordinator():
    return build_coordinator(load_scenario(WNCS_QDC))


def test_the_coordinator_builds_the_group_from_the_controllers_laws(coordinator):
    (group,) = coordinator.link_groups
    assert group.controllers == ("unit1", "unit2") and group.links == ("x1", "x2")
    ref = _Law().closed_loop()  # the analysis' own CSTR case, built apart from the laws
    np.testing.assert_allclose(group.system.Acl, ref[0], rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(group.system.Rcl, ref[1])
    assert coordinator.loops == ()  # nothing to simulate: every loop is a linked controller's
    assert coordinator.govern_links() == []  # the links are on the gateway: wait for proposals


def test_a_proposal_sets_the_update_period_from_the_links_delay(coordinator):
    config = coordinator.config.links
    for pid, d in enumerate((0.0009, 0.0094, 0.0009)):
        neg = offer(
            coordinator,
            "wsn",
            proposal_body(pid, {"x1.link": _link_path(d), "x2.link": _link_path(d / 2)}),
        )
        assert neg.decision.verdict == "accept", neg.decision.reasons
        want = find_h_range(DelayedUpdates(*_Law().closed_loop()), d, h_hi=config.h_hi)
        assert coordinator.link_periods == {
            "x1": pytest.approx(config.margin * want.h_max, rel=1e-6),
            "x2": pytest.approx(config.margin * want.h_max, rel=1e-6),
        }
        assert neg.decision.delays == {"x1": d, "x2": d}
    assert neg.assignment is None  # no loop to negotiate


def test_a_proposal_no_period_can_live_with_is_rejected_and_changes_nothing(coordinator):
    before = dict(coordinator.link_periods)
    neg = offer(
        coordinator,
        "wsn",
        proposal_body(7, {"x1.link": _link_path(0.08, 5), "x2.link": _link_path(0.001)}),
    )
    assert neg.decision.verdict == "reject"
    assert neg.decision.offending == ("x1", "x2")
    assert "no update period" in neg.decision.reasons[-1]
    down = offer(
        coordinator,
        "wsn",
        proposal_body(8, {"x1.link": _link_path(None, -1), "x2.link": _link_path(0.001)}),
    )
    assert down.decision.verdict == "reject" and "no route" in down.decision.reasons[-1]
    assert coordinator.link_periods == before


@pytest.mark.parametrize(
    ("paths", "why"),
    [
        ({"x1.link": _link_path(0.001)}, "paths.x2.link: missing"),
        ({"x1.link": _link_path(-0.001), "x2.link": _link_path(0.001)}, "x1.link.estimates"),
        ({"x1.link": "fast", "x2.link": _link_path(0.001)}, "paths.x1.link: Input should be"),
    ],
)
def test_a_malformed_link_path_is_refused(coordinator, paths, why):
    before = dict(coordinator.link_periods)
    neg = offer(coordinator, "wsn", proposal_body(9, paths))
    assert neg.decision.verdict == "refuse" and why in neg.decision.reasons[0]
    assert coordinator.link_periods == before


def test_the_sampled_analysis_assigns_a_multiple_of_the_sampling_period(tmp_path):
    """analysis: sampled: h = floor(margin x N_max) tau_s, N_max from find_h_max_sampled on the
    analysis' own CSTR case (built apart from the laws); a link delay is rounded up to samples."""

    def sampled(d):
        d["nodes"]["wncsca"]["links"] = {"analysis": "sampled", "margin": 0.9}

    path = write_variant(tmp_path, SCENARIOS / "cstr_recycle_qdc_agent.yaml", "s.yaml", sampled)
    coord = build_coordinator(load_scenario(path))
    (v,) = coord.govern_links()
    tau = 0.0005  # the scenario's tau_s
    ref = SampledQDC.from_law_parts(CASE.plant, QDCNetwork(CASE.plant, CASE.gains), tau)
    n_max = find_h_max_sampled(ref).n_max
    assert v.verdict == "accept"
    assert v.h_max == pytest.approx(n_max * tau)
    assert v.h == pytest.approx(int(0.9 * n_max) * tau)
    assert v.rho == pytest.approx(ref.spectral_radius(int(0.9 * n_max)))
    # a delay of 2.2 samples is judged as 3
    delayed = judge_links(coord.link_groups[0], {"x1": 2.2 * tau}, coord.config.links)
    assert delayed.h_max == pytest.approx(find_h_max_sampled(ref, n_delay=3).n_max * tau)
