"""The TSCH MAC, slot by slot: queues, dedicated and shared cells, channel hopping, retries,
acknowledgements, drops by reason, and the energy of every slot.

IEEE Std 802.15.4-2015 (TSCH, section 6.2.6), as WirelessHART and ISA100.11a run it:

* Slot ``ASN`` starts at ``ASN * slot_ticks`` and ends one slot later. A packet can be sent in a
  slot that starts at or after it reached its holder (``t_ready``, or the end of the slot in
  which the previous hop delivered it); a packet delivered to its destination arrives at the end
  of that slot.
* In each active cell (:mod:`gateway.tsch.schedule`) the transmitter sends the first packet of
  its queue whose next hop is the cell's receiver (one packet per cell), on channel
  ``hopping[(ASN + channel_offset) mod len(hopping)]``. The frame is received with probability
  ``pdr(tx, rx, channel, t)`` (:mod:`gateway.tsch.link_quality`): one uniform draw per attempt.
  A received frame is acknowledged (the ACK's own loss is not modelled: 11 bytes against 127) and
  moves to the receiver's queue; otherwise the packet stays at the head of the queue and is sent
  again in the next cell toward the same neighbour, up to ``max_retries`` retransmissions per
  hop ("retries exhausted" past them).
* Shared cells with the same (slot, channel offset, receiver) are contended for with TSCH CSMA-CA
  (802.15.4-2015 6.2.5.3, as the 6TiSCH simulator implements it): a node's first attempt goes in
  the next shared cell; two or more transmitters in one cell collide and all fail; after a failed
  attempt the node's backoff exponent ``BE`` becomes ``min(BE + 1, max_be)`` and it skips a
  uniform ``0 .. 2^BE - 1`` of its next shared cells (its counter decreases in each shared cell in
  which it has a packet for the receiver); a success resets ``BE = min_be``.
* Every node has one transmit queue of ``queue_capacity`` packets; a packet arriving at a full
  queue (from the application or from a neighbour) is dropped ("queue full"). A packet whose
  next link has no cell, or whose holder goes down, is dropped ("no route", "node down").

Random draws (one generator, owned by the network): in slot order, within a slot in cell order
(channel offset, transmitter): one ``random()`` per attempt that reaches the air, then, for each
failed shared-cell attempt, one ``integers(0, 2^BE)`` for the backoff.

Energy (:mod:`gateway.tsch.energy`): attempts are counted as they happen (``tx_ack``,
``tx_noack``, ``rx_ack``); listening slots are counted from the schedule in bulk (every active
RX cell of a node is a listening slot, idle unless a frame was received in it), sleeping slots
are the rest.
"""

from __future__ import annotations

import copy
from collections import Counter, deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gateway.tsch.schedule import Cell, Schedule

__all__ = ["Packet", "Outcome", "TschMac", "DROP_REASONS"]

DROP_REASONS = ("queue_full", "retries_exhausted", "no_route", "node_down")

Pdr = Callable[[str, str, int, int], float]
"""``pdr(tx, rx, channel, t_ticks)``: the probability that one frame gets through."""


@dataclass
class Packet:
    """A packet on its way: the caller's ``id``, its route and where it is."""

    id: Any
    route: tuple[str, ...]
    t_ready: int
    hop: int = 0  # index in route of the node holding it
    eligible: int = 0  # first ASN in which its holder may send it
    retries: int = 0  # failed attempts on the current hop
    attempts: int = 0  # attempts on every hop so far

    @property
    def holder(self) -> str:
        return self.route[self.hop]

    @property
    def next_hop(self) -> str:
        return self.route[self.hop + 1]


@dataclass(frozen=True)
class Outcome:
    """What became of a packet: delivered at ``t`` (ticks, end of its last slot), or dropped
    at ``t`` with a reason (:data:`DROP_REASONS`)."""

    id: Any
    t: int
    delivered: bool
    reason: str | None = None
    attempts: int = 0


@dataclass
class _Backoff:
    be: int
    counter: int = 0


@dataclass
class _Segment:
    """A stretch of slots run under one schedule, for the listening count."""

    schedule: Schedule
    start: int  # first ASN
    end: int | None = None  # ASN after the last (None: still running)


