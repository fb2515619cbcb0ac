"""The node base class: one event loop per node, driven by the clock's rounds (DESIGN section 3).

A concrete node declares in ``__init__`` what it listens to (:meth:`Node.subscribe`), its timers
(:meth:`Node.every`, :meth:`Node.at`) and publishes with :meth:`Node.publish`; it never writes a
loop. Each round the base class:

1. waits for ``Tick(r, t, expected)`` and collects, for every expected key matching one of its
   subscriptions, that many messages stamped ``r - 1`` (zenoh gives no order across publishers;
   the counts make delivery complete);
2. calls :meth:`Node.advance_to` (plants integrate lazily in their handlers instead);
3. dispatches the messages in ``(key, src, seq)`` order, never arrival order; a message that fails
   to decode or validate is dropped, counted per key and logged once per key;
4. calls :meth:`Node.after_dispatch`, fires the timers due at ``t``;
5. publishes its outputs stamped ``r``; 6. answers ``Done(r, published, next_time)``.

Zenoh callbacks only put raw samples on one queue; state is touched only by the loop thread.
"""

from __future__ import annotations

import heapq
import logging
import queue
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import zenoh
from pydantic import BaseModel

from bus_schemas import Done, Stop, Tick, codec, keys
from bus_schemas.envelope import RawEnvelope
from runtime.errors import NodeTimeout, ProtocolError, SchemaError
from runtime.scenario import Scenario
from runtime.time import to_units

__all__ = ["NodeContext", "Node"]

log = logging.getLogger(__name__)

Handler = Callable[[RawEnvelope, Any], None]


@dataclass
class NodeContext:
    """Everything a node needs from its process: identity, scenario and bus session."""

    name: str
    run_id: str
    scenario: Scenario
    session: zenoh.Session
    options: dict[str, Any] = field(default_factory=dict)


@dataclass
class _Subscription:
    pattern: str  # run-relative
    keyexpr: zenoh.KeyExpr  # absolute
    body_type: type[BaseModel] | None  # None: the handler gets the raw body mapping
    handler: Handler


@dataclass(order=True)
class _Timer:
    t: int
    order: int
    callback: Callable[[], None] = field(compare=False)
    period: int | None = field(compare=False, default=None)


class _StopRequested(Exception):
    def __init__(self, key: str, payload: bytes) -> None:
        super().__init__(key)
        self.key, self.payload = key, payload


class _Adapter(logging.LoggerAdapter):
    def process(self, msg: Any, kwargs: Any) -> tuple[Any, Any]:
        node: Node = self.extra["node"]  # type: ignore[index]
        return f"[{node.name} r={node.round} t={to_units(node.now):.6f}] {msg}", kwargs


