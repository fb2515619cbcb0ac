"""Per-hop delay models and path delivery: exact distributions, losses, retries, determinism.

Reference values are computed here independently of :mod:`gateway`: Irwin-Hall for sums of
uniforms, Erlang for sums of exponentials, enumeration of the ready phase for TDMA, the binomial
interval for losses.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError
from scipy import stats  # noqa: TID253 - not a node: imports what it uses at the top

from gateway.delay_models import (
    ConstantDelay,
    ExponentialDelay,
    TDMADelay,
    UniformDelay,
    expected_attempts,
    expected_attempts_delivered,
    hop_success_probability,
)
from gateway.paths import Hop, Route, deliver

TICKS = 1_000_000
HOPS = 3
N_KS = 2000


def line(model, prr=1.0, retry_limit=3, slots=(0, 0, 0)) -> Route:
    names = ["s", "r1", "r2", "g"]
    return Route(
        tuple(Hop(names[i], names[i + 1], prr, model, retry_limit, slots[i]) for i in range(HOPS))
    )


def delays(route: Route, n: int, seed: int, t_ready=None) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if t_ready is None:
        t_ready = np.zeros(n, dtype=np.int64)
    out = []
    for t in t_ready:
        d = deliver(route, int(t), rng)
        assert d.t_deliver is not None
        out.append(d.t_deliver - int(t))
    return np.asarray(out)


def irwin_hall_cdf(x: np.ndarray, n: int) -> np.ndarray:
    """CDF of the sum of n independent U(0, 1)."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, n)
    total = np.zeros_like(x)
    for k in range(n + 1):
        total += (-1) ** k * math.comb(n, k) * np.where(x > k, (x - k) ** n, 0.0)
    return total / math.factorial(n)


def erlang_cdf(x: np.ndarray, n: int, mean: float) -> np.ndarray:
    """CDF of the sum of n independent Exp(mean)."""
    y = np.maximum(np.asarray(x, dtype=float), 0.0) / mean
    return 1.0 - np.exp(-y) * sum(y**k / math.factorial(k) for k in range(n))


