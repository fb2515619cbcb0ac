"""WSN topology: routing metrics, reconfiguration events, alternatives and input validation."""

from __future__ import annotations

import itertools

import pytest
from pydantic import ValidationError

from gateway.delay_models import ConstantDelay, TDMADelay, UniformDelay
from gateway.topology import (
    Alternatives,
    DelayModelChanged,
    LinkDegraded,
    LinkSpec,
    NodeDown,
    NodeMoved,
    NodeUp,
    RelayAdded,
    Topology,
    TopologyConfig,
    parse_event,
)


def topo(nodes: dict[str, str], links, paths=None, **kw) -> Topology:
    return Topology(
        TopologyConfig(
            nodes={n: {"kind": k} for n, k in nodes.items()},
            links=[
                {"a": a, "b": b, "prr": p, **(extra[0] if extra else {})}
                for a, b, p, *extra in links
            ],
            paths={k: {"src": s, "dst": d} for k, (s, d) in (paths or {}).items()},
            **kw,
        )
    )


def relays(*names: str) -> dict[str, str]:
    return {n: "relay" for n in names}


# ----------------------------------------------------------------------------- metrics


def hop_vs_etx(metric: str, retry_limit: int = 3) -> Topology:
    # s-a-g: 2 hops at PRR 0.5 (ETX 4); s-b-c-g: 3 hops at PRR 1 (ETX 3)
    return topo(
        {"s": "sensor", "g": "gateway", **relays("a", "b", "c")},
        [("s", "a", 0.5), ("a", "g", 0.5), ("s", "b", 1.0), ("b", "c", 1.0), ("c", "g", 1.0)],
        {"up": ("s", "g")},
        metric=metric,
        retry_limit=retry_limit,
    )


def test_hop_count_and_etx_choose_different_routes():
    assert hop_vs_etx("hops").routes()["up"].nodes == ("s", "a", "g")
    assert hop_vs_etx("etx").routes()["up"].nodes == ("s", "b", "c", "g")
    # with the retry limit: 2 x (1 - 0.5^4) / 0.5 = 3.75 > 3, still the 3-hop route ...
    assert hop_vs_etx("etx_limited", 3).routes()["up"].nodes == ("s", "b", "c", "g")
    # ... but without retries every link costs one attempt: the 2-hop route
    assert hop_vs_etx("etx_limited", 0).routes()["up"].nodes == ("s", "a", "g")
    t = hop_vs_etx("hops")
    assert t.route("s", "g", "etx").n_hops == 3
    assert t.routes()["up"].n_hops == 2
    t.metric = "etx"  # changing the metric recomputes the routes
    assert t.routes()["up"].n_hops == 3


def test_equal_hop_counts_broken_by_etx():
    t = topo(
        {"s": "sensor", "g": "gateway", **relays("a", "b")},
        [("s", "a", 0.6), ("a", "g", 0.6), ("s", "b", 0.9), ("b", "g", 0.9)],
        {"up": ("s", "g")},
    )
    assert t.routes()["up"].nodes == ("s", "b", "g")


def test_route_carries_link_parameters_and_reverses():
    t = topo(
        {"s": "sensor", "g": "gateway", "r": "relay"},
        [
            ("s", "r", 0.8, {"retry_limit": 1, "delay": {"type": "constant", "delay": 0.02}}),
            ("r", "g", 0.9),
        ],
        retry_limit=4,
        delay={"type": "uniform", "low": 0.01, "high": 0.02},
    )
    r = t.route("s", "g")
    h1, h2 = r.hops
    assert (h1.prr, h1.retry_limit, h1.delay) == (0.8, 1, ConstantDelay(delay=0.02))
    assert (h2.prr, h2.retry_limit, h2.delay) == (0.9, 4, UniformDelay(low=0.01, high=0.02))
    back = r.reversed()
    assert back.nodes == ("g", "r", "s") and back.hops[1].prr == 0.8
    assert r.delivery_probability == pytest.approx((1 - 0.2**2) * (1 - 0.1**5))


# ----------------------------------------------------------------------------- events


def two_routes() -> Topology:
    # s-r1-g (2 hops) and s-r2-r3-g (3 hops)
    return topo(
        {"s": "sensor", "g": "gateway", **relays("r1", "r2", "r3")},
        [("s", "r1", 0.9), ("r1", "g", 0.9), ("s", "r2", 0.9), ("r2", "r3", 0.9), ("r3", "g", 0.9)],
        {"up": ("s", "g"), "down": ("g", "s")},
    )