class Node:
    """Base class of every bus participant."""

    def __init__(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        self.name = ctx.name
        self.run_id = ctx.run_id
        self.scenario = ctx.scenario
        # sources whose data messages count: the participants, and the clock (external inputs)
        self.participants = frozenset([*ctx.scenario.participants(), "clock"])
        self.round = -1
        self.now = 0
        self.current_key = ""
        self.log = _Adapter(log, {"node": self})
        self.dropped_invalid: Counter[str] = Counter()
        self._logged_drop: set[str] = set()
        self._subs: list[_Subscription] = []
        self._timers: list[_Timer] = []
        self._timer_order = 0
        self._out: list[tuple[str, BaseModel]] = []
        self._seq = 0
        self._queue: queue.Queue[tuple[str, str, bytes]] = queue.Queue()
        self._pending: dict[int, list[tuple[str, RawEnvelope]]] = {}
        self._seen: set[tuple[str, int]] = set()
        self._match_cache: dict[str, list[_Subscription]] = {}
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._timeout = ctx.scenario.clock.round_timeout_s
        self._backlog: list[tuple[str, str, bytes]] = []

    # -- declarations (call from __init__) -----------------------------------------------------
    def subscribe(self, pattern: str, body_type: type[BaseModel] | None, handler: Handler) -> None:
        """Receive messages on run-relative ``pattern``; ``handler(envelope, body)``."""
        self._subs.append(
            _Subscription(
                pattern, zenoh.KeyExpr(keys.full(self.run_id, pattern)), body_type, handler
            )
        )

    def every(self, period: int, callback: Callable[[], None], *, start: int = 0) -> None:
        """Call ``callback`` at ``start``, ``start + period``, ... (ticks)."""
        if period <= 0:
            raise ValueError(f"{self.name}: timer period must be positive, got {period}")
        self._push_timer(start, callback, period)

    def at(self, t: int, callback: Callable[[], None]) -> None:
        """Call ``callback`` once at time ``t`` (ticks, not in the past)."""
        if t < self.now:
            raise ValueError(f"{self.name}: timer at {t} is before now ({self.now})")
        self._push_timer(t, callback, None)

    def publish(self, rel_key: str, body: BaseModel) -> None:
        """Queue ``body`` on run-relative ``rel_key``; sent stamped with this round."""
        self._out.append((rel_key, body))

    # -- hooks -----------------------------------------------------------------------------------
    def advance_to(self, t: int) -> None:
        """Called at the start of every round, before messages are handled."""

    def after_dispatch(self) -> None:
        """Called every round after the messages are handled and before the timers."""

    def on_tick(self, tick: Tick) -> None:
        """Called with every tick before collection (the historian records it)."""

    def on_stop(self, stop: Stop) -> None:
        """Called once when the clock ends the run."""

    # -- the loop --------------------------------------------------------------------------------
    def run(self) -> int:
        """Serve rounds until the clock stops the run; return the process exit code."""
        session = self.ctx.session
        prefix = keys.run_prefix(self.run_id)
        declared = [
            session.declare_subscriber(f"{prefix}/clock/{leaf}", self._enqueue("control"))
            for leaf in ("tick", "stop")
        ]
        for pattern in sorted({s.pattern for s in self._subs}):
            declared.append(
                session.declare_subscriber(keys.full(self.run_id, pattern), self._enqueue("data"))
            )
        declared.append(
            session.liveliness().declare_subscriber(
                keys.full(self.run_id, keys.alive("clock")), self._on_clock_liveliness
            )
        )
        token = session.liveliness().declare_token(keys.full(self.run_id, keys.alive(self.name)))
        try:
            return self._serve()
        finally:
            # Leaving: the token first (the clock sees us go), subscribers and publishers with the
            # session. Undeclaring the clock-liveliness subscriber here races the clock's own exit
            # and makes zenoh log "Unknown token".
            token.undeclare()
            self._declared = declared  # keep the declarations alive until the session closes

    def _serve(self) -> int:
        while True:
            if self._backlog:
                kind, key, payload = self._backlog.pop(0)
            else:
                try:
                    kind, key, payload = self._queue.get(timeout=self._timeout)
                except queue.Empty:
                    self._check_connected()
                    continue
            if kind == "data":
                self._accept(key, payload)
                continue
            if kind == "clock_gone":
                raise ProtocolError(f"{self.name}: the clock left the run (round {self.round})")
            rel = keys.relative(self.run_id, key)
            try:
                env = codec.decode_envelope(payload)
                if env.src != "clock":
                    raise SchemaError(f"control message from {env.src!r}, expected 'clock'")
                if rel == keys.stop():
                    stop = codec.decode_body(env, Stop)
                    self.on_stop(stop)
                    self.log.info("stopped by the clock: %s", stop.reason or "end of run")
                    return 0
                tick = codec.decode_body(env, Tick)
            except SchemaError as err:
                self._reject(rel, str(err))
                continue
            try:
                self._round_(tick)
            except _StopRequested as stop:
                self._backlog.insert(0, ("control", stop.key, stop.payload))

    def _check_connected(self) -> None:
        """Idle between ticks (real time leaves long gaps): check the router is still there."""
        if self.ctx.session.is_closed() or not list(self.ctx.session.info.routers_zid()):
            raise ProtocolError(
                f"{self.name}: lost the connection to the router (round {self.round})"
            )

    def _round_(self, tick: Tick) -> None:
        if tick.round != self.round + 1 and self.round >= 0:
            raise ProtocolError(f"{self.name}: tick {tick.round} after round {self.round}")
        if tick.t < self.now:
            raise ProtocolError(f"{self.name}: time went back from {self.now} to {tick.t}")
        self.round, self.now = tick.round, tick.t
        self.on_tick(tick)
        inbox = self._collect(tick)
        self.advance_to(tick.t)
        for rel, env in sorted(inbox, key=lambda m: (m[0], m[1].src, m[1].seq)):
            self._dispatch(rel, env)
        self.after_dispatch()
        self._fire_timers(tick.t)
        published = self._flush()
        self._drain_nowait()
        self._put(
            keys.done(self.name),
            Done(
                round=tick.round,
                node=self.name,
                published=published,
                next_time=self._timers[0].t if self._timers else None,
                dropped_invalid=dict(self.dropped_invalid),
            ),
        )

    # -- collection ------------------------------------------------------------------------------
    def _enqueue(self, kind: str) -> Callable[[zenoh.Sample], None]:
        q = self._queue

        def callback(sample: zenoh.Sample) -> None:
            q.put((kind, str(sample.key_expr), sample.payload.to_bytes()))

        return callback

    def abort(self) -> None:
        """Leave the run at the next wait (thread-safe): the launcher's way to stop a node that
        joined after the clock had already stopped the run (it would never see the ``Stop``)."""
        self._queue.put(("clock_gone", "", b""))

    def _on_clock_liveliness(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.DELETE:
            self._queue.put(("clock_gone", "", b""))

    def _matches(self, rel: str) -> list[_Subscription]:
        hit = self._match_cache.get(rel)
        if hit is None:
            ke = zenoh.KeyExpr(keys.full(self.run_id, rel))
            hit = [s for s in self._subs if s.keyexpr.intersects(ke)]
            self._match_cache[rel] = hit
        return hit

    def _accept(self, key: str, payload: bytes) -> None:
        """Check one raw data message and file it under its round (or drop it as invalid)."""
        try:
            rel = keys.relative(self.run_id, key)
        except ValueError:
            return
        if rel.startswith("clock/") or rel == keys.inject():
            return  # the clock's control and the requests it stamps are not data ('**' sees them)
        try:
            env = codec.decode_envelope(payload)
            if env.run != self.run_id:
                raise SchemaError(f"envelope of run {env.run!r} on this run's key")
            if env.src not in self.participants:
                raise SchemaError(f"unknown source {env.src!r}")
            if (env.src, env.seq) in self._seen:
                raise SchemaError(f"duplicate message {env.src}#{env.seq}")
            if env.round < self.round - 1 or (env.round == self.round - 1 and self._collected):
                raise SchemaError(f"stale message of round {env.round} in round {self.round}")
        except SchemaError as err:
            self._reject(rel, str(err))
            return
        self._seen.add((env.src, env.seq))
        self._pending.setdefault(env.round, []).append((rel, env))

    _collected = False

    def _collect(self, tick: Tick) -> list[tuple[str, RawEnvelope]]:
        prev = tick.round - 1
        need = {k: n for k, n in tick.expected.items() if n > 0 and self._matches(k)}
        self._collected = False
        deadline = time.monotonic() + self._timeout
        while True:
            have = Counter(rel for rel, _ in self._pending.get(prev, ()))
            missing = {k: n - have[k] for k, n in need.items() if have[k] < n}
            if not missing:
                break
            remaining = deadline - time.monotonic()
            try:
                kind, key, payload = self._queue.get(timeout=max(remaining, 0.0))
            except queue.Empty:
                raise NodeTimeout(
                    f"{self.name}: round {tick.round}: messages of round {prev} missing after "
                    f"{self._timeout} s: {missing}"
                ) from None
            if kind == "data":
                self._accept(key, payload)
            elif kind == "clock_gone":
                raise ProtocolError(f"{self.name}: the clock left during round {tick.round}")
            elif key.endswith("/" + keys.stop()):
                raise _StopRequested(key, payload)  # a fault elsewhere ended the run
            else:
                self._backlog.append((kind, key, payload))
        inbox = self._pending.pop(prev, [])
        for r in [r for r in self._pending if r < prev]:
            for rel, _ in self._pending.pop(r):
                self._reject(rel, f"stale message of round {r}")
        unexpected = [(rel, env) for rel, env in inbox if rel not in need]
        for rel, env in unexpected:
            self._reject(rel, f"{env.src}#{env.seq} was not announced to the clock")
        self._collected = True
        return [(rel, env) for rel, env in inbox if rel in need]

    def _drain_nowait(self) -> None:
        """Handle data already queued (counts invalid input promptly); keep control messages."""
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if item[0] == "data":
                self._accept(item[1], item[2])
            else:
                self._backlog.append(item)

    def _reject(self, rel: str, reason: str) -> None:
        self.dropped_invalid[rel] += 1
        if rel not in self._logged_drop:
            self._logged_drop.add(rel)
            self.log.warning(
                "dropping invalid message on %s: %s (logged once per key)", rel, reason
            )

    # -- dispatch, timers, output ----------------------------------------------------------------
    def _dispatch(self, rel: str, env: RawEnvelope) -> None:
        self.current_key = rel  # handlers may read the run-relative key they are called for
        for sub in self._matches(rel):
            if sub.body_type is None:
                sub.handler(env, env.body)
                continue
            try:
                body = codec.decode_body(env, sub.body_type)
            except SchemaError as err:
                self._reject(rel, f"{env.src}#{env.seq}: {err}")
                continue
            sub.handler(env, body)

    def _push_timer(self, t: int, callback: Callable[[], None], period: int | None) -> None:
        heapq.heappush(self._timers, _Timer(t, self._timer_order, callback, period))
        self._timer_order += 1

    def _fire_timers(self, t: int) -> None:
        if self._timers and self._timers[0].t < t:
            raise ProtocolError(
                f"{self.name}: timer due at {self._timers[0].t} skipped (clock at {t})"
            )
        while self._timers and self._timers[0].t == t:
            timer = heapq.heappop(self._timers)
            timer.callback()
            if timer.period is not None:
                self._push_timer(t + timer.period, timer.callback, timer.period)

    def _flush(self) -> dict[str, int]:
        counts: Counter[str] = Counter()
        for rel, body in self._out:
            self._put(rel, body)
            counts[rel] += 1
        self._out.clear()
        return dict(counts)

    def _put(self, rel: str, body: BaseModel) -> None:
        pub = self._publishers.get(rel)
        if pub is None:
            pub = self.ctx.session.declare_publisher(
                keys.full(self.run_id, rel),
                encoding=zenoh.Encoding(codec.ENCODING),
                congestion_control=zenoh.CongestionControl.BLOCK,
                reliability=zenoh.Reliability.RELIABLE,
                express=True,
            )
            self._publishers[rel] = pub
        payload = codec.encode(
            run=self.run_id,
            src=self.name,
            seq=self._seq,
            round=max(self.round, 0),
            t=self.now,
            body=body,
        )
        self._seq += 1
        pub.put(payload)
