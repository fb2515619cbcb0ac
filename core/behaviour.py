"""The bus-free half of every node: declarations, timers, ordered dispatch, outputs (DESIGN §3).

A :class:`Behaviour` is what one node kind does at time ``t``. It declares in ``__init__`` what it
listens to (:meth:`Behaviour.subscribe`) and its timers (:meth:`Behaviour.every`,
:meth:`Behaviour.at`), and publishes with :meth:`Behaviour.publish`; it never sees the bus and
never writes a loop. An engine drives it round by round, always in this order::

    behaviour.begin_round(round, t)              # checks the round, sets ``now``
    behaviour.advance_to(t)                      # hook: continuous state to t
    for key, env, body_as in inbox:              # sorted by (key, src, seq), never arrival order
        behaviour.dispatch(key, env, body_as)    # every matching handler; bad input rejected
    outputs, next_time = behaviour.end_round()   # after_dispatch, timers due at t, outputs

:class:`kernel.node.BusNode` does it with the messages it collected from zenoh (bodies decoded
from msgpack); :class:`runtime.direct.DirectEngine` with the messages of the previous round passed
in memory. Both engines therefore run the very same code in the very same order, and their traces
agree bit for bit.

A message that fails to validate against a handler's schema, or that a handler refuses
(:meth:`Behaviour.reject`), is dropped, counted per key and logged once per key: a node never
dies of bad input. A subscription that must *answer* a malformed request (the coordination agent
refuses it with its reason) names an ``on_invalid`` handler instead, which gets the raw body and
the :class:`~bus_schemas.errors.SchemaError` (its ``problems`` name every field that is wrong).
"""

from __future__ import annotations

import heapq
import logging
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, cast

from pydantic import BaseModel

from bus_schemas import keys
from bus_schemas.errors import SchemaError
from core.errors import ProtocolError
from core.time import to_units

__all__ = ["Behaviour", "Timer", "Incoming", "BodyAs", "Handler", "InvalidHandler", "Output"]

log = logging.getLogger(__name__)


class Incoming(Protocol):
    """What a handler learns of a message besides its body (a bus envelope has all of it)."""

    @property
    def src(self) -> str: ...

    @property
    def seq(self) -> int: ...

    @property
    def round(self) -> int: ...

    @property
    def t(self) -> int: ...


Handler = Callable[[Any, Any], None]
"""``handler(envelope, body)``: the body as the subscription's schema, or the raw mapping."""

InvalidHandler = Callable[[Any, Any, SchemaError], None]
"""``on_invalid(envelope, raw body, error)``: a body that does not fit the subscription's schema
(the raw body as the engine has it: a mapping, or whatever else was sent)."""

BodyAs = Callable[[type[BaseModel] | None], Any]
"""How an engine hands over a message's body: validated as a schema, or raw (``None``); raises
:class:`~bus_schemas.errors.SchemaError` when the body does not fit the schema."""

Output = tuple[str, BaseModel]
"""One published message: run-relative key and body."""


@dataclass
class _Subscription:
    pattern: str  # run-relative
    body_type: type[BaseModel] | None  # None: the handler gets the raw body mapping
    handler: Handler
    on_invalid: InvalidHandler | None = None