def test_node_down_reroutes_then_path_down_then_back_up():
    t = two_routes()
    assert t.routes()["up"].nodes == ("s", "r1", "g")
    assert t.routes()["down"].nodes == ("g", "r1", "s")
    rc = t.apply(NodeDown(node="r1"))
    assert rc.routes["up"].nodes == ("s", "r2", "r3", "g")
    assert rc.changed == ("down", "up") and rc.down == ()
    rc = t.apply(NodeDown(node="r3"))
    assert rc.routes["up"] is None and set(rc.down) == {"up", "down"}
    rc = t.apply(NodeUp(node="r1"))
    assert rc.routes["up"].n_hops == 2 and rc.down == ()
    assert t.version == 3
    # the source itself down: the path is down
    assert t.apply(NodeDown(node="s")).routes["up"] is None


def test_relay_added_gives_shorter_route():
    t = topo(
        {"s": "sensor", "g": "gateway", **relays("r1", "r2", "r3")},
        [("s", "r1", 1.0), ("r1", "r2", 1.0), ("r2", "r3", 1.0), ("r3", "g", 1.0)],
        {"up": ("s", "g")},
    )
    assert t.routes()["up"].n_hops == 4
    rc = t.apply(
        RelayAdded(
            node="x",
            position=(5.0, 0.0),
            links=[LinkSpec(a="s", b="x", prr=0.95), LinkSpec(a="x", b="g", prr=0.95)],
        )
    )
    assert rc.routes["up"].nodes == ("s", "x", "g") and rc.changed == ("up",)
    assert t.nodes["x"].kind == "relay" and t.nodes["x"].position == (5.0, 0.0)


def test_link_degraded_reroutes_by_etx():
    t = two_routes()
    assert t.routes()["up"].n_hops == 2
    t.metric = "etx"  # the cached routes are recomputed
    assert t.routes()["up"].n_hops == 2
    with pytest.raises(ValueError, match="metric"):
        t.metric = "delay"
    rc = t.apply(LinkDegraded(a="g", b="r1", prr=0.3))  # either order of the ends
    assert rc.routes["up"].nodes == ("s", "r2", "r3", "g")
    assert t.link("r1", "g").prr == 0.3


def test_node_moved_replaces_its_links():
    t = two_routes()
    rc = t.apply(NodeMoved(node="s", position=(1.0, 2.0), links=[LinkSpec(a="r3", b="s", prr=0.8)]))
    assert rc.routes["up"].nodes == ("s", "r3", "g")
    with pytest.raises(ValueError, match="no link"):
        t.link("s", "r1")
    assert t.nodes["s"].position == (1.0, 2.0)


def test_delay_model_changed_network_wide_and_per_link():
    t = two_routes()
    t.apply(DelayModelChanged(link=("s", "r1"), delay=ConstantDelay(delay=0.05)))
    r = t.routes()["up"]
    assert r.hops[0].delay == ConstantDelay(delay=0.05)
    assert r.hops[1].delay == ConstantDelay(delay=0.01)  # the default
    tdma = TDMADelay(slot=0.001, frame_slots=8)
    t.apply(DelayModelChanged(delay=tdma))
    assert all(h.delay == tdma for h in t.routes()["up"].hops)
    assert t.config.delay == tdma


def test_events_from_mappings():
    t = two_routes()
    assert t.apply({"type": "node_down", "node": "r1"}).routes["up"].n_hops == 3
    ev = parse_event({"type": "link_degraded", "a": "s", "b": "r2", "prr": 0.5})
    assert isinstance(ev, LinkDegraded)
    with pytest.raises(ValidationError, match="prr"):
        parse_event({"type": "link_degraded", "a": "s", "b": "r2", "prr": 1.5})


@pytest.mark.parametrize(
    ("event", "match"),
    [
        (NodeDown(node="zz"), "node: unknown node 'zz'"),
        (LinkDegraded(a="s", b="g", prr=0.5), "no link between 's' and 'g'"),
        (RelayAdded(node="r1", links=[]), "exists already"),
        (RelayAdded(node="x", links=[LinkSpec(a="s", b="r3", prr=1.0)]), r"links\[0\]: must have"),
        (RelayAdded(node="x", links=[LinkSpec(a="x", b="zz", prr=1.0)]), r"links\[0\]\.b"),
        (RelayAdded(node="x", links=[LinkSpec(a="x", b="s", prr=1.0)] * 2), "duplicate"),
        (NodeMoved(node="s", links=[LinkSpec(a="s", b="q", prr=1.0)]), r"links\[0\]\.b"),
        (DelayModelChanged(link=("s", "g"), delay=ConstantDelay(delay=0.1)), "no link"),
    ],
)
def test_bad_events_refused_and_topology_unchanged(event, match):
    t = two_routes()
    before = (t.config, t.routes(), t.version)
    with pytest.raises(ValueError, match=match):
        t.apply(event)
    assert (t.config, t.routes(), t.version) == before


