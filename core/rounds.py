"""Which round comes next: the clock's pure logic, shared by the bus clock and the direct engine.

DESIGN section 3: a round that published anything is followed by a microstep at the same time;
otherwise time jumps to the earliest ``next_time`` any participant reported (next-event advance).
The run ends when that time is past ``end`` (ticks) or no participant has anything pending.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Protocol

from bus_schemas import Tick, keys
from core.errors import ProtocolError
from core.time import to_units

__all__ = ["RoundPlanner", "RoundReport", "Participation", "merge_dropped"]


class RoundReport(Protocol):
    """What the planner reads of a participant's answer to a round (a bus ``Done`` has it)."""

    @property
    def round(self) -> int: ...

    @property
    def node(self) -> str: ...

    @property
    def published(self) -> Mapping[str, int]: ...

    @property
    def next_time(self) -> int | None: ...


def merge_dropped(counts: Iterable[Mapping[str, int]]) -> dict[str, int]:
    """The run's invalid input per key from every participant's counts: the largest, since each
    subscriber of a key sees every message on it."""
    merged: dict[str, int] = {}
    for per_key in counts:
        for key, n in per_key.items():
            merged[key] = max(merged.get(key, 0), n)
    return dict(sorted(merged.items()))


class RoundPlanner:
    """Which round comes next (see the module docstring)."""

    def __init__(
        self,
        participants: Iterable[str],
        end: int,
        *,
        max_microsteps: int,
        max_rounds: int = 100_000_000,
    ) -> None:
        self.participants = frozenset(participants)
        self.end = end
        self.max_microsteps = max_microsteps
        self.max_rounds = max_rounds
        self.round = 0
        self.t = 0
        self.expected: dict[str, int] = {}
        self.microsteps = 0
        self.finished = False

    def tick(self) -> Tick:
        """The current round as the clock announces it."""
        return Tick(round=self.round, t=self.t, expected=dict(sorted(self.expected.items())))

    def advance(self, dones: Mapping[str, RoundReport]) -> None:
        """Digest every participant's answer to the current round."""
        missing = self.participants - set(dones)
        if missing:
            raise ProtocolError(f"round {self.round}: no Done from {sorted(missing)}")
        published: dict[str, int] = {}
        for done in dones.values():
            if done.round != self.round:
                raise ProtocolError(f"{done.node}: Done of round {done.round} in {self.round}")
            for key, n in done.published.items():
                published[key] = published.get(key, 0) + n
        self.advance_with(published, {d.node: d.next_time for d in dones.values()})

    def advance_with(self, published: dict[str, int], next_times: Mapping[str, int | None]) -> None:
        """Move on, given the round's published counts per key and each participant's next
        timer (``None``: none): a microstep if anything was published, else next-event
        advance. More than ``max_rounds`` rounds is an error (a run that would never end)."""
        if self.round + 1 >= self.max_rounds:
            raise ProtocolError(
                f"round {self.round}: the run reached clock.max_rounds ({self.max_rounds}) at "
                f"t = {to_units(self.t)}; shorten end_time or raise clock.max_rounds"
            )
        if published:
            self.microsteps += 1
            if self.microsteps > self.max_microsteps:
                raise ProtocolError(
                    f"round {self.round}: more than {self.max_microsteps} microsteps at "
                    f"t = {to_units(self.t)} (a zero-delay cycle?)"
                )
        else:
            pending = [t for t in next_times.values() if t is not None]
            nxt = min(pending) if pending else None
            if nxt is None or nxt > self.end:
                self.finished = True
                return
            if nxt <= self.t:
                late = sorted(n for n, t in next_times.items() if t == nxt)
                raise ProtocolError(
                    f"round {self.round}: {late} report next_time {nxt} <= {self.t}"
                )
            self.t = nxt
            self.microsteps = 0
        self.round += 1
        self.expected = published


class Participation:
    """Who takes part in a round (sparse rounds, DESIGN section 3): a participant whose timer is
    due at the round's time, or one subscribed to a key on which the previous round published.
    The others would change nothing in it (:meth:`core.behaviour.Behaviour.idle_at`, which lets
    the direct engine skip the same rounds), so the clock does not tick them and waits for no
    ``Done`` from them; their last ``next_time`` stands.

    Parameters
    ----------
    participants : iterable of str
        Every participant of the run.
    """

    def __init__(self, participants: Iterable[str]) -> None:
        self.participants = frozenset(participants)
        self.listens: dict[str, tuple[str, ...]] = {}
        self.next_times: dict[str, int | None] = {n: None for n in self.participants}
        self._routes: dict[str, frozenset[str]] = {}

    def learn(self, node: str, next_time: int | None, listens: Iterable[str] | None) -> None:
        """A participant's answer: its next timer and (in round 0) its subscriptions."""
        self.next_times[node] = next_time
        if listens is not None:
            self.listens[node] = tuple(listens)
            self._routes.clear()

    def listeners(self, key: str) -> frozenset[str]:
        """The participants subscribed to concrete key ``key`` (unknown ones count as listening)."""
        hit = self._routes.get(key)
        if hit is None:
            hit = frozenset(
                n
                for n in self.participants
                if n not in self.listens or any(keys.intersects(p, key) for p in self.listens[n])
            )
            self._routes[key] = hit
        return hit

    def of(self, t: int, expected: Mapping[str, int]) -> frozenset[str]:
        """Who takes part in a round at ``t`` announcing ``expected``."""
        who = {n for n, nt in self.next_times.items() if nt == t}
        for key, n in expected.items():
            if n > 0:
                who |= self.listeners(key)
        return frozenset(who) & self.participants

    def drop(self, node: str) -> None:
        """A participant left the run (dropped by the clock)."""
        self.participants = self.participants - {node}
        self.next_times.pop(node, None)
        self._routes.clear()
