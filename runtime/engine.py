"""The direct engine's round loop: behaviours run in one process, round by round, no bus.

:class:`DirectEngine` runs the very behaviours the bus nodes run (:mod:`runtime.direct` builds
them), through the clock's own round logic (:class:`~core.rounds.RoundPlanner`), in the same
order as the bus engines (DESIGN section 3): in round ``r`` each participant, in name order, gets
the messages published in round ``r - 1`` on the keys it listens to, sorted by
``(key, src, seq)``, and its outputs are stamped ``r``; a participant with no message and no
timer due sits the round out (:meth:`~core.behaviour.Behaviour.idle_at`).

A message is handed over in memory: the body object as published when the subscription asks for
its schema (a body is a frozen, validated model: what the bus would decode from msgpack), its
msgpack mapping when the subscription takes raw bodies. So the traces, decisions and assignments
are those of the ``threads`` and ``processes`` engines, bit for bit.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from operator import attrgetter
from typing import Any, NamedTuple

from pydantic import BaseModel

from bus_schemas import codec
from core.behaviour import Behaviour
from core.rounds import RoundPlanner, merge_dropped

__all__ = ["Message", "DirectEngine"]


class _Fields(Mapping[str, Any]):
    """A read-only mapping view of a body's fields."""

    __slots__ = ("_body",)

    def __init__(self, body: BaseModel) -> None:
        self._body = body

    def __getitem__(self, name: str) -> Any:
        try:
            return getattr(self._body, name)
        except AttributeError:
            raise KeyError(name) from None

    def __iter__(self) -> Iterator[str]:
        return iter(type(self._body).model_fields)

    def __len__(self) -> int:
        return len(type(self._body).model_fields)


class Message(NamedTuple):
    """One message passed in memory: what a bus envelope holds, with the body as published.

    A named tuple rather than a frozen dataclass: as immutable, and three times cheaper to make
    (the engine makes one per published message)."""

    key: str  # run-relative
    src: str
    seq: int
    round: int
    t: int
    body: BaseModel

    def mapping(self) -> dict[str, Any]:
        """The body as a bus subscriber of raw bodies gets it (msgpack round trip)."""
        return codec.unpack_mapping(codec.pack_body(self.body))

    def fields(self) -> _Fields:
        """The body's fields by name (no copy, no msgpack round trip: tuples stay tuples)."""
        return _Fields(self.body)

    def body_as(self, body_type: type[BaseModel] | None) -> Any:
        """The body for a subscription of schema ``body_type`` (``None``: raw mapping)."""
        if body_type is None:
            return self.mapping()
        if type(self.body) is body_type:
            return self.body
        return codec.validate_body(self.mapping(), body_type)


class DirectEngine:
    """Runs ``behaviours`` (participant name -> behaviour) to ``end`` (ticks) in memory.

    ``on_round`` is called with each round's messages, already in ``(key, src, seq)`` order
    (the order the historian records them in).
    """

    def __init__(
        self,
        behaviours: Mapping[str, Behaviour],
        *,
        end: int,
        max_microsteps: int,
        max_rounds: int = 100_000_000,
        on_round: Callable[[list[Message]], None] | None = None,
    ) -> None:
        self.behaviours = dict(sorted(behaviours.items()))
        self.planner = RoundPlanner(
            self.behaviours, end, max_microsteps=max_microsteps, max_rounds=max_rounds
        )
        self.on_round = on_round
        self._seq: Counter[str] = Counter()
        self._routes: dict[str, tuple[str, ...]] = {}

    def run(self) -> None:
        """Run every round until the planner finishes, then tell each behaviour the run ended."""
        planner = self.planner
        behaviours = self.behaviours
        next_times: dict[str, int | None] = {n: b.next_time for n, b in behaviours.items()}
        seq = self._seq
        order = attrgetter("key", "src", "seq")
        inbox: list[Message] = []
        while not planner.finished:
            r, t = planner.round, planner.t
            boxes: dict[str, list[tuple[str, Message, Any]]] = {}
            for m in inbox:
                delivery = (m.key, m, m.body_as)
                for name in self._listeners(m.key):
                    if name in boxes:
                        boxes[name].append(delivery)
                    else:
                        boxes[name] = [delivery]
            published: list[Message] = []
            counts: dict[str, int] = {}
            for name, behaviour in behaviours.items():
                mine = boxes.get(name)
                if mine is None and behaviour.idle_at(t):
                    continue  # nothing to do in this round
                outputs, next_times[name] = behaviour.run_round(r, t, mine or ())
                for key, body in outputs:
                    published.append(Message(key, name, seq[name], r, t, body))
                    seq[name] += 1
                    counts[key] = counts.get(key, 0) + 1
            if len(published) > 1:
                published.sort(key=order)
            if self.on_round is not None and published:
                self.on_round(published)
            planner.advance_with(counts, next_times)
            inbox = published
        for behaviour in behaviours.values():
            behaviour.on_stop(True, "")

    def _listeners(self, key: str) -> tuple[str, ...]:
        hit = self._routes.get(key)
        if hit is None:
            hit = tuple(n for n, b in self.behaviours.items() if b.listens_to(key))
            self._routes[key] = hit
        return hit

    def dropped_invalid(self) -> dict[str, int]:
        """Invalid input per key, as the clock merges it (each subscriber sees every message)."""
        return merge_dropped(b.dropped_invalid for b in self.behaviours.values())
