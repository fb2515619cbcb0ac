"""TSCH schedules: cells, a central scheduler for flows, and the check of a written schedule.

A TSCH slotframe has ``length`` slots; a **cell** is one (slot offset, channel offset) pair of
it given to a transmitter and a receiver. Slot number ``ASN`` (absolute slot number, counted from
the start of the run) is slot offset ``ASN mod length`` of slotframe ``ASN div length``; the
cell's frequency there is ``hopping[(ASN + channel_offset) mod len(hopping)]`` (IEEE Std
802.15.4-2015, 6.2.6.3). A **dedicated** cell has one transmitter; **shared** cells with the same
slot, channel offset and receiver are contended for with TSCH CSMA-CA backoff (:mod:`gateway.tsch
.mac`). A cell may be active only in every ``every``-th slotframe (those with ``n mod every ==
phase``): how a flow slower than one packet per slotframe takes fewer cells (WirelessHART gives
each publish period its own superframe; this is the same with one slotframe length).

The **central scheduler** (:func:`build_schedule`), as a WirelessHART network manager does, gives
every flow (a path's packets: a route and a period in slots) chains of cells along its route in
time order: for each hop, one cell and ``retry_cells`` more right after it toward the same
neighbour (retransmissions), then the next hop's cells, so that a packet generated at the chain's
first slot crosses all hops in the chain's span when capacity allows. A flow of period ``P``
slots gets one chain per packet slot ``offset + k P`` of the hyperframe of ``lcm(P, length)``
slots, each of its cells active every ``lcm(P, length) / length`` slotframes: a packet generated
on time finds its chain's first cell at once, and the cells per slotframe are
``hops (1 + retry_cells) length / P``. The manager asks for periods granted by :func:`grant`
(``P`` divides ``length``: ``length / P`` chains per slotframe; ``length`` divides ``P``: one
chain every ``P / length`` slotframes). A cell goes to the first slot
at or after the previous cell in which neither end is busy (a node has one radio: at most one
cell per slot, whatever the channel) and a channel offset is free; when no slot of the slotframe
can take it, the link **lacks** that cell (:attr:`Schedule.lacking`): the manager's "cannot".

:func:`check_cells` checks a schedule written in the scenario: offsets within the slotframe and
the channel offsets, a node in at most one cell of a slot (the receiver of a shared group
excepted), no two dedicated cells on one (slot, channel offset).
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

__all__ = [
    "Cell",
    "Flow",
    "Schedule",
    "build_schedule",
    "check_cells",
    "overlap",
    "flows_of",
    "schedule_for",
    "grant",
]


@dataclass(frozen=True, order=True)
class Cell:
    """One cell: ``tx`` sends to ``rx`` in slot offset ``slot`` on channel offset ``channel``,
    in slotframes ``n`` with ``n mod every == phase``."""

    slot: int
    channel: int
    tx: str
    rx: str
    shared: bool = False
    every: int = 1
    phase: int = 0
    flow: str = ""

    def active_in(self, frame: int) -> bool:
        """Whether the cell is active in slotframe ``frame``."""
        return frame % self.every == self.phase

    @property
    def link(self) -> tuple[str, str]:
        return (self.tx, self.rx)


@dataclass(frozen=True)
class Flow:
    """Packets from ``route[0]`` to ``route[-1]`` every ``period`` slots, the first at absolute
    slot ``offset`` (``0 <= offset < period``; the packets come at ``offset + k period``)."""

    name: str
    route: tuple[str, ...]
    period: int
    offset: int = 0

    def __post_init__(self) -> None:
        if self.period < 1:
            raise ValueError(f"flow {self.name!r}: the period must be >= 1 slot")
        if len(self.route) < 2:
            raise ValueError(f"flow {self.name!r}: a route has at least two nodes")


@dataclass
class Schedule:
    """Cells of a slotframe of ``length`` slots and ``channels`` channel offsets.

    ``lacking`` maps a link ``(tx, rx)`` to the cells the scheduler could not place for it.
    """

    length: int
    channels: int
    cells: list[Cell] = field(default_factory=list)
    lacking: dict[tuple[str, str], int] = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        return not self.lacking

    def by_slot(self) -> dict[int, list[Cell]]:
        """Slot offset -> its cells, sorted."""
        out: dict[int, list[Cell]] = defaultdict(list)
        for c in sorted(self.cells):
            out[c.slot].append(c)
        return dict(out)

    def cells_per_frame(self) -> dict[tuple[str, str], float]:
        """Link -> cells per slotframe on average (a cell active every ``e`` frames is 1/e)."""
        out: dict[tuple[str, str], float] = defaultdict(float)
        for c in self.cells:
            out[c.link] += 1.0 / c.every
        return dict(sorted(out.items()))

    def describe_lack(self) -> str:
        """``"link r1->gw lacks 2 cells; ..."`` (empty when feasible)."""
        return "; ".join(
            f"link {a}->{b} lacks {n} cell{'s' if n != 1 else ''}"
            for (a, b), n in sorted(self.lacking.items())
        )


def overlap(a: Cell, b: Cell) -> bool:
    """Whether two cells of the same slot offset are ever active in the same slotframe
    (``n = a.phase mod a.every`` and ``n = b.phase mod b.every`` have a common solution)."""
    g = math.gcd(a.every, b.every)
    return (a.phase - b.phase) % g == 0


class _Occupancy:
    """What each slot offset already holds, for the scheduler."""

    def __init__(self, length: int, channels: int, reserved: Iterable[Cell]) -> None:
        self.length = length
        self.channels = channels
        self.slots: dict[int, list[Cell]] = defaultdict(list)
        for c in reserved:
            self.slots[c.slot].append(c)

    def fits(self, probe: Cell) -> int | None:
        """The lowest free channel offset for ``probe`` in its slot, or ``None``."""
        used: set[int] = set()
        for c in self.slots[probe.slot]:
            if not overlap(c, probe):
                continue
            if {c.tx, c.rx} & {probe.tx, probe.rx}:
                return None
            used.add(c.channel)
        free = [k for k in range(self.channels) if k not in used]
        return free[0] if free else None

    def add(self, cell: Cell) -> None:
        self.slots[cell.slot].append(cell)


def build_schedule(
    flows: Sequence[Flow],
    length: int,
    channels: int,
    *,
    retry_cells: int = 1,
    reserved: Sequence[Cell] = (),
) -> Schedule:
    """Chains of cells for every flow (module docstring), flows in name order.

    Parameters
    ----------
    flows : sequence of Flow
        The paths' packets: route (source first) and period in slots.
    length, channels : int
        Slots per slotframe and channel offsets available.
    retry_cells : int
        Extra cells per hop and chain for retransmissions toward the same neighbour.
    reserved : sequence of Cell
        Cells already taken (e.g. shared cells written in the scenario); kept in the schedule.
    """
    if length < 1 or channels < 1:
        raise ValueError("a slotframe needs at least one slot and one channel offset")
    occupancy = _Occupancy(length, channels, reserved)
    schedule = Schedule(length, channels, cells=list(reserved))
    lacking: dict[tuple[str, str], int] = defaultdict(int)
    for flow in sorted(flows, key=lambda f: f.name):
        hops = list(zip(flow.route[:-1], flow.route[1:], strict=True))
        offset = flow.offset % flow.period
        hyper = math.lcm(flow.period, length)  # the chains repeat every hyper slots
        every = hyper // length
        starts = [offset + k * flow.period for k in range(hyper // flow.period)]
        for start in starts:
            position = start  # absolute slot from the chain's slotframe start
            for tx, rx in hops:
                for _ in range(1 + retry_cells):
                    placed = _place(occupancy, tx, rx, position, every, flow.name)
                    if placed is None:
                        lacking[tx, rx] += 1
                        continue
                    cell, position = placed
                    schedule.cells.append(cell)
                    occupancy.add(cell)
                    position += 1
    schedule.cells.sort()
    schedule.lacking = dict(sorted(lacking.items()))
    return schedule


def _place(
    occupancy: _Occupancy, tx: str, rx: str, position: int, every: int, flow: str
) -> tuple[Cell, int] | None:
    """The first cell for ``tx -> rx`` at absolute slot ``position`` or later (within one
    cycle of ``length * every`` slots), and its absolute slot."""
    length = occupancy.length
    for pos in range(position, position + length * every):
        probe = Cell(pos % length, 0, tx, rx, every=every, phase=(pos // length) % every)
        channel = occupancy.fits(probe)
        if channel is not None:
            cell = Cell(probe.slot, channel, tx, rx, every=every, phase=probe.phase, flow=flow)
            return cell, pos
    return None


def check_cells(
    cells: Sequence[Cell], length: int, channels: int, *, where: str = "schedule"
) -> None:
    """Refuse a written schedule that a TSCH network cannot run (``ValueError`` naming the
    cell by its index in ``cells``): offsets out of range, a node in two cells of one slot (the
    receiver of a group of shared cells excepted), two dedicated cells on one (slot, channel
    offset), a shared cell that shares its (slot, channel offset) with another receiver."""
    for i, c in enumerate(cells):
        at = f"{where}[{i}]"
        if not 0 <= c.slot < length:
            raise ValueError(f"{at}.slot: {c.slot} is outside the slotframe (0..{length - 1})")
        if not 0 <= c.channel < channels:
            raise ValueError(
                f"{at}.channel: channel offset {c.channel} is outside 0..{channels - 1} "
                f"({channels} channel offsets)"
            )
        if c.tx == c.rx:
            raise ValueError(f"{at}: a cell joins two different nodes, got {c.tx!r} twice")
        if not 0 <= c.phase < c.every:
            raise ValueError(f"{at}.phase: must be in 0..{c.every - 1}, got {c.phase}")
    by_slot: dict[int, list[tuple[int, Cell]]] = defaultdict(list)
    for i, c in enumerate(cells):
        by_slot[c.slot].append((i, c))
    for slot, members in sorted(by_slot.items()):
        for k, (i, a) in enumerate(members):
            for j, b in members[:k]:
                if not overlap(a, b):
                    continue
                same_group = a.shared and b.shared and a.channel == b.channel and a.rx == b.rx
                if same_group:
                    if a.tx == b.tx:
                        raise ValueError(
                            f"{where}[{i}]: node {a.tx!r} is in two cells of slot {slot} "
                            f"(also {where}[{j}])"
                        )
                    continue
                if a.channel == b.channel:
                    raise ValueError(
                        f"{where}[{i}]: channel offset {a.channel} of slot {slot} is already "
                        f"used by {where}[{j}]"
                    )
                common = {a.tx, a.rx} & {b.tx, b.rx}
                if common:
                    raise ValueError(
                        f"{where}[{i}]: node {sorted(common)[0]!r} is in two cells of slot "
                        f"{slot} (also {where}[{j}])"
                    )


def grant(period: int, length: int) -> int:
    """The period (slots) the manager gives a flow that asks for ``period``: the longest at or
    below it that the slotframe repeats exactly, a multiple of ``length`` or a divisor of it
    (as a WirelessHART manager grants publish periods from its superframes). Periods that are
    neither would need cells of several repetitions in one slot, which a schedule of one
    slotframe length cannot hold without conflicts; a slotframe length with many divisors
    (120, 240) keeps the granted periods close to the asked ones."""
    if period < 1:
        raise ValueError(f"a period is at least one slot, got {period}")
    if period >= length:
        return (period // length) * length
    return max(d for d in range(1, period + 1) if length % d == 0)


def flows_of(
    routes: Mapping[str, Sequence[str] | None],
    periods: Mapping[str, int],
    slot_ticks: int,
    length: int,
    offsets: Mapping[str, int] | None = None,
) -> list[Flow]:
    """One flow per routed path: ``routes`` (path name -> nodes, ``None`` when down),
    ``periods`` (path name -> packet period, ticks; paths without one carry nothing and get
    no cells) and ``offsets`` (path name -> the slot of its next packet, default 0). A period
    becomes whole slots (rounded down, at least one), then the :func:`grant`-ed period."""
    out = []
    for name, route in sorted(routes.items()):
        period = periods.get(name)
        if route is None or period is None or len(route) < 2:
            continue
        granted = grant(max(1, period // slot_ticks), length)
        offset = (offsets or {}).get(name, 0) % granted
        out.append(Flow(name, tuple(route), granted, offset))
    return out


def schedule_for(
    routes: Mapping[str, Sequence[str] | None],
    periods: Mapping[str, int],
    *,
    slot_ticks: int,
    length: int,
    channels: int,
    retry_cells: int,
    written: Sequence[Cell] = (),
    static: bool = False,
    offsets: Mapping[str, int] | None = None,
) -> Schedule:
    """The manager's schedule for these routes and periods: the central scheduler's, around the
    ``written`` cells; or, ``static``, the written cells themselves, a routed link without any
    cell lacking one. What a gateway runs and what the coordination agent asks it."""
    flows = flows_of(routes, periods, slot_ticks, length, offsets)
    if not static:
        return build_schedule(flows, length, channels, retry_cells=retry_cells, reserved=written)
    have = {c.link for c in written}
    lacking: dict[tuple[str, str], int] = {}
    for f in flows:
        for link in zip(f.route[:-1], f.route[1:], strict=True):
            if link not in have:
                lacking[link] = 1
    return Schedule(length, channels, cells=sorted(written), lacking=dict(sorted(lacking.items())))
