"""Per-hop delay models of the WSN emulator, and the retransmission arithmetic they share.

Seed 000, section I: the latency ``tau_d`` a control packet meets depends on the network
configuration, above all on the number of hops of its path. A message on a path of ``n`` hops is
delayed by the sum of ``n`` per-hop delays (DESIGN.md, section 5); this module says what one hop
costs. Delays are given in scenario time units (floats) in the configuration; a hop's duration is
returned in integer ticks (:mod:`core.time`), so successive hops chain on integer time.

Retransmissions
---------------
Each transmission attempt on a link succeeds independently with the link's packet reception
ratio ``p`` (PRR). With a retry limit ``r`` a hop makes at most ``r + 1`` attempts; if all fail,
the packet is lost at that hop. The number of attempts ``a`` until the first success is geometric,
``P(a = k) = p (1 - p)^(k-1)``, so (with ``q = 1 - p``)::

    P(hop delivers)              = 1 - q^(r+1)
    E[attempts]                  = sum_{k=0..r} q^k = (1 - q^(r+1)) / p    (delivered or not)
    E[attempts | hop delivers]   = sum_{k=1..r+1} k p q^(k-1) / (1 - q^(r+1))

What a hop of ``a`` attempts costs, model by model (every attempt pays the model's per-attempt
delay: the failed ones because the sender learns of the failure by the missing acknowledgement
only after the attempt, the last because it is the transmission)::

    constant     a * delay                                  (each attempt exactly ``delay``)
    uniform      sum of a independent U(low, high) draws
    exponential  sum of a independent (base + Exp(mean)) draws = a * base + Gamma(a, mean)
    tdma         wait for the link's next slot + (a - 1) * frame + tx_time
                 (a failed attempt is retried in the link's slot of the next frame)

Rounding: each attempt's draw is rounded to the nearest tick (:func:`core.time.to_ticks`), so a
hop of ``a`` attempts is off by at most ``a / 2`` ticks, the constant model costs exactly
``a * to_ticks(delay)`` ticks, and TDMA is computed wholly in ticks (slot and transmission
lengths rounded once). Configure delays much larger than one tick (1e-6 time unit).

TDMA slot waiting, precisely
----------------------------
The slot-frame is ``frame_slots`` slots of length ``L = slot`` and starts at ``t = 0``: slot ``j``
of frame ``k`` occupies ``[(k N + j) L, (k N + j + 1) L)`` with ``N = frame_slots``. Each link owns
one slot index ``s`` (used in both directions). A packet ready at the sender at ``t_r`` (ticks) is
sent at the start of the link's first slot that starts at or after ``t_r`` (a packet ready exactly
at a slot start goes in that slot)::

    wait    = (s L - t_r) mod (N L)                 0 <= wait < N L
    t_first = t_r + wait
    t_done  = t_first + (a - 1) N L + tx_time       (tx_time <= L; default L, the whole slot)

so the hop delay is ``wait + (a - 1) N L + tx_time``, and ``t_done`` is the next hop's ready
time. The model is deterministic given ``t_r``: its randomness is the phase of the ready time in
the frame (and the retries). There is no queueing: packets on the same link do not delay each
other. :meth:`TDMADelay.mean_attempt` assumes a uniformly random phase (mean wait ``N L / 2``).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from core.registry import Kind, Registry
from core.time import TICKS_PER_UNIT, to_ticks

__all__ = [
    "ConstantDelay",
    "UniformDelay",
    "ExponentialDelay",
    "TDMADelay",
    "DelayModel",
    "DELAY_MODELS",
    "hop_success_probability",
    "expected_attempts",
    "expected_attempts_delivered",
]

_FROZEN = ConfigDict(frozen=True, extra="forbid")


def _check_prr_retries(prr: float, retry_limit: int) -> None:
    if not 0.0 < prr <= 1.0:
        raise ValueError(f"prr: must be in (0, 1], got {prr}")
    if retry_limit < 0:
        raise ValueError(f"retry_limit: must be >= 0, got {retry_limit}")


def hop_success_probability(prr: float, retry_limit: int) -> float:
    """Probability that a hop delivers within ``retry_limit + 1`` attempts: ``1 - (1-p)^(r+1)``."""
    _check_prr_retries(prr, retry_limit)
    return 1.0 - (1.0 - prr) ** (retry_limit + 1)


def expected_attempts(prr: float, retry_limit: int) -> float:
    """Expected attempts on a hop, delivered or not: ``(1 - (1-p)^(r+1)) / p``.

    This is the expected transmission count with the retry limit (it tends to ETX = 1/p as the
    limit grows) and what the sender's radio pays per packet offered to the hop.
    """
    return hop_success_probability(prr, retry_limit) / prr


def expected_attempts_delivered(prr: float, retry_limit: int) -> float:
    """Expected attempts on a hop given that it delivers: ``E[a | a <= r + 1]``."""
    _check_prr_retries(prr, retry_limit)
    q = 1.0 - prr
    k = np.arange(1, retry_limit + 2)
    w = prr * q ** (k - 1)
    return float(np.sum(k * w) / np.sum(w))


def _round_sum(draws: np.ndarray) -> int:
    """Sum of per-attempt draws (units), each rounded to the nearest tick."""
    return int(np.rint(draws * TICKS_PER_UNIT).astype(np.int64).sum())


class _PerAttemptDelay(BaseModel):
    """A model in which every attempt's delay is an independent draw of one distribution,
    whatever the time (constant, uniform, exponential; not TDMA): a hop that delivers costs
    ``E[a | hop delivers]`` mean attempts (module docstring)."""

    model_config = _FROZEN

    def mean_attempt(self) -> float:
        """Mean per-attempt delay, time units."""
        raise NotImplementedError

    def mean_hop(self, prr: float, retry_limit: int) -> float:
        """Mean delay of a hop that delivers (retries included), time units."""
        return expected_attempts_delivered(prr, retry_limit) * self.mean_attempt()


class ConstantDelay(_PerAttemptDelay):
    """Every attempt takes exactly ``delay`` time units."""

    type: Literal["constant"] = "constant"
    delay: float = Field(ge=0, description="per-attempt delay, time units")

    def hop_ticks(self, t_ready: int, attempts: int, rng: np.random.Generator, slot: int) -> int:
        """Duration in ticks of a hop of ``attempts`` attempts: ``attempts * to_ticks(delay)``."""
        return attempts * to_ticks(self.delay)

    def mean_attempt(self) -> float:
        """Mean per-attempt delay, time units."""
        return self.delay


class UniformDelay(_PerAttemptDelay):
    """Every attempt takes an independent ``U(low, high)`` time."""

    type: Literal["uniform"] = "uniform"
    low: float = Field(ge=0, description="shortest per-attempt delay, time units")
    high: float = Field(ge=0, description="longest per-attempt delay, time units")

    @model_validator(mode="after")
    def _ordered(self) -> UniformDelay:
        if not self.low <= self.high:
            raise ValueError(f"high: must be >= low ({self.low}), got {self.high}")
        return self

    def hop_ticks(self, t_ready: int, attempts: int, rng: np.random.Generator, slot: int) -> int:
        """Duration in ticks of a hop: ``attempts`` draws of ``U(low, high)``, each rounded."""
        return _round_sum(rng.uniform(self.low, self.high, size=attempts))

    def mean_attempt(self) -> float:
        """Mean per-attempt delay ``(low + high) / 2``, time units."""
        return 0.5 * (self.low + self.high)


class ExponentialDelay(_PerAttemptDelay):
    """Every attempt takes ``base + Exp(mean)``: a fixed part plus exponential jitter."""

    type: Literal["exponential"] = "exponential"
    base: float = Field(ge=0, description="fixed part of the per-attempt delay, time units")
    mean: float = Field(gt=0, description="mean of the exponential jitter, time units")

    def hop_ticks(self, t_ready: int, attempts: int, rng: np.random.Generator, slot: int) -> int:
        """Duration in ticks of a hop: ``attempts`` draws of ``base + Exp(mean)``, each rounded."""
        return _round_sum(self.base + rng.exponential(self.mean, size=attempts))

    def mean_attempt(self) -> float:
        """Mean per-attempt delay ``base + mean``, time units."""
        return self.base + self.mean


class TDMADelay(BaseModel):
    """Slot waiting in a TDMA slot-frame (see the module docstring for the exact rule)."""

    model_config = _FROZEN

    type: Literal["tdma"] = "tdma"
    slot: float = Field(gt=0, description="slot length L, time units")
    frame_slots: int = Field(ge=1, description="slots per frame N (frame length N L)")
    tx_time: float | None = Field(
        default=None,
        gt=0,
        description="time from slot start to reception at the next node (<= slot); "
        "default: the whole slot",
    )

    @model_validator(mode="after")
    def _fits(self) -> TDMADelay:
        if to_ticks(self.slot) < 1:
            raise ValueError(f"slot: shorter than one tick ({self.slot})")
        if self.tx_time is not None and self.tx_time > self.slot:
            raise ValueError(f"tx_time: must be <= slot ({self.slot}), got {self.tx_time}")
        return self

    @property
    def frame(self) -> float:
        """Frame length ``N L``, time units."""
        return self.frame_slots * self.slot

    def ticks(self) -> tuple[int, int, int]:
        """``(slot, frame, tx_time)`` in ticks."""
        slot_t = to_ticks(self.slot)
        tx_t = slot_t if self.tx_time is None else to_ticks(self.tx_time)
        return slot_t, slot_t * self.frame_slots, tx_t

    def hop_ticks(self, t_ready: int, attempts: int, rng: np.random.Generator, slot: int) -> int:
        """Duration in ticks of a hop on the link owning ``slot``: wait + retries + tx_time."""
        slot_t, frame_t, tx_t = self.ticks()
        wait = (slot * slot_t - t_ready) % frame_t
        return wait + (attempts - 1) * frame_t + tx_t

    def mean_attempt(self) -> float:
        """Mean first-attempt delay under a uniformly random ready phase: ``N L / 2 + tx``."""
        _, frame_t, tx_t = self.ticks()
        return (frame_t / 2 + tx_t) / TICKS_PER_UNIT

    def mean_hop(self, prr: float, retry_limit: int) -> float:
        """Mean delay of a hop that delivers: ``N L / 2 + tx + (E[a | ok] - 1) N L``."""
        _, frame_t, _ = self.ticks()
        extra = expected_attempts_delivered(prr, retry_limit) - 1.0
        return self.mean_attempt() + extra * frame_t / TICKS_PER_UNIT


DELAY_MODELS: Registry[BaseModel] = Registry(
    "delay model",
    tag="type",
    kinds=[  # no build: a delay model's configuration is the model
        Kind("constant", ConstantDelay),
        Kind("uniform", UniformDelay),
        Kind("exponential", ExponentialDelay),
        Kind("tdma", TDMADelay),
    ],
)
"""Every per-hop delay model by its ``type:``; to add one, a class with ``hop_ticks`` and
``mean_hop`` (as above) and an entry here."""

DelayModel = DELAY_MODELS.union()
"""A per-hop delay model, chosen by its ``type`` field."""
