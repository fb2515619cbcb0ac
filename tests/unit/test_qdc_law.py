"""Seed 001's quasi-decentralized control as a platform law (``controllers/qdc/law.py``), the two
CSTRs with recycle on the direct engine, and what the scenario refuses.

Independent references: the stacked controller of :class:`controllers.qdc.network.QDCNetwork`
integrated by ``solve_ivp`` (the law's exact propagation),
:func:`controllers.qdc.model.simulate_nonlinear`
(continuous-time controllers against the non-linear plant: the sampled loop converges to it at
first order in ``tau_s``), and ``h_max`` from :mod:`agents.update_period.analysis` for the law's
own gains.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.integrate import solve_ivp

from agents.update_period.analysis import CSTRRecycleCase, build_lambda, find_h_max
from bus_schemas import Estimate, Rates, keys
from controllers.behaviour import ControllerBehaviour
from controllers.qdc.model import simulate_nonlinear
from controllers.qdc.network import QDCNetwork
from controllers.registry import build_multi_loop_law
from core.errors import ConfigError
from core.record import summarize
from core.time import to_ticks
from runtime.direct import simulate
from scenario import load_scenario
from scenario.views import controller_spec
from tests.conftest import SCENARIOS, write_variant

QDC = SCENARIOS / "cstr_recycle_qdc.yaml"
CASE = CSTRRecycleCase()
UNITS = ("unit1", "unit2")


def _law(scenario, node):
    cfg = scenario.nodes[node]
    plant = scenario.nodes[scenario.loops[cfg.loops[0]].plant].build()
    return build_multi_loop_law(
        cfg.law,
        loops=cfg.loops,
        plant=plant,
        tau_s=scenario.multi_loop_tau_s(node),
        context=scenario.multi_loop_context(node),
    )


def _edit_law(**kw):
    def edit(d):
        for node in UNITS:
            d["nodes"][node]["law"].update(kw)

    return edit


# -- the law is the analysed controller ----------------------------------------------------------
@pytest.mark.parametrize(
    ("edit", "delta1", "scheme"),
    [(None, 0.0, "model"), (_edit_law(scheme="zoh"), 0.0, "zoh"),
     (_edit_law(model_params={"dH1": -5.5e4}), 0.1, "model")],
    ids=["model", "zoh", "mismatch"],
)  # fmt: skip
def test_each_unit_runs_its_block_of_the_analysed_network(tmp_path, edit, delta1, scheme):
    """F is block diagonal by unit; each law's F, G, H are unit i's blocks of the QDCNetwork that
    agents/update_period/analysis.py builds (same linearization, same gains, same models)."""
    path = QDC if edit is None else write_variant(tmp_path, QDC, "v.yaml", edit)
    scenario = load_scenario(path)
    net = QDCNetwork(CASE.plant, CASE.gains, model=CASE.model(delta1), scheme=scheme)
    for i, node in enumerate(UNITS):
        law = _law(scenario, node)
        assert law.plant_units == CASE.plant
        block = slice(4 * i, 4 * i + 4)
        assert_allclose(law.local.F, net.F[block, block], rtol=1e-12, atol=1e-9)
        assert_array_equal(law.local.G, net.G[block, i : i + 1])
        assert_array_equal(law.local.H, net.H[2 * i : 2 * i + 2, block])
        other = np.delete(net.F[block], np.arange(4 * i, 4 * i + 4), axis=1)
        assert not other.any()  # nothing of the other unit enters unit i's controller
        assert_array_equal(law.x_s, CASE.x_s)


def test_propagation_equals_the_stacked_controller_integrated_independently():
    """Both laws driven with held samples at irregular instants and estimates exchanged at update
    instants, against z' = F z + G m of the stacked QDCNetwork integrated by solve_ivp (DOP853)
    with the reset z <- R z: estimates and moves agree to 1e-9 (relative to their size)."""
    scenario = load_scenario(QDC)
    laws = [_law(scenario, n) for n in UNITS]
    net = QDCNetwork(CASE.plant, CASE.gains)
    rng = np.random.default_rng(5)
    t_samples = np.cumsum(rng.uniform(0.0002, 0.002, 150))
    h = 0.0377
    updates = set(np.round(np.arange(h, t_samples[-1], h), 9))
    events = sorted({*np.round(t_samples, 9), *updates})
    y_s = np.array([CASE.x_s[0], CASE.x_s[2]])
    z = np.zeros(8)
    m = np.zeros(2)
    t_prev = 0.0
    checked = 0
    for t in events:
        z = solve_ivp(
            lambda _t, w, m=m: net.F @ w + net.G @ m, (t_prev, t), z, method="DOP853",
            rtol=1e-12, atol=1e-12,
        ).y[:, -1]  # fmt: skip
        t_prev = t
        if t in updates:
            sent = [law.transmit(t) for law in laws]
            laws[0].receive(t, "x2", sent[1])
            laws[1].receive(t, "x1", sent[0])
            z = net.R @ z
        if t in np.round(t_samples, 9):
            y = y_s + 3.0 * np.sin(np.array([7.0, 11.0]) * t) + rng.normal(0.0, 0.3, 2)
            u1 = laws[0].step(t, {"t1": y[0]}, {"t1": 0.0, "ca0": None})
            u2 = laws[1].step(t, {"t2": y[1]}, {"t2": 0.0, "ca03": None})
            u_ref = CASE.u_s + net.H @ z
            got = np.array([u1["t1"], u1["ca0"], u2["t2"], u2["ca03"]])
            assert_allclose(got, u_ref, rtol=1e-9, atol=1e-9 * np.abs(u_ref - CASE.u_s).max())
            m = y - y_s
            checked += 1
        for i, law in enumerate(laws):
            assert_allclose(law.z, z[4 * i : 4 * i + 4], rtol=1e-9, atol=1e-9 * np.abs(z).max())
    assert checked == 150 and len(updates) > 3


def _sampled(tau_s: float, end: float, monitor: float):
    def edit(d):
        d["end_time"] = end
        d["nodes"]["reactors"]["monitor_period"] = monitor
        for name in ("t1", "t2"):
            d["loops"][name]["tau_s"] = tau_s

    return edit


def test_direct_engine_converges_to_the_continuous_loop_at_first_order_in_tau_s(tmp_path):
    """The non-linear plant on the direct engine (samples every tau_s, moves held) against
    simulate_nonlinear (the same controllers in continuous time, RK4 at 1e-4 h), compared at
    the update instants over 0.2 h: the largest temperature difference halves with tau_s
    (measured 0.036 K at 2e-4 h, 0.017 K at 1e-4 h, for a 1 K initial deviation)."""
    h = 0.038806
    errors = []
    for tau_s in (2e-4, 1e-4):
        path = write_variant(tmp_path, QDC, f"s{tau_s}.yaml", _sampled(tau_s, 0.2, h))
        scenario = load_scenario(path)
        rec = simulate(scenario)
        x0 = np.array([scenario.nodes["reactors"].x0[s] for s in ("T1", "CA1", "T2", "CA2")])
        ref = simulate_nonlinear(
            CASE.plant_nl, CASE.x_s, CASE.u_s, QDCNetwork(CASE.plant, CASE.gains), h, x0, 0.2,
            max_step=1e-4,
        )  # fmt: skip
        plant = rec.plants["reactors"]
        assert plant.t == [to_ticks(k * h) for k in range(len(plant.t))]
        n = len(plant.t)  # the update instants k h up to 0.2 h (ref also has 0.2 h itself)
        assert_allclose(ref.t[:n], np.arange(n) * h, atol=1e-12) and n == 6
        errors.append(np.abs(np.array(plant.x) - ref.x[:n])[:, [0, 2]].max())
    assert errors[1] < 0.02
    assert 0.4 < errors[1] / errors[0] < 0.6, errors


def _deviation(rec) -> tuple[np.ndarray, np.ndarray]:
    plant = rec.plants["reactors"]
    t = np.array(plant.t) / 1e6
    return t, np.max(np.abs(np.array(plant.x) - CASE.x_s)[:, [0, 2]], axis=1)


def test_converges_at_0_9_h_max_and_leaves_3_k_at_1_2_h_max(tmp_path):
    """From 1 K on both temperatures, 2 h on the direct engine, h_max computed by the analysis
    for the law's own gains: at 0.9 h_max the temperatures are within 0.02 K of the steady state
    at the end (measured 0.0075 K); at 1.2 h_max they leave 3 K (measured 4.1 K at 2 h, still
    growing: 20 K at 5.5 h, README)."""
    law = _law(load_scenario(QDC), "unit1")
    h_max = find_h_max(build_lambda(law.plant_units, law.gains)).h_max
    assert h_max == pytest.approx(0.04312, abs=1e-5)
    finals = {}
    for factor in (0.9, 1.2):

        def edit(d: dict, factor: float = factor) -> None:
            d["end_time"] = 2.0
            for link in d["links"].values():
                link["period"] = round(factor * h_max, 6)

        rec = simulate(load_scenario(write_variant(tmp_path, QDC, f"h{factor}.yaml", edit)))
        t, dev = _deviation(rec)
        finals[factor] = (dev[-1], dev.max())
        links = summarize(rec)["network"]["links"]
        assert links["x1"]["delivered"] == links["x1"]["sent"] == int(2.0 / (factor * h_max)) + 1
    assert finals[0.9][0] < 0.02 and finals[0.9][1] < 2.0
    assert finals[1.2][0] > 3.0


def test_actuator_only_loops_record_their_moves():
    """ca0 / ca03 have no samples: one record entry per execution, with the move and no y; the
    summary gives them no step figures and no sensor path."""
    short = load_scenario(QDC).model_copy(update={"end_time": 0.01})
    rec = simulate(short)
    t1, ca0 = rec.loops["t1"], rec.loops["ca0"]
    assert ca0.t == t1.t and ca0.y == [None] * len(t1.t)
    assert all(u is not None for u in ca0.u) and ca0.u[0] == CASE.u_s[1]
    summary = summarize(rec)
    assert summary["loops"]["ca0"]["iae"] is None and summary["loops"]["ca0"]["steps"] == []
    assert summary["network"]["paths"]["ca0"]["sent"] == 0
    assert summary["network"]["paths"]["ca0"]["delay_mean"] is None


# -- run-time link periods (the controller node alone, no bus) -----------------------------------
def test_link_period_assigned_at_run_time_reschedules_the_next_transmission():
    scenario = load_scenario(QDC)
    node = ControllerBehaviour("unit1", controller_spec(scenario, "unit1"))
    h = to_ticks(0.038806)

    def fire(t):
        node.now = t
        node._fire_timers(t)
        out = [body for key, body in node._out if key == keys.link_tx("x1")]
        node._out.clear()
        return out

    assert len(fire(0)) == 1 and len(fire(h)) == 1
    node.now = h + 1000
    node._on_rates(None, Rates(mode="x", periods={}, closed={}, control_periods={},
                               proposal=None, link_periods={"x1": 5000}))  # fmt: skip
    assert node._timers[0].t == h + 5000  # one new period after the last transmission
    sent = fire(h + 5000)
    assert len(sent) == 1 and isinstance(sent[0], Estimate) and sent[0].t_sent == h + 5000
    for t in range(h + 10000, 2 * h, 5000):
        assert len(fire(t)) == 1
    assert not fire(2 * h)  # the old schedule's timer is void
    node.now = 2 * h
    node._on_rates(None, Rates(mode="x", periods={}, closed={}, control_periods={},
                               proposal=None, link_periods={"x1": 2000}))  # fmt: skip
    assert node._timers[0].t == 2 * h  # last + 2000 has passed: at once
    assert fire(2 * h) and not fire(h + 40000) and fire(2 * h + 2000)  # h + 40000: stale


# -- what the scenario refuses --------------------------------------------------------------------
def _loop(name, **kw):
    return lambda d: d["loops"][name].update(kw)


def _units(inputs0):
    def edit(d):
        d["nodes"]["unit1"]["law"]["units"] = [
            {"states": ["T1", "CA1"], "inputs": inputs0, "outputs": ["T1"]},
            {"states": ["T2", "CA2"], "inputs": ["Q2", "CA03"], "outputs": ["T2"]},
        ]

    return edit


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (_edit_law(observer_poles=[[-50, 25], [-50, -25]]),
         "nodes.unit1.controller.law.qdc.observer_poles: observer_poles[0][1] = 25.0 is not in "
         "the open left half-plane"),
        (_edit_law(observer_poles=[[-50, 0.0], [-50, -25]]), "observer_poles[0][1] = 0.0 is not"),
        (lambda d: (_units(["Q1"])(d), d["loops"]["ca0"].update(actuator="Q2")),
         "nodes.unit1.law.qdc: plant.B[0] has shape (2, 1): must be square because K_ij = "
         "-B_i^-1 A_ij must cancel the coupling"),
        (lambda d: (_units(["Q1", "Q2"])(d), d["loops"]["ca0"].update(actuator="Q2")),
         "nodes.unit1.law.qdc: plant.B[0] is singular: must be nonsingular because K_ij"),
        (lambda d: d["links"]["x1"].update(period=0.0),
         "links.x1.period: Input should be greater than 0"),
        (lambda d: d["links"]["x2"].update(period=-0.04),
         "links.x2.period: Input should be greater than 0"),
        (_loop("ca0", tau_s=0.001),
         "loops.ca0: tau_s: an actuator-only loop (sensor: null) samples nothing"),
        (_loop("ca0", actuator="Q2"),
         "nodes.unit1.law.qdc: loops: 'CA0' of unit 0 must be moved by exactly one"),
        (_edit_law(unit=2), "nodes.unit1.law.qdc: unit: 2, but the plant has 2 units"),
        (_edit_law(model_params={"dH9": 1.0}), "model_params.dH9: not a parameter of the plant"),
        (lambda d: d["links"]["x1"].update(to="unit1"),
         "links.x1.to: a link joins two different controllers"),
        (lambda d: d["links"]["x1"].update(network="unit2"),
         "links.x1.network: 'unit2' is not a network or gateway node"),
        (lambda d: d["links"]["x1"].update(source_node="s1"),
         "links.x1.source_node: only links over a gateway name WSN nodes"),
        (lambda d: d["links"].update(t1=d["links"]["x1"]), "links.t1: a loop has that name"),
        (lambda d: d["setpoints"].append({"t": 1.0, "loop": "ca0", "value": 4.1})
         or d["nodes"].update(operator={"kind": "operator"}),
         "setpoints[0].loop: 'ca0' is actuator-only"),
        (lambda d: d["loops"]["t1"].update(sensor=None) or d["loops"]["t1"].pop("tau_s"),
         "nodes.unit1.loops: every loop is actuator-only (sensor: null)"),
    ],
)  # fmt: skip
def test_bad_qdc_input_is_refused_naming_file_and_field(tmp_path, edit, expected):
    def full(d):
        d.setdefault("setpoints", [])
        edit(d)

    path = write_variant(tmp_path, QDC, "bad.yaml", full)
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    assert f"{path}: " in str(err.value) and expected in str(err.value), str(err.value)


def test_actuator_only_loop_of_a_single_loop_controller_is_refused(tmp_path):
    def edit(d):
        d["loops"]["level"]["sensor"] = None
        d["loops"]["level"].pop("tau_s")

    path = write_variant(tmp_path, SCENARIOS / "jcstr_benchmark.yaml", "bad.yaml", edit)
    with pytest.raises(ConfigError, match=r"loops\.level\.sensor: null \(an actuator-only loop\)"):
        load_scenario(path)


def test_links_need_laws_that_exchange_estimates(tmp_path):
    def edit(d):
        d["links"] = {"e": {"from": "mrac", "to": "mrac", "network": "network", "period": 0.1}}

    path = write_variant(tmp_path, SCENARIOS / "column_mrac.yaml", "bad.yaml", edit)
    with pytest.raises(ConfigError, match=r"links\.e\.from: the law of node 'mrac' \('mrac'\)"):
        load_scenario(path)


def test_wsn_scenario_routes_the_estimates_over_the_relay():
    """cstr_recycle_qdc_wsn.yaml: the links take u1 - r - u2 (2 hops), the samples the wired
    fieldbus; per-link delivered delays are reported with the other paths."""
    scenario = load_scenario(SCENARIOS / "cstr_recycle_qdc_wsn.yaml")
    rec = simulate(scenario.model_copy(update={"end_time": 0.2}))
    summary = summarize(rec)
    route = summary["network"]["configurations"][0]["paths"]["x1.link"]
    assert route["route"] == ["u1", "r", "u2"] and route["hops"] == 2
    links = summary["network"]["links"]
    assert links["x1"]["sent"] == 6 and links["x1"]["delay_mean"] > 0.0004
    assert summary["network"]["paths"]["t1"]["hops"] == 0
