"""Delivered path delays of the WSN emulator beside their exact distributions.

For each per-hop delay model on a 3-hop path (sensor - relay - relay - gateway), with packet
reception ratio ``prr`` and ``retries`` retries per hop, carries ``n`` packets ready at random
times and prints: mean / p95 / max of the delivered delay against the exact values, the
Kolmogorov-Smirnov p-value against the exact CDF, the loss fraction against
``1 - (1 - (1-p)^(r+1))^3``, and the paper's three path-delay estimates (time stamps of the
delivered packets, ``k`` ping probes, hops x mean per-hop delay).

Exact distributions (independent of the emulator's code): given ``m`` attempts in all over the
three hops (the sum of three geometric counts truncated at ``r + 1`` and conditioned on
delivery), the delay is ``m d`` (constant), ``m low + (high - low) IH_m`` (uniform, Irwin-Hall),
``m base + Erlang(m, mean)`` (exponential), or the first-attempt delay enumerated over every
ready phase in the frame plus ``(m - 3)`` frames (TDMA); the exact CDF is the mixture over ``m``.
"max" of the exact distribution is the top of its support.

    .venv/bin/python bench/gateway_delays.py [--prr 0.9] [--retries 2] [--n 10000] [--probes 20]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from scipy import stats  # noqa: TID253 - not a node: imports what it uses at the top

from gateway.delay_models import ConstantDelay, ExponentialDelay, TDMADelay, UniformDelay
from gateway.estimates import TimestampEstimator, hops_estimate, ping_estimate
from gateway.paths import Hop, Route, deliver

TICKS = 1_000_000
HOPS = 3
SLOT, FRAME_SLOTS = 0.002, 10


def attempts_pmf(prr: float, retries: int) -> dict[int, float]:
    """P(m attempts over the path | delivered), m = 3 .. 3 (r + 1)."""
    q = 1.0 - prr
    hop = np.array([prr * q**k for k in range(retries + 1)])
    hop /= hop.sum()  # attempts 1 .. r + 1 given the hop delivers
    total = np.array([1.0])
    for _ in range(HOPS):
        total = np.convolve(total, hop)
    return {HOPS + i: float(p) for i, p in enumerate(total)}


def irwin_hall_cdf(x, n):
    x = np.clip(np.asarray(x, dtype=float), 0.0, n)
    s = sum((-1) ** k * math.comb(n, k) * np.where(x > k, (x - k) ** n, 0.0) for k in range(n + 1))
    return s / math.factorial(n)


def erlang_cdf(x, n, mean):
    y = np.maximum(np.asarray(x, dtype=float), 0.0) / mean
    return 1.0 - np.exp(-y) * sum(y**k / math.factorial(k) for k in range(n))


def tdma_first_attempt_delays(slots) -> np.ndarray:
    """Path delay (units) for every ready phase (ticks) in the frame, one attempt per hop."""
    slot_t = round(SLOT * TICKS)
    frame_t = slot_t * FRAME_SLOTS
    t = np.arange(frame_t, dtype=np.int64)
    t0 = t.copy()
    for s in slots:
        k = -((s * slot_t - t) // frame_t)
        t = s * slot_t + k * frame_t + slot_t
    return np.sort(t - t0) / TICKS


class Exact:
    """Exact delivered-delay distribution of one model on the 3-hop path."""

    def __init__(self, name: str, model, pmf: dict[int, float], slots=None) -> None:
        self.name, self.model, self.pmf = name, model, pmf
        if isinstance(model, TDMADelay):
            self.base = tdma_first_attempt_delays(slots)

    def cdf_given(self, x, m):
        md = self.model
        if isinstance(md, ConstantDelay):
            return (np.asarray(x) >= m * md.delay - 0.5e-9).astype(float)
        if isinstance(md, UniformDelay):
            return irwin_hall_cdf((np.asarray(x) - m * md.low) / (md.high - md.low), m)
        if isinstance(md, ExponentialDelay):
            return erlang_cdf(np.asarray(x) - m * md.base, m, md.mean)
        shifted = np.asarray(x) - (m - HOPS) * md.frame + 0.5e-9
        return np.searchsorted(self.base, shifted, side="right") / len(self.base)

    def mean_given(self, m):
        md = self.model
        if isinstance(md, TDMADelay):
            return float(self.base.mean()) + (m - HOPS) * md.frame
        return m * md.mean_attempt()

    def cdf(self, x):
        return sum(p * self.cdf_given(x, m) for m, p in self.pmf.items())

    @property
    def mean(self):
        return sum(p * self.mean_given(m) for m, p in self.pmf.items())

    def quantile(self, q):
        lo, hi = 0.0, self.support_max if math.isfinite(self.support_max) else 10.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if self.cdf(mid) >= q else (mid, hi)
        return hi

    @property
    def support_max(self):
        md, m = self.model, max(self.pmf)
        if isinstance(md, ConstantDelay):
            return m * md.delay
        if isinstance(md, UniformDelay):
            return m * md.high
        if isinstance(md, ExponentialDelay):
            return math.inf
        return float(self.base[-1]) + (m - HOPS) * md.frame


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--prr", type=float, default=0.9)
    ap.add_argument("--retries", type=int, default=2)
    ap.add_argument("--n", type=int, default=10_000)
    ap.add_argument("--probes", type=int, default=20)
    ap.add_argument("--seed", type=int, default=2024)
    args = ap.parse_args()
    p, r = args.prr, args.retries
    pmf = attempts_pmf(p, r)
    cases = [
        ("constant 0.01", ConstantDelay(delay=0.01), (0, 0, 0)),
        ("uniform(0.005, 0.015)", UniformDelay(low=0.005, high=0.015), (0, 0, 0)),
        ("0.004 + Exp(0.006)", ExponentialDelay(base=0.004, mean=0.006), (0, 0, 0)),
        ("TDMA slots 5,2,7", TDMADelay(slot=SLOT, frame_slots=FRAME_SLOTS), (5, 2, 7)),
        ("TDMA slots 0,1,2", TDMADelay(slot=SLOT, frame_slots=FRAME_SLOTS), (0, 1, 2)),
    ]
    loss_exact = 1.0 - (1.0 - (1.0 - p) ** (r + 1)) ** HOPS
    lo, hi = stats.binom.interval(0.99, args.n, loss_exact)
    print(
        f"3-hop path, PRR {p}, {r} retries per hop, {args.n} packets at random ready times "
        f"(TDMA: slot {SLOT}, {FRAME_SLOTS} slots per frame); delays in time units"
    )
    print(
        f"exact loss fraction {loss_exact:.5f}, 99 % binomial interval "
        f"[{lo / args.n:.5f}, {hi / args.n:.5f}]"
    )
    print()
    head = (
        f"{'model':22s} {'mean':>8s} {'exact':>8s} {'p95':>8s} {'exact':>8s} {'max':>8s} "
        f"{'exact':>8s} {'KS p':>6s} {'loss':>7s} | {'stamps':>8s} {'ping':>8s} {'hops':>8s}"
    )
    print(head)
    print("-" * len(head))
    for i, (label, model, slots) in enumerate(cases):
        names = ["s", "r1", "r2", "g"]
        route = Route(tuple(Hop(names[h], names[h + 1], p, model, r, slots[h]) for h in range(3)))
        rng = np.random.default_rng([args.seed, i])
        ready = np.sort(np.random.default_rng([args.seed, i, 1]).integers(0, 10**9, args.n))
        stamps = TimestampEstimator()
        d, lost = [], 0
        for t0 in ready:
            t, _, _ = deliver(route, int(t0), rng)
            if t is None:
                lost += 1
            else:
                stamps.add(int(t0), t)
                d.append((t - int(t0)) / TICKS)
        d = np.asarray(d)
        ex = Exact(label, model, pmf, slots)
        ks = (
            "  -  "
            if isinstance(model, ConstantDelay)
            else f"{stats.kstest(d, ex.cdf).pvalue:6.3f}"
        )
        ping = ping_estimate(
            route, 0, np.random.default_rng([args.seed, i, 2]), args.probes, interval=7_777
        )
        print(
            f"{label:22s} {d.mean():8.5f} {ex.mean:8.5f} "
            f"{np.quantile(d, 0.95, method='inverted_cdf'):8.5f} {ex.quantile(0.95):8.5f} "
            f"{d.max():8.5f} {ex.support_max:8.5f} {ks:>6s} {lost / args.n:7.5f} | "
            f"{stamps.estimate().tau_d:8.5f} {ping.tau_d:8.5f} {hops_estimate(route).tau_d:8.5f}"
        )
    print()
    print(
        "stamps: mean delay of the delivered packets; ping: RTT/2 over "
        f"{args.probes} probes; hops: 3 x mean per-hop delay with expected retries."
    )
    print(
        "TDMA 0,1,2 is a schedule ordered along the uplink: one wait, then straight through; "
        "ping and hop count overestimate it by about one frame."
    )


if __name__ == "__main__":
    main()