class Timer:
    """A periodic timer of a behaviour (:meth:`Behaviour.every`) whose period may change while
    it runs: a sensor told to sample at a new rate, a link told to transmit at a new period.

    It fires at ``start`` and then every period, as one-off timers (:meth:`Behaviour.at`), each
    firing scheduling the next after its callback. :meth:`retime` keeps the phase of the last
    firing: the next one is a new period after it, or now if that has passed (a period after
    now if it fired in this instant); a firing scheduled before the change is stale and does
    nothing (each scheduling carries a generation). :meth:`cancel` makes every pending firing
    stale.
    """

    def __init__(
        self,
        behaviour: Behaviour,
        period: int,
        callback: Callable[[], None],
        *,
        start: int = 0,
        end: int | None = None,
    ) -> None:
        if period <= 0:
            raise ValueError(f"{behaviour.name}: timer period must be positive, got {period}")
        self.behaviour = behaviour
        self.period = period
        self.callback = callback
        self.end = end
        self.last: int | None = None
        """When it last fired (ticks), ``None`` before its first firing."""
        self._generation = 0
        self._schedule(start)

    def retime(self, period: int) -> bool:
        """Fire every ``period`` ticks from now on, keeping the last firing's phase (see the
        class docstring); whether the period changed."""
        if period <= 0:
            raise ValueError(f"{self.behaviour.name}: timer period must be positive, got {period}")
        if period == self.period:
            return False
        self.period = period
        self._generation += 1
        now = self.behaviour.now
        nxt = now if self.last is None else max(self.last + period, now)
        if self.last == now:
            nxt = now + period  # fired in this instant already
        self._schedule(nxt)
        return True

    def cancel(self) -> None:
        """Fire no more (the pending firing is stale)."""
        self._generation += 1

    def _schedule(self, t: int) -> None:
        if self.end is None or t <= self.end:
            self.behaviour.at(t, self._firing(self._generation))

    def _firing(self, generation: int) -> Callable[[], None]:
        def fire() -> None:
            if generation != self._generation:
                return  # retimed or cancelled since it was scheduled
            self.callback()
            self.last = self.behaviour.now
            self._schedule(self.behaviour.now + self.period)

        return fire


@dataclass(order=True)
class _Timer:
    t: int
    order: int
    callback: Callable[[], None] = field(compare=False)


class _Adapter(logging.LoggerAdapter):  # type: ignore[type-arg]
    def process(self, msg: Any, kwargs: Any) -> tuple[Any, Any]:
        node = cast("Behaviour", self.extra["node"])  # type: ignore[index]
        return f"[{node.name} r={node.round} t={to_units(node.now):.6f}] {msg}", kwargs


