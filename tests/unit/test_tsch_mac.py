"""The TSCH MAC and its scheduler against closed forms (issue 15, items 1, 2 and 4).

* a line of n hops, one dedicated cell per hop in route order, no loss: the delay is the cells'
  span exactly;
* per-attempt PDR p, one retry cell per hop (and one retry allowed): delivered ratio
  ``(1 - (1-p)^2)^n`` and mean delay ``(2n - 1 + (1-p)/(2-p))`` slots, within sampling error;
* k saturated contenders in one shared cell: throughput of the TSCH CSMA-CA backoff equals the
  stationary probability of exactly one transmitter, computed exactly from the Markov chain of
  the nodes' (BE, counter) states;
* two flows through one cell per slotframe faster than it: queue-full drops as the arithmetic
  says;
* energy: a node's slots of each kind, and its charge, equal the sum over its cells.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from gateway.tsch.energy import RADIOS, charge_uC
from gateway.tsch.mac import TschMac
from gateway.tsch.schedule import Cell, Flow, Schedule, build_schedule, check_cells

SLOT = 10_000  # ticks (10 ms at 1 s per time unit)
HOPPING = (15, 20, 25, 26)


def _mac(schedule, pdr=1.0, seed=1, **kw):
    return TschMac(
        schedule,
        slot_ticks=SLOT,
        hopping=HOPPING,
        pdr=(lambda a, b, ch, t: pdr) if not callable(pdr) else pdr,
        rng=np.random.default_rng(seed),
        **kw,
    )


def _line(n):
    return tuple(f"n{i}" for i in range(n + 1))


@pytest.mark.parametrize("n", [1, 3, 5])
def test_a_line_with_one_cell_per_hop_in_route_order_takes_the_cells_span(n):
    route = _line(n)
    sched = build_schedule([Flow("f", route, 20)], 20, 4, retry_cells=0)
    assert sched.feasible
    offsets = [c.slot for c in sorted(sched.cells)]
    assert offsets == list(range(n))  # in route order, one after the other
    mac = _mac(sched)
    outcomes = []
    for k in range(5):
        t0 = k * 20 * SLOT  # the start of the first cell's slot
        assert mac.submit(k, route, t0) is None
        outcomes += mac.advance(t0 + 20 * SLOT)
    assert [o.delivered for o in outcomes] == [True] * 5
    for k, o in enumerate(outcomes):
        span = (offsets[-1] - offsets[0] + 1) * SLOT
        assert o.t - k * 20 * SLOT == span


@pytest.mark.parametrize(("n", "p"), [(1, 0.7), (3, 0.8), (4, 0.55)])
def test_retry_cells_give_the_closed_form_ratio_and_delay(n, p):
    """One retry cell per hop right after the hop's cell, one retry allowed: a hop delivers with
    q = 1 - (1-p)^2; the packet leaves hop i at slot 2i or 2i+1 and the next hop's cell is at
    2(i+1), so only the last hop's attempt shows in the delay: given delivery it ends
    2(n-1) + 1 + k slots after the first cell starts, k = 1 with probability
    p(1-p) / q = (1-p)/(2-p)."""
    route = _line(n)
    length = 2 * n + 2
    sched = build_schedule([Flow("f", route, length)], length, 4, retry_cells=1)
    assert [c.slot for c in sorted(sched.cells)] == list(range(2 * n))
    mac = _mac(sched, pdr=p, seed=7, max_retries=1)
    outcomes = []
    trials = 6000
    for k in range(trials):
        t0 = k * length * SLOT
        mac.submit(k, route, t0)
        outcomes += [(o, t0) for o in mac.advance(t0 + length * SLOT)]
    assert len(outcomes) == trials  # every packet delivered or dropped within its slotframe
    delivered = [o.t - t0 for o, t0 in outcomes if o.delivered]
    q = 1 - (1 - p) ** 2
    ratio = q**n
    sigma = np.sqrt(ratio * (1 - ratio) / trials)
    assert abs(len(delivered) / trials - ratio) < 4 * sigma
    mean = (2 * n - 1 + (1 - p) / (2 - p)) * SLOT
    k = (1 - p) / (2 - p)
    sd = np.sqrt(k * (1 - k)) * SLOT / np.sqrt(len(delivered))
    assert abs(np.mean(delivered) - mean) < 4 * sd + 1e-9
    reasons = {o.reason for o, _ in outcomes if not o.delivered}
    assert reasons <= {"retries_exhausted"}


def _exact_shared_throughput(k: int, min_be: int, max_be: int) -> float:
    """Stationary P(exactly one of k saturated nodes transmits) in a shared cell, from the joint
    Markov chain of the nodes' (BE, counter) (PDR 1: a lone transmitter succeeds)."""
    states = [(min_be, 0)] + [(be, c) for be in range(min_be + 1, max_be + 1) for c in range(2**be)]
    index = {s: i for i, s in enumerate(states)}
    joint = list(itertools.product(range(len(states)), repeat=k))
    jindex = {j: i for i, j in enumerate(joint)}
    P = np.zeros((len(joint), len(joint)))
    single = np.zeros(len(joint))
    for j, js in enumerate(joint):
        nodes = [states[i] for i in js]
        senders = [i for i, (_, c) in enumerate(nodes) if c == 0]
        single[j] = len(senders) == 1
        options = []  # per node: list of (next state index, probability)
        for be, c in nodes:
            if c > 0:
                options.append([(index[(be, c - 1)], 1.0)])
            elif len(senders) == 1:
                options.append([(index[(min_be, 0)], 1.0)])
            else:
                nb = min(be + 1, max_be)
                options.append([(index[(nb, x)], 1.0 / 2**nb) for x in range(2**nb)])
        for combo in itertools.product(*options):
            target = jindex[tuple(s for s, _ in combo)]
            P[j, target] += float(np.prod([w for _, w in combo]))
    w, v = np.linalg.eig(P.T)
    pi = np.real(v[:, np.argmin(np.abs(w - 1))])
    pi /= pi.sum()
    return float(pi @ single)


