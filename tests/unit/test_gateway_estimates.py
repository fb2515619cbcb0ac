"""The paper's three path-delay estimates against delivered delays and exact means.

Criterion ("within the model's spread"): for every delay model on a 3-hop path with PRR 0.9 and
two retries, each estimate differs from the mean delivered delay by less than the standard
deviation of the delivered delays; in addition the time-stamp and ping estimates lie within four
standard errors of the exact mean, and the hop-count estimate equals the exact mean for models
whose hops are independent. TDMA with a schedule ordered along the route is the documented
exception: ping and hop count then overestimate by one frame.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gateway.delay_models import ConstantDelay, ExponentialDelay, TDMADelay, UniformDelay
from gateway.estimates import TimestampEstimator, hops_estimate, ping_estimate
from gateway.paths import Hop, Route, deliver

TICKS = 1_000_000
HOPS, PRR, RETRIES = 3, 0.9, 2
# E[attempts | delivered] for PRR 0.9, two retries: (0.9 + 2 x 0.09 + 3 x 0.009) / 0.999
EA = (0.9 + 2 * 0.09 + 3 * 0.009) / 0.999


def line(model, slots=(0, 0, 0), prr=PRR, retries=RETRIES) -> Route:
    names = ["s", "r1", "r2", "g"]
    return Route(
        tuple(Hop(names[i], names[i + 1], prr, model, retries, slots[i]) for i in range(3))
    )


def tdma_exact_mean(slots, slot_t=2000, n_slots=10):
    """Mean delivered delay (units) over every ready phase, plus one frame per retry."""
    frame_t = slot_t * n_slots
    t = np.arange(frame_t, dtype=np.int64)
    t0 = t.copy()
    for s in slots:
        k = -((s * slot_t - t) // frame_t)
        t = s * slot_t + k * frame_t + slot_t
    return (np.mean(t - t0) + HOPS * (EA - 1) * frame_t) / TICKS


TDMA = TDMADelay(slot=0.002, frame_slots=10)
CASES = {
    "constant": (line(ConstantDelay(delay=0.01)), HOPS * 0.01 * EA),
    "uniform": (line(UniformDelay(low=0.005, high=0.015)), HOPS * 0.01 * EA),
    "exponential": (line(ExponentialDelay(base=0.004, mean=0.006)), HOPS * 0.01 * EA),
    "tdma": (line(TDMA, slots=(5, 2, 7)), tdma_exact_mean((5, 2, 7))),
}


def delivered(route: Route, n: int = 2000, seed: int = 0) -> tuple[TimestampEstimator, list]:
    rng = np.random.default_rng(seed)
    ready = np.sort(np.random.default_rng(seed + 100).integers(0, 10**9, size=n))
    est = TimestampEstimator()
    d = []
    for t0 in ready:
        t, _, _ = deliver(route, int(t0), rng)
        if t is not None:
            est.add(int(t0), t)
            d.append((t - int(t0)) / TICKS)
    return est, d


@pytest.mark.parametrize("name", list(CASES))
def test_three_estimates_agree_with_delivered_delays(name):
    route, exact_mean = CASES[name]
    ts, d = delivered(route)
    mean, sigma, n = np.mean(d), np.std(d, ddof=1), len(d)
    assert sigma > 0  # retries spread even the constant model
    # 1. time stamps: the mean of the delivered delays themselves
    e1 = ts.estimate()
    assert (e1.method, e1.count) == ("timestamps", n)
    assert e1.tau_d == pytest.approx(mean, rel=1e-12) and e1.std == pytest.approx(sigma)
    # 2. ping: k = 400 probes, irregular phases
    e2 = ping_estimate(route, 12_345, np.random.default_rng(1), probes=400, interval=7_777)
    assert 380 <= e2.count <= 400
    # 3. hop count x per-hop mean (retries included)
    e3 = hops_estimate(route)
    assert e3.count == HOPS
    for e in (e1, e2, e3):
        assert abs(e.tau_d - mean) < sigma, (e.method, e.tau_d, mean, sigma)
    assert abs(e1.tau_d - exact_mean) < 4 * sigma / math.sqrt(n)
    assert abs(e2.tau_d - exact_mean) < 4 * e2.std / math.sqrt(e2.count)
    if name != "tdma":
        assert e3.tau_d == pytest.approx(exact_mean, rel=1e-12)


def test_tdma_schedule_along_the_route_defeats_ping_and_hop_count():
    # slots 0, 1, 2 in route order: one wait for the first slot, then straight through
    route = line(TDMA, slots=(0, 1, 2))
    ts, d = delivered(route)
    exact = tdma_exact_mean((0, 1, 2))
    e1 = ts.estimate()
    assert abs(e1.tau_d - exact) < 4 * np.std(d) / math.sqrt(len(d))
    frame = TDMA.frame
    # hop count assumes a random wait (half a frame) at every hop: (hops - 1) frame / 2 too much
    assert hops_estimate(route).tau_d - exact == pytest.approx((HOPS - 1) * frame / 2, abs=1e-5)
    # ping: the way back waits most of a frame at each hop, so RTT / 2 is about a frame too long
    e2 = ping_estimate(route, 0, np.random.default_rng(2), probes=400, interval=7_777)
    assert e2.tau_d - exact == pytest.approx(frame, abs=0.1 * frame)


def test_ping_with_every_probe_lost():
    route = line(ConstantDelay(delay=0.01), prr=1e-6, retries=0)
    e = ping_estimate(route, 0, np.random.default_rng(0), probes=5)
    assert e.count == 0 and math.isnan(e.tau_d)


def test_ping_on_lossless_constant_path_is_exact():
    route = line(ConstantDelay(delay=0.01), prr=1.0)
    e = ping_estimate(route, 0, np.random.default_rng(0), probes=3, interval=1000)
    assert (e.tau_d, e.count, e.std) == (pytest.approx(0.03), 3, 0.0)


def test_timestamp_window_reset_and_errors():
    est = TimestampEstimator(window=3)
    assert est.estimate().count == 0 and math.isnan(est.estimate().tau_d)
    for k, delay in enumerate([10, 20, 30, 40, 50]):
        est.add(1000 * k, 1000 * k + delay * 1000)
    e = est.estimate()
    assert (e.count, e.tau_d) == (3, pytest.approx(0.04))
    est.reset()
    assert est.count == 0
    with pytest.raises(ValueError, match="before sampled"):
        est.add(10, 5)
    with pytest.raises(ValueError, match="window"):
        TimestampEstimator(window=0)


def test_hops_estimate_with_a_measured_per_hop_delay():
    route = line(ConstantDelay(delay=0.01))
    assert hops_estimate(route, per_hop=0.02).tau_d == pytest.approx(0.06)
    with pytest.raises(ValueError, match="per_hop"):
        hops_estimate(route, per_hop=-1.0)
    with pytest.raises(ValueError, match="probes"):
        ping_estimate(route, 0, np.random.default_rng(0), probes=0)