def test_tdma_slots_assigned_apart_on_shared_nodes():
    t = topo(
        {"s": "sensor", "g": "gateway", **relays("r1", "r2")},
        [("s", "r1", 1.0), ("r1", "r2", 1.0), ("r2", "g", 1.0, {"slot": 3})],
        {"up": ("s", "g")},
        delay={"type": "tdma", "slot": 0.001, "frame_slots": 4},
    )
    assert [h.slot for h in t.routes()["up"].hops] == [0, 1, 3]
    t.apply(RelayAdded(node="x", links=[LinkSpec(a="r1", b="x", prr=1.0)]))
    assert t.hop("r1", "x").slot == 2  # 0 and 1 are used at r1
    t.apply(RelayAdded(node="y", links=[LinkSpec(a="y", b="r1", prr=1.0)]))
    assert t.hop("r1", "y").slot == 3  # 0, 1, 2 used at r1 (3 is used only at r2, not adjacent)
    # an assigned slot is used modulo its model's frame
    t.apply(DelayModelChanged(link=("r1", "y"), delay=TDMADelay(slot=0.001, frame_slots=2)))
    assert t.hop("y", "r1").slot == 1
    # an explicit slot must fit the frame: a shorter frame is refused, naming the link
    with pytest.raises(ValueError, match=r"links\[2\]\.slot: must be < frame_slots \(3\)"):
        t.apply(DelayModelChanged(delay=TDMADelay(slot=0.001, frame_slots=3)))


# ----------------------------------------------------------------------------- k shortest


def test_k_shortest_matches_enumeration():
    links = [
        ("s", "a", 0.9, 0.011), ("s", "b", 1.0, 0.023), ("a", "b", 0.8, 0.007),
        ("a", "c", 1.0, 0.031), ("b", "c", 0.7, 0.013), ("b", "d", 1.0, 0.029),
        ("c", "d", 0.95, 0.005), ("c", "g", 1.0, 0.041), ("d", "g", 0.85, 0.017),
        ("a", "d", 1.0, 0.053),
    ]  # fmt: skip
    t = topo(
        {"s": "sensor", "g": "gateway", **relays("a", "b", "c", "d")},
        [(a, b, p, {"delay": {"type": "constant", "delay": d}}) for a, b, p, d in links],
        retry_limit=2,
    )
    adj: dict[str, list[str]] = {}
    for a, b, *_ in links:
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)

    def simple_paths(path):
        if path[-1] == "g":
            yield path
            return
        for n in adj[path[-1]]:
            if n not in path:
                yield from simple_paths(path + [n])

    def cost(path):
        return sum(t.hop(a, b).mean_delay for a, b in itertools.pairwise(path))

    every = sorted(simple_paths(["s"]), key=cost)
    got = t.k_shortest("s", "g", 6)
    assert [r.nodes for r in got] == [tuple(p) for p in every[:6]]
    assert len(t.k_shortest("s", "g", 100)) == len(every)
    # the best by mean delay is the delay-metric shortest path
    assert t.route("s", "g", "delay").nodes == tuple(every[0])


# ----------------------------------------------------------------------------- alternatives


def alternatives_case() -> Topology:
    # three disjoint routes s -> g, all PRR 1: energy grows as delay falls
    #   B: s-b-g        2 hops x 0.02  = 0.04   (ETX 2: the proposal)
    #   A: s-a1-a2-g    3 hops x 0.01  = 0.03   (ETX 3)
    #   C: s-c1-..-g    4 hops x 0.005 = 0.02   (ETX 4)
    def c(d):
        return {"delay": {"type": "constant", "delay": d}}

    return topo(
        {"s": "sensor", "t": "sensor", "g": "gateway", **relays("b", "a1", "a2", "c1", "c2", "c3")},
        [
            ("s", "b", 1.0, c(0.02)),
            ("b", "g", 1.0, c(0.02)),
            ("s", "a1", 1.0, c(0.01)),
            ("a1", "a2", 1.0, c(0.01)),
            ("a2", "g", 1.0, c(0.01)),
            ("s", "c1", 1.0, c(0.005)),
            ("c1", "c2", 1.0, c(0.005)),
            ("c2", "c3", 1.0, c(0.005)),
            ("c3", "g", 1.0, c(0.005)),
            ("t", "g", 1.0, c(0.01)),
        ],  # fmt: skip
        {"level": ("s", "g"), "temp": ("t", "g")},
        metric="etx",
    )