class TschMac:
    """The MAC of one TSCH network (module docstring).

    Parameters
    ----------
    schedule : Schedule
        The cells (rebuilt later with :meth:`set_schedule`).
    slot_ticks : int
        Slot duration in ticks.
    hopping : sequence of int
        The hopping sequence (IEEE 802.15.4 channels 11-26).
    pdr : callable
        ``pdr(tx, rx, channel, t_ticks)``.
    rng : numpy Generator
        The network's own generator.
    """

    def __init__(
        self,
        schedule: Schedule,
        *,
        slot_ticks: int,
        hopping: Sequence[int],
        pdr: Pdr,
        rng: np.random.Generator,
        queue_capacity: int = 10,
        max_retries: int = 3,
        min_be: int = 1,
        max_be: int = 7,
    ) -> None:
        if slot_ticks < 1:
            raise ValueError("a slot lasts at least one tick")
        if not hopping:
            raise ValueError("the hopping sequence is empty")
        self.slot_ticks = slot_ticks
        self.hopping = tuple(hopping)
        self.pdr = pdr
        self.rng = rng
        self.queue_capacity = queue_capacity
        self.max_retries = max_retries
        self.min_be = min_be
        self.max_be = max_be
        self.counts: dict[str, Counter[str]] = {}  # node -> tx_ack, tx_noack, rx_ack
        self.queues: dict[str, deque[Packet]] = {}
        self._hops: dict[str, Counter[str]] = {}  # node -> queued packets per next hop
        self.backoff: dict[str, _Backoff] = {}
        self.down: set[str] = set()
        self.asn = 0  # slots before this one are done
        self.drops: Counter[str] = Counter()
        self.delivered = 0
        self.segments: list[_Segment] = []
        self._install(schedule, 0)

    def clone(self, rng: np.random.Generator) -> TschMac:
        """A copy with the same schedule, queues, backoff and counters, drawing from ``rng``:
        for probes that must not disturb the real network's draws."""
        twin = copy.copy(self)
        twin.rng = rng
        twin.queues = {n: deque(copy.copy(p) for p in q) for n, q in self.queues.items()}
        twin._hops = {n: Counter(c) for n, c in self._hops.items()}
        twin.backoff = {n: _Backoff(b.be, b.counter) for n, b in self.backoff.items()}
        twin.down = set(self.down)
        twin.drops = Counter(self.drops)
        twin.counts = {n: Counter(c) for n, c in self.counts.items()}
        twin.segments = [_Segment(s.schedule, s.start, s.end) for s in self.segments]
        return twin

    # -- the schedule ---------------------------------------------------------------------------

    def _install(self, schedule: Schedule, asn: int) -> None:
        if self.segments:
            self.segments[-1].end = asn
        self.segments.append(_Segment(schedule, asn))
        self.schedule = schedule
        self.length = schedule.length
        self._slots = schedule.by_slot()
        self._offsets = sorted(self._slots)
        self._links = {c.link for c in schedule.cells}

    def set_schedule(self, schedule: Schedule, t: int) -> list[Outcome]:
        """Run ``schedule`` from the first slot starting at or after ``t`` (slots before are
        run under the old one first). Packets whose next link has no cell any more are dropped
        ("no route"); returns every outcome up to then."""
        out = self.advance(t)
        self._install(schedule, self.asn)
        for node in sorted(self.queues):
            for p in [p for p in self.queues[node] if (p.holder, p.next_hop) not in self._links]:
                self._remove(p)
                out.append(self._drop(p, "no_route", self.asn * self.slot_ticks))
        return out

    def set_down(self, node: str, down: bool, t: int) -> list[Outcome]:
        """Node ``node`` goes down (its queue is lost: "node down") or comes back, at ``t``."""
        out = self.advance(t)
        if down:
            self.down.add(node)
            for p in list(self.queues.get(node, ())):
                self._remove(p)
                out.append(self._drop(p, "node_down", t))
        else:
            self.down.discard(node)
        return out

    # -- packets --------------------------------------------------------------------------------

    def submit(self, packet_id: Any, route: Sequence[str] | None, t: int) -> Outcome | None:
        """A packet enters the network at ``route[0]`` at ``t`` (ticks). Returns its outcome at
        once when it cannot enter (no route, source down, queue full), else ``None``."""
        if route is None or len(route) < 2:
            return self._drop(Packet(packet_id, tuple(route or ()), t), "no_route", t)
        p = Packet(packet_id, tuple(route), t, eligible=self._first_slot_at(t))
        if p.holder in self.down:
            return self._drop(p, "node_down", t)
        if (p.holder, p.next_hop) not in self._links:
            return self._drop(p, "no_route", t)
        if len(self.queues.get(p.holder, ())) >= self.queue_capacity:
            return self._drop(p, "queue_full", t)
        self._enqueue(p)
        return None

    def _enqueue(self, p: Packet) -> None:
        self.queues.setdefault(p.holder, deque()).append(p)
        self._hops.setdefault(p.holder, Counter())[p.next_hop] += 1

    def _remove(self, p: Packet) -> None:
        self.queues[p.holder].remove(p)
        self._hops[p.holder][p.next_hop] -= 1

    def _first_slot_at(self, t: int) -> int:
        return -(-t // self.slot_ticks)  # ceil: the first slot starting at or after t

    def _drop(self, p: Packet, reason: str, t: int) -> Outcome:
        self.drops[reason] += 1
        return Outcome(p.id, t, False, reason, p.attempts)

    def pending(self) -> int:
        return sum(len(q) for q in self.queues.values())

    # -- time -----------------------------------------------------------------------------------

    def next_wakeup(self) -> int | None:
        """End (ticks) of the next slot in which a queued packet may be sent, or ``None`` when
        the queues are empty: the caller's next timer."""
        asn = self._next_busy_slot(self.asn)
        return None if asn is None else (asn + 1) * self.slot_ticks

    def _next_busy_slot(self, asn: int) -> int | None:
        waiting = {}  # link -> the first eligible slot of its first queued packet
        for node, hops in self._hops.items():
            for hop, n in hops.items():
                if n > 0:
                    p = next(p for p in self.queues[node] if p.next_hop == hop)
                    waiting[node, hop] = p.eligible
        if not waiting:
            return None
        start = max(asn, min(waiting.values()))
        for frame in range(start // self.length, start // self.length + 2 * self._max_every()):
            for offset in self._offsets:
                a = frame * self.length + offset
                if a < start:
                    continue
                for c in self._slots[offset]:
                    if c.active_in(frame) and waiting.get(c.link, a + 1) <= a:
                        return a
        return None

    def _max_every(self) -> int:
        return max((c.every for c in self.schedule.cells), default=1)

    def advance(self, t: int) -> list[Outcome]:
        """Run every slot that starts before ``t``; the outcomes in slot order."""
        out: list[Outcome] = []
        end = self._first_slot_at(t)  # slots < end start before t
        while self.asn < end:
            busy = self._next_busy_slot(self.asn)
            if busy is None or busy >= end:
                self.asn = end
                break
            self._run_slot(busy, out)
            self.asn = busy + 1
        return out

    def _run_slot(self, asn: int, out: list[Outcome]) -> None:
        frame, offset = divmod(asn, self.length)
        t_start = asn * self.slot_ticks
        t_end = t_start + self.slot_ticks
        cells = [c for c in self._slots[offset] if c.active_in(frame)]
        groups: dict[tuple[int, str], list[Cell]] = {}
        for c in cells:
            if c.shared:
                groups.setdefault((c.channel, c.rx), []).append(c)
        for c in cells:
            if not c.shared:
                p = self._head(c.tx, c.rx, asn)
                if p is not None:
                    ok = c.rx not in self.down and self._draw(c, asn, t_start)
                    self._attempted(p, c, ok, out, t_end)
            elif groups[(c.channel, c.rx)][0] is c:
                self._run_shared(asn, groups[(c.channel, c.rx)], t_start, t_end, out)

    def _run_shared(
        self, asn: int, group: list[Cell], t_start: int, t_end: int, out: list[Outcome]
    ) -> None:
        senders: list[tuple[Cell, Packet]] = []
        for c in group:
            p = self._head(c.tx, c.rx, asn)
            if p is None:
                continue
            b = self.backoff.setdefault(c.tx, _Backoff(self.min_be))
            if b.counter > 0:
                b.counter -= 1  # backing off: this shared cell is skipped
                continue
            senders.append((c, p))
        if len(senders) == 1:
            c, p = senders[0]
            ok = c.rx not in self.down and self._draw(c, asn, t_start)
            self._attempted(p, c, ok, out, t_end)
            if ok:
                self.backoff[c.tx] = _Backoff(self.min_be)
            return
        for c, p in senders:  # two or more in one cell: a collision, every sender fails
            self._attempted(p, c, False, out, t_end)

    def _head(self, tx: str, rx: str, asn: int) -> Packet | None:
        if tx in self.down:
            return None
        for p in self.queues.get(tx, ()):
            if p.next_hop == rx and p.eligible <= asn:
                return p
        return None

    def _draw(self, c: Cell, asn: int, t_start: int) -> bool:
        channel = self.hopping[(asn + c.channel) % len(self.hopping)]
        return bool(self.rng.random() < self.pdr(c.tx, c.rx, channel, t_start))

    def _attempted(self, p: Packet, c: Cell, ok: bool, out: list[Outcome], t_end: int) -> None:
        """One attempt of ``p`` in cell ``c``: acknowledged (``ok``) or not."""
        p.attempts += 1
        if not ok:
            self._charge(c.tx, "tx_noack")
            p.retries += 1
            if c.shared:
                self._back_off(c.tx)
            if p.retries > self.max_retries:
                self._remove(p)
                out.append(self._drop(p, "retries_exhausted", t_end))
                if c.shared:
                    self.backoff[c.tx] = _Backoff(self.min_be)
            return
        self._charge(c.tx, "tx_ack")
        self._charge(c.rx, "rx_ack")
        self._remove(p)
        p.hop += 1
        p.retries = 0
        p.eligible = t_end // self.slot_ticks
        if p.hop == len(p.route) - 1:
            self.delivered += 1
            out.append(Outcome(p.id, t_end, True, None, p.attempts))
            return
        if p.holder in self.down:
            out.append(self._drop(p, "node_down", t_end))
        elif (p.holder, p.next_hop) not in self._links:
            out.append(self._drop(p, "no_route", t_end))
        elif len(self.queues.get(p.holder, ())) >= self.queue_capacity:
            out.append(self._drop(p, "queue_full", t_end))
        else:
            self._enqueue(p)

    def _back_off(self, tx: str) -> None:
        b = self.backoff.setdefault(tx, _Backoff(self.min_be))
        b.be = min(b.be + 1, self.max_be)
        b.counter = int(self.rng.integers(0, 2**b.be))

    def _charge(self, node: str, kind: str) -> None:
        self.counts.setdefault(node, Counter())[kind] += 1

    # -- energy ---------------------------------------------------------------------------------

    def listening(self, end: int) -> Counter[str]:
        """Node -> its listening slots (active RX cells) among slots ``0 .. end - 1``."""
        out: Counter[str] = Counter()
        for seg in self.segments:
            a = seg.start
            b = min(end, seg.end if seg.end is not None else end)
            if b <= a:
                continue
            length = seg.schedule.length
            listens = {(c.slot, c.rx, c.every, c.phase) for c in seg.schedule.cells}
            for slot, rx, every, phase in listens:
                period, r = length * every, phase * length + slot
                out[rx] += (b - 1 - r) // period - (a - 1 - r) // period
        return out

    def slot_counts(self, nodes: Sequence[str], t: int) -> dict[str, Counter[str]]:
        """Node -> slots of each kind (:data:`gateway.tsch.energy.SLOT_KINDS`) among the slots
        that end by ``t`` (run :meth:`advance` to ``t`` first)."""
        end = min(t // self.slot_ticks, self.asn)
        listening = self.listening(end)
        out = {}
        for node in nodes:
            mine = self.counts.get(node, Counter())
            counts: Counter[str] = Counter(
                tx_ack=mine["tx_ack"], tx_noack=mine["tx_noack"], rx_ack=mine["rx_ack"]
            )
            counts["idle"] = max(listening[node] - mine["rx_ack"], 0)
            busy = counts["tx_ack"] + counts["tx_noack"] + counts["rx_ack"] + counts["idle"]
            counts["sleep"] = max(end - busy, 0)
            out[node] = counts
        return out
