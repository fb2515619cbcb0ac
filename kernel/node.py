"""The bus node: runs one behaviour on the bus, driven by the clock's rounds (DESIGN section 3).

What a node does lives in its :class:`~core.behaviour.Behaviour` (bus-free, shared with the
direct engine); this class only moves its messages. Each round it:

1. waits for ``Tick(r, t, expected, digests)`` and collects, for every expected key matching
   one of the behaviour's subscriptions, the messages stamped ``r - 1`` whose digests
   (:func:`bus_schemas.codec.digest`) the tick announces: zenoh gives no order across
   publishers, and the digests make delivery complete. Only the announced messages count: a
   forged one, even in a well-formed envelope from the key's owner (an ``--insecure`` run),
   cannot let a round start without the genuine one; it is dropped and counted;
2. runs the behaviour's round (:meth:`~core.behaviour.Behaviour.run_round`) with them in
   ``(key, src, seq)`` order, never arrival order; a message that fails to decode or validate is
   dropped, counted per key and logged once per key;
3. publishes the behaviour's outputs stamped ``r`` and answers ``Done(r, published, digests,
   next_time)``
   (an observer, :attr:`BusNode.observer`, only in the rounds it is ticked for).

Threads: zenoh-python calls each subscriber's callback in a thread of its own, one sample after
the other. A node runs its rounds in its tick subscriber's thread (:meth:`BusNode._on_tick`):
a hop to another thread would cost a wake-up (about 40 us, and a round has several:
``bench/round_budget.py``). Its loop thread (:meth:`BusNode.run`) takes the stop and the
clock's departure, ends a round under way (through the queue the round's collection waits on)
and raises what a round failed with. The behaviour is touched by one thread at a time (the
node's ``_busy`` lock, held for a round). A data message the callback checks and files under
its round itself (:meth:`BusNode._on_data`, under the node's lock), and wakes the round only
when the messages it waits for are complete. What a callback refuses is counted in the round
(before ``Done``). An observer runs its rounds in the loop thread, from the clock's log.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import zenoh
from pydantic import BaseModel

from bus_schemas import Done, Stop, Tick, TickLog, Working, codec, keys
from bus_schemas.envelope import RawEnvelope
from bus_schemas.errors import SchemaError
from core.behaviour import Behaviour
from core.errors import NodeTimeout, ProtocolError
from kernel.heartbeat import Heartbeat, beat_interval

__all__ = ["NodeContext", "BusNode"]

log = logging.getLogger(__name__)

_OWNER_CACHE = 10_000
"""Concrete keys whose owners a node remembers (a run has far fewer)."""

_AHEAD = 1_000
"""Rounds a data message may be ahead of the node's last tick and still be kept for its round.
A message stamped ``s`` is published after tick ``s`` reached its publisher, and a subscriber of
its key takes part in round ``s + 1``, so the clock cannot tick far past it; but zenoh orders
nothing across publishers, and a node that sat rounds out sees a later round's data before the
ticks in between (measured: 3 rounds ahead in a clean benchmark run on a loaded machine, which a
window of ``[r - 1, r + 1]`` turns into a stalled run). Anything further ahead than this is
forged: dropped and counted, never kept."""

_PENDING_MAX = 100_000
"""Messages a node keeps for rounds it has not collected yet; past that, dropped and counted
(a forged flood inside the window must not fill memory either)."""


@dataclass
class NodeContext:
    """What a node needs from its process: identity, the run's participants and the bus."""

    name: str
    run_id: str
    session: zenoh.Session
    participants: frozenset[str]
    round_timeout_s: float
    options: dict[str, Any] = field(default_factory=dict)
    publishers: Mapping[str, tuple[str, ...]] | None = None
    """Publisher -> the run-relative key expressions it owns; ``None``: any participant (or the
    clock) may publish on any key."""
    heartbeat: Heartbeat | None = None
    """The process's heartbeat thread, shared by its nodes (:mod:`kernel.heartbeat`); ``None``:
    the node runs one of its own, beating every :func:`~kernel.heartbeat.beat_interval` of
    ``round_timeout_s``."""