@pytest.mark.parametrize("k", [2, 3])
def test_a_shared_cell_with_k_contenders_matches_the_backoffs_throughput(k):
    min_be, max_be = 1, 3
    cells = [Cell(0, 0, f"s{i}", "g", shared=True) for i in range(k)]
    sched = Schedule(1, 1, cells=cells)
    check_cells(cells, 1, 1)
    mac = _mac(
        sched, seed=11, min_be=min_be, max_be=max_be, max_retries=10**9, queue_capacity=10**6
    )
    frames = 30_000
    for i in range(k):
        for m in range(frames):
            mac.submit((i, m), (f"s{i}", "g"), 0)
    outcomes = mac.advance(frames * SLOT)
    throughput = sum(o.delivered for o in outcomes) / frames
    expected = _exact_shared_throughput(k, min_be, max_be)
    assert abs(throughput - expected) < 0.02, (throughput, expected)
    assert not any(o.reason for o in outcomes)


def test_two_flows_through_one_cell_per_slotframe_drop_as_the_arithmetic_says():
    """One cell per slotframe of 10 slots from s to g; two flows at s, each a packet every 4
    slots: 0.5 packets per slot offered, 0.1 carried. With a queue of 5, every packet that
    finds 5 queued is dropped: drops = offered - carried - queued at the end."""
    length, capacity = 10, 5
    sched = Schedule(length, 1, cells=[Cell(0, 0, "s", "g")])
    mac = _mac(sched, queue_capacity=capacity)
    slots = 2000
    drops = 0
    outcomes = []
    for asn in range(slots):
        for flow in ("a", "b"):
            if asn % 4 == 0:
                o = mac.submit((flow, asn), ("s", "g"), asn * SLOT)
                drops += o is not None
        outcomes += mac.advance((asn + 1) * SLOT)
    offered = 2 * (slots // 4)
    carried = slots // length
    assert sum(o.delivered for o in outcomes) == carried
    assert drops == mac.drops["queue_full"] == offered - carried - mac.pending()
    assert mac.pending() == capacity
    assert drops / offered == pytest.approx(1 - (1 / length) / (2 / 4), abs=0.01)


def test_the_charge_per_slotframe_is_the_sum_over_the_cells():
    """Node a: a TX cell to b (used by one packet each frame, acknowledged), an RX cell from c
    (c never sends: idle listening); the rest of its slots sleep. b: one RX cell, used."""
    length, frames = 8, 50
    cells = [Cell(1, 0, "a", "b"), Cell(5, 1, "c", "a")]
    mac = _mac(Schedule(length, 2, cells=cells))
    for f in range(frames):
        mac.submit(f, ("a", "b"), f * length * SLOT)
        mac.advance((f + 1) * length * SLOT)
    counts = mac.slot_counts(["a", "b", "c"], frames * length * SLOT)
    assert counts["a"] == {"tx_ack": frames, "idle": frames, "sleep": frames * (length - 2)} | {
        "tx_noack": 0,
        "rx_ack": 0,
    }
    assert counts["b"]["rx_ack"] == frames and counts["b"]["sleep"] == frames * (length - 1)
    radio = RADIOS["openmote_cc2538"]
    per_frame = 54.5 + 6.4 + (length - 2) * 1.3e-6 * 0.01 * 1e6
    assert charge_uC(radio, counts["a"], 0.01) == pytest.approx(frames * per_frame, rel=1e-12)


def test_the_channel_hops_by_asn_and_offset():
    seen = []

    def pdr(a, b, channel, t):
        seen.append((t // SLOT, channel))
        return 1.0

    length = 3
    mac = _mac(Schedule(length, 2, cells=[Cell(2, 1, "a", "b")]), pdr=pdr)
    for f in range(6):
        mac.submit(f, ("a", "b"), f * length * SLOT)
        mac.advance((f + 1) * length * SLOT)
    assert seen == [(asn, HOPPING[(asn + 1) % len(HOPPING)]) for asn in range(2, 18, 3)]


def test_the_scheduler_says_which_link_lacks_how_many_cells():
    """Three flows of a packet every 2 slots through one relay to the gateway, 6 slots: the
    relay's link to the gateway needs 9 cells, and the relay can be in one cell per slot."""
    flows = [Flow(f"f{i}", (f"s{i}", "r", "g"), 2) for i in range(3)]
    sched = build_schedule(flows, 6, 4, retry_cells=0)
    assert not sched.feasible
    lack = sched.lacking
    assert ("r", "g") in lack and lack[("r", "g")] > 0
    assert "link r->g lacks" in sched.describe_lack()
    check_cells(sched.cells, 6, 4)  # what was placed runs
    # at a period of 12 slots the same flows fit, and take fewer cells
    slow = build_schedule([Flow(f.name, f.route, 12) for f in flows], 6, 4, retry_cells=0)
    assert slow.feasible
    assert sum(slow.cells_per_frame().values()) < len(sched.cells)


@pytest.mark.parametrize(
    ("cells", "message"),
    [
        ([Cell(6, 0, "a", "b")], "slot: 6 is outside the slotframe"),
        ([Cell(0, 4, "a", "b")], "channel offset 4 is outside 0..3"),
        ([Cell(0, 0, "a", "b"), Cell(0, 1, "a", "c")], "node 'a' is in two cells of slot 0"),
        ([Cell(0, 0, "a", "b"), Cell(0, 0, "c", "d")], "channel offset 0 of slot 0 is already"),
        ([Cell(0, 0, "a", "g", shared=True), Cell(0, 0, "b", "g", shared=True)], None),
    ],
)
def test_a_written_schedule_is_checked(cells, message):
    if message is None:
        check_cells(cells, 6, 4)
        return
    with pytest.raises(ValueError, match=message):
        check_cells(cells, 6, 4)