def tdma_path_delay(phase_ticks, slots, slot_t, n_slots, tx_t):
    """Path delay (ticks) of a packet ready at ``phase`` by walking the slot starts (PRR 1)."""
    frame_t = slot_t * n_slots
    t = np.asarray(phase_ticks, dtype=np.int64)
    t0 = t.copy()
    for s in slots:
        start = s * slot_t
        k = -((start - t) // frame_t)  # ceil((t - start) / frame): first start at or after t
        t = start + k * frame_t + tx_t
    return t - t0


# ----------------------------------------------------------------------------- no loss


def test_constant_gives_exactly_hops_times_delay():
    route = line(ConstantDelay(delay=0.0125))
    d = delays(route, 50, seed=1, t_ready=np.arange(50) * 777)
    assert np.all(d == HOPS * 12_500)


def test_uniform_sum_follows_irwin_hall():
    low, high = 0.005, 0.015
    d = delays(line(UniformDelay(low=low, high=high)), N_KS, seed=2) / TICKS
    p = stats.kstest(d, lambda x: irwin_hall_cdf((x - HOPS * low) / (high - low), HOPS)).pvalue
    assert p > 0.01
    # the test has power: two hops' worth of delay, or a 10 % wider interval, are rejected
    wrong = stats.kstest(
        d, lambda x: irwin_hall_cdf((x - HOPS * low) / (1.1 * (high - low)), HOPS)
    ).pvalue
    assert wrong < 0.01


def test_exponential_sum_follows_shifted_erlang():
    base, mean = 0.004, 0.006
    d = delays(line(ExponentialDelay(base=base, mean=mean)), N_KS, seed=3) / TICKS
    assert d.min() >= HOPS * base - 1e-6
    assert stats.kstest(d, lambda x: erlang_cdf(x - HOPS * base, HOPS, mean)).pvalue > 0.01
    assert stats.kstest(d, lambda x: erlang_cdf(x - HOPS * base, HOPS, 1.1 * mean)).pvalue < 0.01


@pytest.mark.parametrize("slots", [(5, 2, 7), (0, 1, 2)])
def test_tdma_sum_follows_phase_enumeration(slots):
    model = TDMADelay(slot=0.002, frame_slots=10, tx_time=0.0015)
    slot_t, n_slots, tx_t = 2000, 10, 1500
    frame_t = slot_t * n_slots
    ready = np.random.default_rng(40).integers(0, 10**9, size=N_KS)
    d = delays(line(model, slots=slots), N_KS, seed=4, t_ready=ready)
    # exact: every phase of the ready time in the frame equally likely (ticks)
    exact = np.sort(tdma_path_delay(np.arange(frame_t), slots, slot_t, n_slots, tx_t))
    assert np.all(d == tdma_path_delay(ready, slots, slot_t, n_slots, tx_t))

    def cdf(x):
        return np.searchsorted(exact, x, side="right") / len(exact)

    assert stats.kstest(d, cdf).pvalue > 0.01
    # worked example, slots (5, 2, 7): ready at phase 0 waits 5 slots, sends (1.5 slots),
    # waits for slot 2 of the next frame, ... all by hand:
    if slots == (5, 2, 7):
        t = 5 * 2000 + 1500  # 11 500, end of hop 1
        t = 20_000 + 2 * 2000 + 1500  # 25 500, end of hop 2
        t = 20_000 + 7 * 2000 + 1500  # 35 500, end of hop 3
        assert deliver(line(model, slots=slots), 0, np.random.default_rng(0)).t_deliver == t
        # ready exactly at the slot start: no wait
        one = Route((Hop("a", "b", 1.0, model, 0, 5),))
        assert deliver(one, 10_000, np.random.default_rng(0)).t_deliver == 10_000 + 1500
        assert deliver(one, 10_001, np.random.default_rng(0)).t_deliver == 30_000 + 1500


# ----------------------------------------------------------------------------- losses, retries


@pytest.mark.parametrize(
    ("prr", "retries", "model"),
    [
        (0.7, 1, ConstantDelay(delay=0.01)),
        (0.5, 0, UniformDelay(low=0.001, high=0.003)),
        (0.4, 2, TDMADelay(slot=0.001, frame_slots=4)),
    ],
)
def test_loss_fraction_inside_binomial_interval(prr, retries, model):
    n = 10_000
    route = line(model, prr=prr, retry_limit=retries)
    rng = np.random.default_rng(5)
    results = [deliver(route, 0, rng) for _ in range(n)]
    lost = sum(r.lost for r in results)
    exact = 1.0 - (1.0 - (1.0 - prr) ** (retries + 1)) ** HOPS
    lo, hi = stats.binom.interval(0.99, n, exact)
    assert lo <= lost <= hi
    for r in results:
        assert all(1 <= a <= retries + 1 for a in r.attempts)
        assert r.hops == HOPS
        if r.lost:  # lost where a hop used up its attempts
            assert r.attempts[-1] == retries + 1 and len(r.attempts) <= HOPS
        else:
            assert len(r.attempts) == HOPS


def test_constant_delay_is_attempts_times_delay():
    route = line(ConstantDelay(delay=0.01), prr=0.6, retry_limit=3)
    rng = np.random.default_rng(6)
    seen = set()
    for _ in range(2000):
        t, attempts, _ = deliver(route, 100, rng)
        if t is not None:
            assert t - 100 == sum(attempts) * 10_000
            seen.add(sum(attempts))
    assert seen == set(range(3, 13))  # every total from 3 to 3 (r + 1) occurs


def test_tdma_retry_waits_one_frame():
    slots, slot_t, n_slots, tx_t = (5, 2, 7), 2000, 10, 2000
    route = line(TDMADelay(slot=0.002, frame_slots=10), prr=0.5, retry_limit=2, slots=slots)
    rng = np.random.default_rng(7)
    ready = rng.integers(0, 10**8, size=3000)
    base = tdma_path_delay(ready, slots, slot_t, n_slots, tx_t)
    checked = 0
    for t0, b in zip(ready, base, strict=True):
        t, attempts, _ = deliver(route, int(t0), rng)
        if t is not None:  # whole frames do not change the phase: each retry adds one frame
            assert t - t0 == b + (sum(attempts) - HOPS) * slot_t * n_slots
            checked += 1
    assert checked > 1000


def test_exponential_retries_add_erlang_stages():
    base, mean, prr = 0.002, 0.003, 0.6
    route = line(ExponentialDelay(base=base, mean=mean), prr=prr, retry_limit=2)
    rng = np.random.default_rng(8)
    by_total: dict[int, list[float]] = {}
    for _ in range(6000):
        t, attempts, _ = deliver(route, 0, rng)
        if t is not None:
            by_total.setdefault(sum(attempts), []).append(t / TICKS)
    for n in (3, 4, 5):  # given n attempts in all: n * base + Erlang(n, mean)
        d = np.asarray(by_total[n])
        assert len(d) > 300
        assert stats.kstest(d, lambda x, n=n: erlang_cdf(x - n * base, n, mean)).pvalue > 0.01


def test_uniform_retries_stay_in_support():
    route = line(UniformDelay(low=0.002, high=0.004), prr=0.5, retry_limit=1)
    rng = np.random.default_rng(9)
    for _ in range(1000):
        t, attempts, _ = deliver(route, 0, rng)
        if t is not None:
            n = sum(attempts)
            assert n * 2000 <= t <= n * 4000


def test_retry_arithmetic_matches_enumeration():
    for prr, r in [(1.0, 0), (0.9, 0), (0.7, 3), (0.2, 5)]:
        q = 1.0 - prr
        pk = [prr * q ** (k - 1) for k in range(1, r + 2)]  # P(first success at attempt k)
        ok = sum(pk)
        tries = sum(k * p for k, p in enumerate(pk, 1)) + (r + 1) * (1.0 - ok)
        assert hop_success_probability(prr, r) == pytest.approx(ok)
        assert expected_attempts(prr, r) == pytest.approx(tries)
        assert expected_attempts_delivered(prr, r) == pytest.approx(
            sum(k * p for k, p in enumerate(pk, 1)) / ok
        )
    with pytest.raises(ValueError, match="prr"):
        expected_attempts(0.0, 1)
    with pytest.raises(ValueError, match="retry_limit"):
        expected_attempts(0.5, -1)


def test_mean_hop_delay_per_model():
    ea = expected_attempts_delivered(0.8, 2)
    assert ConstantDelay(delay=0.01).mean_hop(0.8, 2) == pytest.approx(0.01 * ea)
    assert UniformDelay(low=0.01, high=0.03).mean_hop(0.8, 2) == pytest.approx(0.02 * ea)
    assert ExponentialDelay(base=0.01, mean=0.02).mean_hop(0.8, 2) == pytest.approx(0.03 * ea)
    tdma = TDMADelay(slot=0.002, frame_slots=10)
    assert tdma.mean_hop(0.8, 2) == pytest.approx(0.01 + 0.002 + (ea - 1) * 0.02)


# ----------------------------------------------------------------------------- determinism


def test_same_generator_seed_same_deliveries():
    route = line(ExponentialDelay(base=0.001, mean=0.002), prr=0.8, retry_limit=2)
    a = [deliver(route, 10 * k, np.random.default_rng(11)) for k in range(5)]
    b = [deliver(route, 10 * k, np.random.default_rng(11)) for k in range(5)]
    assert a == b
    ga, gb = np.random.default_rng(12), np.random.default_rng(12)
    assert [deliver(route, 0, ga) for _ in range(50)] == [deliver(route, 0, gb) for _ in range(50)]
    gc = np.random.default_rng(13)
    assert [deliver(route, 0, gc) for _ in range(50)] != [
        deliver(route, 0, np.random.default_rng(12)) for _ in range(50)
    ]


def test_delivery_unpacks_as_triple():
    t, attempts, hops = deliver(line(ConstantDelay(delay=0.001)), 5, np.random.default_rng(0))
    assert (t, attempts, hops) == (5 + 3000, (1, 1, 1), 3)


# ----------------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("cls", "kwargs", "field"),
    [
        (ConstantDelay, {"delay": -0.1}, "delay"),
        (UniformDelay, {"low": -0.1, "high": 0.1}, "low"),
        (UniformDelay, {"low": 0.2, "high": 0.1}, "high"),
        (ExponentialDelay, {"base": 0.0, "mean": 0.0}, "mean"),
        (ExponentialDelay, {"base": -1.0, "mean": 1.0}, "base"),
        (TDMADelay, {"slot": 0.0, "frame_slots": 4}, "slot"),
        (TDMADelay, {"slot": 0.01, "frame_slots": 0}, "frame_slots"),
        (TDMADelay, {"slot": 0.01, "frame_slots": 4, "tx_time": 0.02}, "tx_time"),
        (ConstantDelay, {"delay": 0.1, "jitter": 0.1}, "jitter"),
    ],
)
def test_bad_model_refused_naming_field(cls, kwargs, field):
    with pytest.raises(ValidationError, match=field):
        cls(**kwargs)


def test_route_must_chain():
    m = ConstantDelay(delay=0.01)
    with pytest.raises(ValueError, match="not followed"):
        Route((Hop("a", "b", 1.0, m, 0), Hop("c", "d", 1.0, m, 0)))