def test_alternatives_lower_delay_at_higher_energy_until_none_left():
    t = alternatives_case()
    alts = t.alternatives()
    assert alts.current["level"].nodes == ("s", "b", "g") and alts.count == 1
    nxt = alts.next(["level"])
    assert nxt["level"].nodes == ("s", "a1", "a2", "g")
    assert nxt["temp"] == alts.current["temp"] == t.routes()["temp"]
    assert alts.next(["level"])["level"].nodes == ("s", "c1", "c2", "c3", "g")
    assert alts.count == 3
    assert alts.next(["level"]) is None
    assert alts.exhausted and alts.stuck == ("level",)


def test_alternatives_stuck_path_reported_while_others_improve():
    t = alternatives_case()
    alts = Alternatives(t)
    nxt = alts.next()  # every path rejected: temp (one link) cannot improve, level can
    assert nxt is not None and alts.stuck == ("temp",)
    assert alts.next(["temp"]) is None
    with pytest.raises(ValueError, match="unknown path"):
        alts.next(["nope"])


def test_alternatives_follow_the_current_state():
    t = alternatives_case()
    t.apply(NodeDown(node="a2"))
    alts = t.alternatives()
    assert alts.next(["level"])["level"].n_hops == 4  # A is gone
    t.apply(NodeDown(node="g"))
    alts = t.alternatives()
    assert alts.current == {"level": None, "temp": None}
    assert alts.next() is None


# ----------------------------------------------------------------------------- validation


def base_config(**edits):
    data = {
        "nodes": {"s": {"kind": "sensor"}, "g": {"kind": "gateway"}},
        "links": [{"a": "s", "b": "g", "prr": 0.9}],
    }
    data.update(edits)
    return data


@pytest.mark.parametrize(
    ("edits", "match"),
    [
        ({"links": [{"a": "s", "b": "zz", "prr": 0.9}]}, r"links\[0\]\.b: unknown node 'zz'"),
        ({"links": [{"a": "s", "b": "g", "prr": 0.0}]}, r"links\.0\.prr"),
        ({"links": [{"a": "s", "b": "g", "prr": 1.5}]}, r"links\.0\.prr"),
        ({"links": [{"a": "s", "b": "s", "prr": 1.0}]}, r"links\[0\]: a link joins"),
        (
            {"links": [{"a": "s", "b": "g", "prr": 1.0}, {"a": "g", "b": "s", "prr": 1.0}]},
            r"links\[1\]: duplicate",
        ),
        ({"delay": {"type": "constant", "delay": -0.01}}, r"delay\.constant\.delay"),
        (
            {
                "links": [
                    {
                        "a": "s",
                        "b": "g",
                        "prr": 1.0,
                        "delay": {"type": "uniform", "low": -1.0, "high": 1.0},
                    }
                ]
            },
            r"links\.0\.delay\.uniform\.low",
        ),
        ({"retry_limit": -1}, "retry_limit"),
        (
            {"links": [{"a": "s", "b": "g", "prr": 1.0, "retry_limit": -2}]},
            r"links\.0\.retry_limit",
        ),
        ({"nodes": {"s": {"kind": "sensor"}}, "links": []}, "gateway"),
        ({"nodes": {"s": {"kind": "antenna"}, "g": {"kind": "gateway"}}}, r"nodes\.s\.kind"),
        (
            {
                "delay": {"type": "tdma", "slot": 0.001, "frame_slots": 4},
                "links": [{"a": "s", "b": "g", "prr": 1.0, "slot": 4}],
            },
            r"links\[0\]\.slot",
        ),
        ({"paths": {"p": {"src": "s", "dst": "x"}}}, r"paths\.p\.dst"),
        ({"metric": "shortest"}, "metric"),
    ],  # fmt: skip
)
def test_bad_config_refused_naming_field(edits, match):
    with pytest.raises(ValidationError, match=match):
        TopologyConfig.model_validate(base_config(**edits))


def test_route_queries_check_names():
    t = Topology.from_dict(base_config())
    assert t.route("s", "g").n_hops == 1
    with pytest.raises(ValueError, match="src: unknown node"):
        t.route("x", "g")
    with pytest.raises(ValueError, match=r"paths\.p\.dst"):
        t.add_path("p", "s", "nowhere")
    t.add_path("p", "g", "s")
    assert t.routes()["p"].nodes == ("g", "s")
    assert Topology(t.config).routes() == t.routes()  # the snapshot rebuilds the same network