class _StopRequested(Exception):
    def __init__(self, key: str, payload: bytes) -> None:
        super().__init__(key)
        self.key, self.payload = key, payload


def _raw(env: RawEnvelope) -> Callable[[type[BaseModel] | None], Any]:
    def body_as(body_type: type[BaseModel] | None) -> Any:
        return env.body if body_type is None else codec.decode_body(env, body_type)

    return body_as


class BusNode:
    """Runs ``behaviour`` as bus participant ``ctx.name`` (see the module docstring)."""

    def __init__(self, ctx: NodeContext, behaviour: Behaviour) -> None:
        self.ctx = ctx
        self.behaviour = behaviour
        self.name = ctx.name
        self.run_id = ctx.run_id
        # sources whose data messages count: the participants, and the clock (external inputs)
        self.participants = frozenset([*ctx.participants, "clock"])
        self.log = behaviour.log
        self._seq = 0
        self._queue: queue.Queue[tuple[str, str, bytes]] = queue.Queue()
        self._pending: dict[int, list[tuple[str, RawEnvelope, int]]] = {}  # (key, env, digest)
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._timeout = ctx.round_timeout_s
        self._backlog: list[tuple[str, str, bytes]] = []
        self._declared: list[Any] = []
        self._last_tick = -1  # every tick counts, the rounds this node sat out too
        self._owners: dict[str, frozenset[str]] = {}  # concrete key -> sources that own it
        self._n_pending = 0  # messages in self._pending
        # shared with the data callback (_on_data), under _lock: _pending, _filed, _n_pending,
        # _owners, _last_tick, _collected, _awaiting, _rejected
        self._lock = threading.Lock()
        self._filed: dict[int, dict[str, set[int]]] = {}  # round -> key -> digests filed
        # (round, key -> digests) the loop waits on
        self._awaiting: tuple[int, Mapping[str, tuple[int, ...]]] | None = None
        self._rejected: dict[str, tuple[int, str]] = {}  # key -> (count, first reason) to report
        # A node's rounds run in its tick subscriber's callback thread (an observer's in the
        # loop's): _busy is held for each round and by the loop while it touches the behaviour
        # (the stop); _wake is what a round's collection waits on (the data callbacks' "ready",
        # the stop, the clock gone); _over: no more rounds (set under _busy, but when the loop
        # exits, which cannot wait for a hung round); _failure: why a round failed, for the
        # loop to raise.
        self._busy = threading.Lock()
        self._wake: queue.Queue[tuple[str, str, bytes]] = (
            self._queue if self.observer else queue.Queue()
        )
        self._over = False
        self._failure: BaseException | None = None
        # (round, t, began) of the round this node is answering, for the heartbeat's thread
        # (one tuple, written whole); the beats' own sequence numbers (only that thread's)
        self._working: tuple[int, int, float] | None = None
        self._beat_seq = 0

    observer = False
    """Whether the node observes every round (:attr:`kernel.clock.ClockSpec.observers`: the
    historian): it takes every tick from the clock's log (``clock/log``, a few times a second,
    the ``Stop`` last), collects and handles each round's messages, and answers (``Done``) only
    the rounds it is ticked for, the clock's sync rounds. The others take only their ticks
    (``clock/tick/<name>``): those of the rounds they take part in, and one every
    :data:`kernel.clock.SYNC_ROUNDS` rounds; and the stop (``clock/stop``)."""

    @property
    def _control_keys(self) -> tuple[str, ...]:
        """The run-relative keys of the clock's messages to this node."""
        return (keys.tick_log(),) if self.observer else (keys.tick_to(self.name), keys.stop())

    @property
    def round(self) -> int:
        return self.behaviour.round

    @property
    def dropped_invalid(self) -> Counter[str]:
        return self.behaviour.dropped_invalid

    def on_tick(self, tick: Tick) -> None:
        """Called with every tick before collection (the historian records it)."""

    def on_handled(self) -> None:
        """Called after the ticks of one message of the clock (a log: several) are handled."""

    def on_stop(self, stop: Stop) -> None:
        """Called once when the clock ends the run."""
        self.behaviour.on_stop(stop.ok, stop.reason)

    # -- the loop --------------------------------------------------------------------------------
    def run(self) -> int:
        """Serve rounds until the clock stops the run; return the process exit code."""
        session = self.ctx.session
        declared = [
            session.declare_subscriber(
                keys.full(self.run_id, rel),
                self._on_tick if rel == keys.tick_to(self.name) else self._on_control,
            )
            for rel in self._control_keys
        ]
        data = [
            session.declare_subscriber(keys.full(self.run_id, pattern), self._on_data)
            for pattern in self.behaviour.patterns
        ]
        declared.append(
            session.liveliness().declare_subscriber(
                keys.full(self.run_id, keys.alive("clock")),
                self._on_clock_liveliness,
            )
        )
        token = session.liveliness().declare_token(keys.full(self.run_id, keys.alive(self.name)))
        heartbeat = self.ctx.heartbeat or Heartbeat(beat_interval(self.ctx.round_timeout_s))
        try:
            with heartbeat.watching(self):
                return self._serve()
        finally:
            self._over = True  # no round after this; one under way stops waiting
            self._interrupt_round("clock_gone")
            # Leaving: the token first (the clock sees us go), then the data subscriptions (the
            # threads engine's session outlives a node that leaves early: they would file
            # messages for nobody), the rest with the session. Undeclaring the clock-liveliness
            # subscriber here races the clock's own exit and makes zenoh log "Unknown token".
            token.undeclare()
            for sub in data:
                sub.undeclare()
            self._declared = declared  # keep the declarations alive until the session closes

    @property
    def working(self) -> tuple[int, int, float] | None:
        """``(round, t, began)`` of the round under way that this node answers, ``None`` between
        rounds (:class:`kernel.heartbeat.Worker`)."""
        return self._working

    def beat(self, round_: int, t: int, busy_s: float) -> None:
        """Tell the clock this node is still working on round ``round_`` (the heartbeat's
        thread calls it while a round lasts longer than a beat: :mod:`kernel.heartbeat`)."""
        payload = codec.encode(
            run=self.run_id,
            src=self.name,
            seq=self._beat_seq,
            round=round_,
            t=t,
            body=Working(round=round_, node=self.name, busy_s=busy_s),
        )
        self._beat_seq += 1
        self.ctx.session.put(
            keys.full(self.run_id, keys.working(self.name)),
            payload,
            encoding=zenoh.Encoding(codec.ENCODING),
        )

    def _serve(self) -> int:
        while True:
            if self._backlog:
                kind, key, payload = self._backlog.pop(0)
            else:
                try:
                    kind, key, payload = self._queue.get(timeout=self._timeout)
                except queue.Empty:
                    if self._busy.acquire(blocking=False):  # no round under way
                        try:
                            self._flush_rejections()
                        finally:
                            self._busy.release()
                    self._check_connected()
                    continue
            if kind == "ready":
                continue  # a collection's wake-up that came after the collection ended
            if kind == "clock_gone":
                raise ProtocolError(f"{self.name}: the clock left the run (round {self.round})")
            if kind == "failed":
                assert self._failure is not None
                raise self._failure
            rel = keys.relative(self.run_id, key)
            try:
                if rel not in self._control_keys:
                    raise SchemaError("not a key of the clock's messages to this node")
                env = self._control(payload)
                if rel == keys.tick_log():
                    log_ = codec.decode_body(env, TickLog)
                    ticks, stop = log_.ticks, log_.stop
                elif rel == keys.stop():
                    ticks, stop = (), codec.decode_body(env, Stop)
                else:
                    ticks, stop = (codec.decode_body(env, Tick),), None
            except SchemaError as err:
                with self._busy:
                    self._reject(rel, str(err))
                continue
            if stop is not None:
                self._interrupt_round("stop", key, payload)  # a round under way ends now
            try:
                for tick in ticks:  # an observer's, from the clock's log
                    self._round_(tick)
            except _StopRequested as request:
                self._backlog.insert(0, ("control", request.key, request.payload))
                continue
            finally:
                self.on_handled()
            if stop is not None:
                with self._busy:
                    self._over = True
                    self.on_stop(stop)
                self.log.info("stopped by the clock: %s", stop.reason or "end of run")
                return 0

    def _control(self, payload: bytes) -> RawEnvelope:
        """The envelope of a control message, if it is the clock's of this run (else
        ``SchemaError``)."""
        env = codec.decode_envelope(payload)
        if env.src != "clock":
            raise SchemaError(f"control message from {env.src!r}, expected 'clock'")
        if env.run != self.run_id:
            raise SchemaError(f"control message of run {env.run!r} on this run's key")
        return env

    def _is_stop(self, key: str, payload: bytes) -> bool:
        """Whether a message on ``clock/stop`` is the clock's stop; anything else is dropped and
        counted (garbage there must not make a node leave its round without a ``Done``)."""
        try:
            codec.decode_body(self._control(payload), Stop)
        except SchemaError as err:
            self._reject(keys.relative(self.run_id, key), str(err))
            return False
        return True

    def _check_connected(self) -> None:
        """Idle between ticks (real time leaves long gaps): check the router is still there."""
        if self.ctx.session.is_closed() or not list(self.ctx.session.info.routers_zid()):
            raise ProtocolError(
                f"{self.name}: lost the connection to the router (round {self.round})"
            )

    def _round_(self, tick: Tick) -> None:
        if tick.round <= self._last_tick or (self.observer and tick.round != self._last_tick + 1):
            raise ProtocolError(f"{self.name}: tick {tick.round} after round {self._last_tick}")
        answers = tick.participants is None or self.name in tick.participants
        with self._lock:
            self._last_tick = tick.round
            if answers or self.observer:
                self._collected = False  # round r - 1's messages still count
        if not (answers or self.observer):
            self.on_tick(tick)  # sparse rounds: nothing to collect, no timer due, no Done
            return
        if not answers:
            self._work(tick, answers=False)  # an observer between sync rounds: no one waits
            return
        self._working = (tick.round, tick.t, time.monotonic())
        try:
            self._work(tick, answers=True)
        finally:
            self._working = None

    def _work(self, tick: Tick, *, answers: bool) -> None:
        """Round ``tick``: collect, handle, publish, and answer (``Done``) if ``answers``."""
        self.behaviour.begin_round(tick.round, tick.t)
        self.on_tick(tick)
        inbox = self._collect(tick)
        ordered = sorted(inbox, key=lambda m: (m[0], m[1].src, m[1].seq))
        self.behaviour.advance_to(tick.t)
        for rel, env in ordered:
            self.behaviour.dispatch(rel, env, _raw(env))
        outputs, next_time = self.behaviour.end_round()
        digests: dict[str, list[int]] = {}
        for rel, body in outputs:
            digests.setdefault(rel, []).append(self._put(rel, body))
        self._flush_rejections()
        if not answers:
            return  # an observer between sync rounds
        self._put(
            keys.done(self.name),
            Done(
                round=tick.round,
                node=self.name,
                published={k: len(v) for k, v in digests.items()},
                digests={k: tuple(v) for k, v in digests.items()},
                next_time=next_time,
                dropped_invalid=dict(self.dropped_invalid),
                listens=tuple(self.behaviour.patterns) if tick.round == 0 else None,
            ),
        )

    # -- collection ------------------------------------------------------------------------------
    def _on_control(self, sample: zenoh.Sample) -> None:
        """Zenoh's callback for the clock's tick or stop: onto the loop's queue."""
        self._queue.put(("control", str(sample.key_expr), sample.payload.to_bytes()))

    def _on_data(self, sample: zenoh.Sample) -> None:
        """Zenoh's callback for a data message: check it and file it under its round; wake the
        loop if this completes the round it waits for."""
        key, payload = str(sample.key_expr), sample.payload.to_bytes()
        with self._lock:
            self._accept(key, payload)
            if self._awaiting is not None and not self._missing(*self._awaiting):
                self._awaiting = None
                self._wake.put(("ready", "", b""))

    def _on_tick(self, sample: zenoh.Sample) -> None:
        """Zenoh's callback for this node's tick: runs the round in zenoh's thread for the
        subscriber (one thread wake-up less per tick than a hop to the loop's thread; zenoh
        calls it for one tick after the other). What fails is handed to the loop to raise; a
        stop that ends the round (``_StopRequested``) the loop has too."""
        key, payload = str(sample.key_expr), sample.payload.to_bytes()
        with self._busy:
            if self._over:
                return
            try:
                tick = codec.decode_body(self._control(payload), Tick)
            except SchemaError as err:
                self._reject(keys.relative(self.run_id, key), str(err))
                return
            try:
                self._round_(tick)
            except _StopRequested:
                return
            except BaseException as err:  # noqa: BLE001 - the loop raises it
                self._over, self._failure = True, err
                self._queue.put(("failed", "", b""))

    def abort(self) -> None:
        """Leave the run at the next wait (thread-safe): the launcher's way to stop a node that
        joined after the clock had already stopped the run (it would never see the ``Stop``)."""
        self._leave()

    def _on_clock_liveliness(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.DELETE:
            self._leave()

    def _leave(self) -> None:
        """The clock is gone (or the launcher says so): the loop raises, a round under way
        ends."""
        self._queue.put(("clock_gone", "", b""))
        self._interrupt_round("clock_gone")

    def _interrupt_round(self, kind: str, key: str = "", payload: bytes = b"") -> None:
        """End a round under way in the tick's callback (:meth:`_on_tick`): its collection
        waits on ``_wake``. An observer's rounds run in the loop, which has the message
        already."""
        if self._wake is not self._queue:
            self._wake.put((kind, key, payload))

    def _accept(self, key: str, payload: bytes) -> None:
        """Check one raw data message and file it under its round (or drop it as invalid; the
        loop counts it). Called with the lock held."""
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
            if env.src not in self._owners_of(rel):
                raise SchemaError(f"{env.src!r} does not publish on this key")
            digest = codec.digest(payload)
            if digest in self._filed.get(env.round, {}).get(rel, ()):
                raise SchemaError(f"duplicate message {env.src}#{env.seq}")
            now = self._last_tick
            if env.round < now - 1 or (env.round == now - 1 and self._collected):
                raise SchemaError(f"stale message of round {env.round} in round {now}")
            if env.round > now + _AHEAD:  # a forged future must not fill our memory
                raise SchemaError(f"message of round {env.round} ahead of round {now}")
            if self._n_pending >= _PENDING_MAX:
                raise SchemaError(f"{_PENDING_MAX} messages already wait for their rounds")
        except SchemaError as err:
            n, reason = self._rejected.get(rel, (0, str(err)))
            self._rejected[rel] = (n + 1, reason)
            return
        self._pending.setdefault(env.round, []).append((rel, env, digest))
        self._filed.setdefault(env.round, {}).setdefault(rel, set()).add(digest)
        self._n_pending += 1

    def _missing(self, prev: int, need: Mapping[str, tuple[int, ...]]) -> dict[str, int]:
        """How many of the messages of round ``prev`` announced on each key of ``need`` (by
        their digests) are not filed yet (lock held)."""
        have = self._filed.get(prev) or {}
        missing = {}
        for key, digests in need.items():
            filed = have.get(key, ())
            n = sum(1 for d in digests if d not in filed)
            if n:
                missing[key] = n
        return missing

    def _flush_rejections(self) -> None:
        """Count what the data callback refused (the behaviour's counters, its log)."""
        with self._lock:
            rejected, self._rejected = self._rejected, {}
        for rel, (n, reason) in rejected.items():
            self.behaviour.reject(rel, reason, n)

    _collected = False

    def _owners_of(self, rel: str) -> frozenset[str]:
        """The sources whose messages on concrete key ``rel`` count (see :class:`NodeContext`)."""
        owners = self._owners.get(rel)
        if owners is None:
            table = self.ctx.publishers
            if table is None:
                owners = self.participants
            else:
                owners = frozenset(
                    n for n, pats in table.items() if any(keys.intersects(p, rel) for p in pats)
                )
            if len(self._owners) < _OWNER_CACHE:  # forged keys must not fill our memory either
                self._owners[rel] = owners
        return owners

    def _collect(self, tick: Tick) -> list[tuple[str, RawEnvelope]]:
        prev = tick.round - 1
        if any(tick.expected.values()) and not tick.digests:
            raise ProtocolError(f"{self.name}: tick {tick.round} announces no digests")
        need = {k: ds for k, ds in tick.digests.items() if self.behaviour.listens_to(k)}
        deadline = time.monotonic() + self._timeout
        try:
            while True:
                with self._lock:
                    missing = self._missing(prev, need)
                    self._awaiting = (prev, need) if missing else None
                if not missing:
                    break
                try:
                    kind, key, payload = self._wake.get(
                        timeout=max(deadline - time.monotonic(), 0.0)
                    )
                except queue.Empty:
                    with self._lock:
                        if not self._missing(prev, need):
                            break  # complete as the time ran out
                    raise NodeTimeout(
                        f"{self.name}: round {tick.round}: messages of round {prev} missing "
                        f"after {self._timeout} s: {missing}"
                    ) from None
                if kind == "ready":
                    continue
                if kind == "clock_gone":
                    raise ProtocolError(f"{self.name}: the clock left during round {tick.round}")
                if not key.endswith("/" + keys.stop()):
                    self._backlog.append((kind, key, payload))  # a later tick, the clock's log
                elif self._is_stop(key, payload):
                    raise _StopRequested(key, payload)  # a fault elsewhere ended the run
        finally:
            with self._lock:
                self._awaiting = None
        with self._lock:
            inbox = self._pending.pop(prev, [])
            self._filed.pop(prev, None)
            self._n_pending -= len(inbox)
            stale = [(r, self._pending.pop(r)) for r in [r for r in self._pending if r < prev]]
            for r, old in stale:
                self._filed.pop(r, None)
                self._n_pending -= len(old)
            self._collected = True
        for r, old in stale:
            for rel, _, _ in old:
                self._reject(rel, f"stale message of round {r}")
        taken = []
        for rel, env, digest in inbox:
            if digest in need.get(rel, ()):
                taken.append((rel, env))
            else:  # forged, altered, or published without telling the clock
                self._reject(rel, f"{env.src}#{env.seq} is not a message announced to the clock")
        return taken

    def _reject(self, rel: str, reason: str) -> None:
        self.behaviour.reject(rel, reason)

    def _put(self, rel: str, body: BaseModel) -> int:
        """Publish ``body`` on ``rel`` as this node's next message; return its digest."""
        pub = self._publishers.get(rel)
        if pub is None:
            pub = self.ctx.session.declare_publisher(
                keys.full(self.run_id, rel),
                encoding=zenoh.Encoding(codec.ENCODING),
                congestion_control=zenoh.CongestionControl.BLOCK,
                reliability=zenoh.Reliability.RELIABLE,
                express=False,  # batched: 0.5 us a put, not 33 (bench/round_budget.py)
            )
            self._publishers[rel] = pub
        payload = codec.encode(
            run=self.run_id,
            src=self.name,
            seq=self._seq,
            round=max(self.round, 0),
            t=self.behaviour.now,
            body=body,
        )
        self._seq += 1
        pub.put(payload)
        return codec.digest(payload)