class Behaviour:
    """Base class of what a node kind does, run by every engine (see the module docstring)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.round = -1
        self.now = 0
        self.current_key = ""
        self.log = _Adapter(log, {"node": self})
        self.dropped_invalid: Counter[str] = Counter()
        self._logged_drop: set[str] = set()
        self._subs: list[_Subscription] = []
        self._timers: list[_Timer] = []
        self._timer_order = 0
        self._out: list[Output] = []
        self._match_cache: dict[str, list[_Subscription]] = {}

    # -- declarations (call from __init__) -----------------------------------------------------
    def subscribe(
        self,
        pattern: str,
        body_type: type[BaseModel] | None,
        handler: Handler,
        *,
        on_invalid: InvalidHandler | None = None,
    ) -> None:
        """Receive messages on run-relative ``pattern``: ``handler(envelope, body)`` with the body
        validated as ``body_type`` (``None``: the raw mapping). A body that does not validate is
        dropped and counted (:meth:`reject`), or, with ``on_invalid``, handed to
        ``on_invalid(envelope, raw body, error)`` to answer."""
        self._subs.append(_Subscription(pattern, body_type, handler, on_invalid))
        self._match_cache.clear()

    def every(
        self,
        period: int,
        callback: Callable[[], None],
        *,
        start: int = 0,
        end: int | None = None,
    ) -> Timer:
        """Call ``callback`` at ``start``, ``start + period``, ... (ticks), up to ``end``
        (``None``: to the run's end); the :class:`Timer` returned may be retimed or cancelled."""
        return Timer(self, period, callback, start=start, end=end)

    def at(self, t: int, callback: Callable[[], None]) -> None:
        """Call ``callback`` once at time ``t`` (ticks, not in the past)."""
        if t < self.now:
            raise ValueError(f"{self.name}: timer at {t} is before now ({self.now})")
        self._push_timer(t, callback)

    def publish(self, rel_key: str, body: BaseModel) -> None:
        """Queue ``body`` on run-relative ``rel_key``; sent stamped with this round."""
        self._out.append((rel_key, body))

    def reject(self, rel: str, reason: str, count: int = 1) -> None:
        """Drop ``count`` invalid messages on ``rel`` (``reason``: the first's): counted per key,
        logged once per key."""
        self.dropped_invalid[rel] += count
        if rel not in self._logged_drop:
            self._logged_drop.add(rel)
            self.log.warning(
                "dropping invalid message on %s: %s (logged once per key)", rel, reason
            )

    # -- hooks -----------------------------------------------------------------------------------
    def advance_to(self, t: int) -> None:
        """Called at the start of every round, before messages are handled."""

    def after_dispatch(self) -> None:
        """Called every round after the messages are handled and before the timers."""

    def on_stop(self, ok: bool, reason: str) -> None:
        """Called once when the run ends."""

    # -- what the engines call -------------------------------------------------------------------
    @property
    def patterns(self) -> list[str]:
        """The run-relative key expressions this behaviour listens to, sorted, once each."""
        return sorted({s.pattern for s in self._subs})

    @property
    def next_time(self) -> int | None:
        """The time of the earliest pending timer (ticks), or ``None``."""
        return self._timers[0].t if self._timers else None

    def idle_at(self, t: int) -> bool:
        """Whether a round at ``t`` with no message for this behaviour would change nothing: no
        timer is due then. The hooks (:meth:`advance_to`, :meth:`after_dispatch`) must do
        nothing in such a round — which is what lets the direct engine skip it (sparse rounds,
        DESIGN section 3)."""
        return not self._timers or self._timers[0].t != t

    def listens_to(self, rel: str) -> bool:
        """Whether a message on concrete run-relative key ``rel`` reaches a handler."""
        return bool(self._matches(rel))

    def begin_round(self, round_: int, t: int) -> None:
        """Enter round ``round_`` at time ``t`` (ticks); rounds only go on, time never goes
        back. An engine may leave out the rounds in which a behaviour has nothing to do (see
        :meth:`idle_at`)."""
        if round_ <= self.round:
            raise ProtocolError(f"{self.name}: tick {round_} after round {self.round}")
        if t < self.now:
            raise ProtocolError(f"{self.name}: time went back from {self.now} to {t}")
        self.round, self.now = round_, t

    def dispatch(self, rel: str, env: Incoming, body_as: BodyAs) -> None:
        """Hand one message to every handler subscribed to ``rel``."""
        self.current_key = rel  # handlers may read the run-relative key they are called for
        for sub in self._matches(rel):
            try:
                body = body_as(sub.body_type)
            except SchemaError as err:
                if sub.on_invalid is None:
                    self.reject(rel, f"{env.src}#{env.seq}: {err}")
                else:  # answered, not dropped
                    sub.on_invalid(env, body_as(None), err)
                continue
            sub.handler(env, body)

    def end_round(self) -> tuple[list[Output], int | None]:
        """Finish the round: :meth:`after_dispatch`, the timers due now, then the outputs (in
        the order published) and the time of the next timer."""
        self.after_dispatch()
        self._fire_timers(self.now)
        out, self._out = self._out, []
        return out, self.next_time

    def run_round(
        self, round_: int, t: int, inbox: Sequence[tuple[str, Incoming, BodyAs]]
    ) -> tuple[list[Output], int | None]:
        """One whole round: :meth:`begin_round`, :meth:`advance_to`, :meth:`dispatch` of
        ``inbox`` (already in ``(key, src, seq)`` order), :meth:`end_round`."""
        self.begin_round(round_, t)
        self.advance_to(t)
        for rel, env, body_as in inbox:
            self.dispatch(rel, env, body_as)
        return self.end_round()

    # -- internals -------------------------------------------------------------------------------
    def _matches(self, rel: str) -> list[_Subscription]:
        hit = self._match_cache.get(rel)
        if hit is None:
            hit = [s for s in self._subs if keys.intersects(s.pattern, rel)]
            self._match_cache[rel] = hit
        return hit

    def _push_timer(self, t: int, callback: Callable[[], None]) -> None:
        heapq.heappush(self._timers, _Timer(t, self._timer_order, callback))
        self._timer_order += 1

    def _fire_timers(self, t: int) -> None:
        if self._timers and self._timers[0].t < t:
            raise ProtocolError(
                f"{self.name}: timer due at {self._timers[0].t} skipped (clock at {t})"
            )
        while self._timers and self._timers[0].t == t:
            heapq.heappop(self._timers).callback()
