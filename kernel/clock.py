"""The clock: conservative round synchronisation in virtual time (DESIGN section 3).

:class:`RoundPlanner` is the pure logic (which round and time come next, given every
participant's ``Done``); :class:`Pacer` waits for the wall clock in real-time mode;
:class:`ClockRunner` drives both on the bus, watches liveliness and timeouts, and ends the run
with a ``Stop`` naming the node and the round of any fault.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh
from pydantic import BaseModel

from bus_schemas import Done, InjectRequest, Stop, Tick, TickLog, Working, codec, keys
from bus_schemas.errors import SchemaError
from core.errors import NodeFault, ProtocolError
from core.rounds import Participation, RoundPlanner, merge_dropped
from core.time import TICKS_PER_UNIT, to_units

__all__ = ["ClockSpec", "Interpreter", "RoundPlanner", "Pacer", "ClockRunner", "INJECT_SOURCE"]

INJECT_SOURCE = "inject"
"""The only source the clock takes external requests from (``wncs inject``)."""

Interpreter = Callable[[InjectRequest], tuple[str, BaseModel]]
"""Turns a validated external request into the message the clock stamps (run-relative key and
body); raises ``ValueError`` (or :class:`SchemaError`) for a request the run cannot take."""


def _no_injections(request: InjectRequest) -> tuple[str, BaseModel]:
    raise ValueError("this run takes no external requests")


@dataclass(frozen=True)
class ClockSpec:
    """What the clock needs to know of a run (computed once from the scenario)."""

    participants: frozenset[str]
    end: int  # ticks
    time_unit: str
    round_timeout_s: float
    startup_timeout_s: float
    max_microsteps: int
    may_drop: frozenset[str] = frozenset()
    max_rounds: int = 100_000_000
    work_timeout_s: float = 3600.0
    """The longest a node may work on one round while it says it is working (its progress
    heartbeat, :mod:`kernel.heartbeat`): ``round_timeout_s`` judges silence, this judges work."""
    observers: frozenset[str] = frozenset()
    """Participants that take every tick from the clock's log (``clock/log``, :class:`TickLog`)
    and handle every round's messages but answer only the sync rounds (:data:`SYNC_ROUNDS`):
    the historian. No other round waits for them, so they keep off its critical path; the sync
    rounds bound how far they may lag. Liveliness covers them like any participant, and the
    clock waits for them to leave."""


log = logging.getLogger(__name__)

SYNC_ROUNDS = 256
"""Every this many rounds the tick goes to every node, whether it takes part or not: a node that
sits rounds out then still knows the round within this many (the data it may keep ahead of its
last tick, :data:`kernel.node._AHEAD`, is more)."""

LOG_TICKS = 64
LOG_S = 0.1
"""The clock logs its ticks (``clock/log``) in batches: at a sync round (the observers answer
it), when :data:`LOG_TICKS` ticks wait or the oldest has waited :data:`LOG_S` s of wall time,
with the ``Stop``, and every round of a real-time run. An observer that woke for every tick
cost the rounds' critical path about a tenth (its thread and the node's share two cores and,
in the threads engine, one interpreter lock: ``bench/round_budget.py``)."""

CANCEL_GRACE_S = 5.0
"""A run cancelled mid-round (Ctrl-C) ends that round first, waiting this long at most for its
``Done`` messages: every message of the rounds before the last tick is then in the history."""


class Pacer:
    """Real-time pacing: virtual time ``t`` is due at ``start + t * seconds_per_unit`` (monotonic).

    Like simpy's ``RealtimeEnvironment``, it only paces the same loop; with ``strict`` a lag of
    more than one ``seconds_per_unit`` raises instead of being logged.
    """

    def __init__(self, seconds_per_unit: float, *, strict: bool = False) -> None:
        self.seconds_per_unit = seconds_per_unit
        self.strict = strict
        self.start = time.monotonic()
        self.max_lag = 0.0

    def delay(self, t: int) -> float:
        """Wall seconds to wait before time ``t`` (ticks) may begin; negative when late."""
        target = self.start + t / TICKS_PER_UNIT * self.seconds_per_unit
        lag = time.monotonic() - target
        if lag > self.max_lag:
            self.max_lag = lag
            if lag > 0.05 * self.seconds_per_unit:
                if self.strict and lag > self.seconds_per_unit:
                    raise ProtocolError(f"simulation too slow for real time: {lag:.3f} s behind")
                log.warning("real time: %.3f s behind at t = %.6f", lag, to_units(t))
        return -lag


class ClockRunner:
    """Drives the rounds of one run over a zenoh session."""

    def __init__(
        self,
        session: zenoh.Session,
        run_id: str,
        spec: ClockSpec,
        *,
        interpret: Interpreter = _no_injections,
        realtime: float | None = None,
    ) -> None:
        self.session = session
        self.run_id = run_id
        self.spec = spec
        self.interpret = interpret
        self.observers = spec.observers & spec.participants
        self.participants = spec.participants - self.observers  # they answer every round due
        self.planner = RoundPlanner(
            self.participants,
            spec.end,
            max_microsteps=spec.max_microsteps,
            max_rounds=spec.max_rounds,
        )
        self.participation = Participation(self.participants)
        self.ticked: dict[str, int] = {}  # node -> rounds it took part in (sparse rounds)
        self.pacer = Pacer(realtime) if realtime else None
        self._queue: queue.Queue[tuple[str, str, bytes | zenoh.SampleKind]] = queue.Queue()
        self._alive: set[str] = set()
        self._seq = 0
        self.dropped_invalid: dict[str, dict[str, int]] = {}
        self.error: str | None = None
        self.span: tuple[float, float] | None = None
        """``perf_counter`` at the first round and after the last of a run that ended well: its
        run phase, stamped where the rounds go (a run's progress display may see them late)."""
        self.dropped_nodes: list[dict[str, Any]] = []
        self._injections: list[tuple[str, BaseModel]] = []  # (run-relative key, body)
        self._cancelled: str | None = None  # the reason given to cancel(), if any
        self._log: list[Tick] = []  # ticks not yet logged on clock/log
        self._log_since = 0.0  # monotonic time the oldest of them was logged
        self._announced: dict[str, list[int]] = {}  # key -> digests of the last round's messages
        # The round under way, shared by this thread and the Done callback (_on_done), under
        # _lock: its tick, the nodes that answer it, their answers so far, when it started,
        # whether it still waits for answers (_collecting), whether rounds may still start
        # (_running), a cancel waiting for the round's end, and what failed in a callback.
        self._lock = threading.Lock()
        self._tick = Tick(round=0, t=0, expected={})
        self._who: frozenset[str] = frozenset()
        self._dones: dict[str, Done] = {}
        self._round_started = 0.0
        self._heard: dict[str, float] = {}  # node -> monotonic time of its last beat this round
        self._collecting = False
        self._running = False
        self._cancelling: str | None = None
        self._cancel_deadline = 0.0
        self._failure: BaseException | None = None

    @property
    def members(self) -> frozenset[str]:
        """Every node of the run still in it: the participants and the observers (liveliness
        and the run's end wait for them all)."""
        return self.participants | self.observers

    # -- bus plumbing ----------------------------------------------------------------------------
    def _full(self, rel: str) -> str:
        return keys.full(self.run_id, rel)

    def _publish(
        self, rel: str, body: BaseModel, *, round: int | None = None, t: int | None = None
    ) -> None:
        """Publish as the clock, stamped with the current round and time unless told otherwise."""
        round = self.planner.round if round is None else round
        self._put([rel], self._envelope(body, round, self.planner.t if t is None else t))

    def _publish_tick(self, tick: Tick, to: frozenset[str]) -> None:
        """Publish ``tick`` on ``clock/tick/<node>`` for each node of ``to`` but the observers,
        and log it (:data:`LOG_TICKS`)."""
        if not self._log:
            self._log_since = time.monotonic()
        self._log.append(tick)
        rels = [keys.tick_to(n) for n in sorted(to - self.observers)]
        if rels:
            self._put(rels, self._envelope(tick, tick.round, tick.t))
        if (
            tick.round % SYNC_ROUNDS == 0
            or len(self._log) >= LOG_TICKS
            or self.pacer is not None
            or time.monotonic() - self._log_since >= LOG_S
        ):
            self._publish_log()

    def _publish_log(self, stop: Stop | None = None) -> None:
        """Publish the ticks logged since the last log (and ``stop``) on ``clock/log``."""
        if not self._log and stop is None:
            return
        last: Tick | Stop = stop if stop is not None else self._log[-1]
        payload = self._envelope(TickLog(ticks=tuple(self._log), stop=stop), last.round, last.t)
        self._put([keys.tick_log()], payload)
        self._log.clear()

    def _publish_stop(self, stop: Stop) -> None:
        """End the run: the last ticks and the stop on ``clock/log``, the stop on ``clock/stop``."""
        self._publish_log(stop)
        self._publish(keys.stop(), stop)

    def _envelope(self, body: BaseModel, round: int, t: int) -> bytes:
        """``body`` as the clock's next message of round ``round`` at ``t``."""
        payload = codec.encode(
            run=self.run_id, src="clock", seq=self._seq, round=round, t=t, body=body
        )
        self._seq += 1
        return payload

    def _put(self, rels: list[str], payload: bytes) -> None:
        """The same ``payload`` on each run-relative key of ``rels``."""
        for rel in rels:
            self.session.put(
                self._full(rel),
                payload,
                encoding=zenoh.Encoding(codec.ENCODING),
                congestion_control=zenoh.CongestionControl.BLOCK,
                express=False,  # batched: 0.5 us a put, not 33 (bench/round_budget.py)
            )

    def cancel(self, reason: str) -> None:
        """Stop the run from outside (another thread): the clock publishes ``Stop(ok=False)``
        with ``reason`` as for any fault (e.g. a node failed while starting, or the user
        interrupted the run: the caller reports that, so it is logged at info), between rounds:
        a round under way ends first (:data:`CANCEL_GRACE_S`)."""
        self._cancelled = reason
        self._queue.put(("cancel", reason, b""))

    def _on_alive(self, sample: zenoh.Sample) -> None:
        name = str(sample.key_expr).rsplit("/", 1)[-1]
        self._queue.put(("alive", name, sample.kind))

    def _on_inject(self, sample: zenoh.Sample) -> None:
        self._queue.put(("inject", str(sample.key_expr), sample.payload.to_bytes()))

    def _take_injection(self, payload: bytes) -> None:
        """Validate an external request and keep it for the next round (bad ones are logged):
        a network event for its gateway (``events/<network>``), a mode or a set-point request
        as operations would send it (``ops/mode``, ``ops/setpoint/<loop>``)."""
        try:
            env = codec.decode_envelope(payload)
            if env.run != self.run_id:
                raise SchemaError(f"request of run {env.run!r} on this run's key")
            if env.src != INJECT_SOURCE:
                raise SchemaError(f"request from {env.src!r}, expected {INJECT_SOURCE!r}")
            rel, body = self.interpret(codec.decode_body(env, InjectRequest))
        except (SchemaError, ValueError) as err:
            log.warning("clock: dropping injected request: %s", err)
            return
        log.info("clock: injected %s on %s, in the next round", body, rel)
        self._injections.append((rel, body))

    def _stamp_injections(self, round_: int, t: int) -> None:
        """Publish pending external inputs as the clock's messages of the previous round and
        announce them with that round's other messages (DESIGN section 3, external inputs)."""
        if not self._injections or round_ == 0:
            return
        for rel, body in self._injections:
            payload = self._envelope(body, round_ - 1, t)
            self._put([rel], payload)
            self._announced.setdefault(rel, []).append(codec.digest(payload))
        self._injections.clear()

    def _handle_alive(self, name: str, kind: zenoh.SampleKind) -> None:
        if kind == zenoh.SampleKind.PUT:
            self._alive.add(name)
            return
        self._alive.discard(name)
        if name not in self.members or self.planner.finished:
            return
        unit = self.spec.time_unit
        where = f"round {self.planner.round} (t = {to_units(self.planner.t):.6f} {unit})"
        if name in self.spec.may_drop:
            log.warning("node %r left during %s; dropped, the run carries on", name, where)
            self.participants = self.participants - {name}
            self.planner.participants = self.participants
            self.participation.drop(name)
            self.dropped_nodes.append(
                {"node": name, "round": self.planner.round, "t": self.planner.t}
            )
            return
        raise NodeFault(f"node {name!r} left the run during {where}")

    # -- the run ---------------------------------------------------------------------------------
    def run(self) -> int:
        """Run to the end; 0 on success, 3 when a fault stopped the run (see :attr:`error`)."""
        live = self.session.liveliness()
        token = live.declare_token(self._full(keys.alive("clock")))
        subs = [
            live.declare_subscriber(self._full(keys.alive_all()), self._on_alive, history=True),
            self.session.declare_subscriber(self._full(keys.done_all()), self._on_done),
            self.session.declare_subscriber(self._full(keys.working_all()), self._on_working),
            self.session.declare_subscriber(self._full(keys.inject()), self._on_inject),
        ]
        try:
            try:
                self._wait_for_participants()
                began = time.perf_counter()
                self._rounds()
                self.span = (began, time.perf_counter())
                self._publish_stop(self._stop(ok=True))
                log.info("run finished at round %d", self.planner.round)
                code = 0
            except (NodeFault, ProtocolError, TimeoutError) as err:
                self.error = str(err)
                (log.info if str(err) == self._cancelled else log.error)("%s", err)
                self._publish_stop(self._stop(ok=False, reason=str(err)))
                code = 3
            self._wait_for_exit(timeout=self.spec.round_timeout_s)
            return code
        finally:
            for s in subs:
                s.undeclare()
            token.undeclare()

    def _stop(self, *, ok: bool, reason: str = "") -> Stop:
        return Stop(
            ok=ok,
            reason=reason,
            round=self.planner.round,
            t=self.planner.t,
            dropped_invalid=merge_dropped(self.dropped_invalid.values()),
            dropped_nodes={d["node"]: d["round"] for d in self.dropped_nodes},
            rounds_taken=dict(sorted(self.ticked.items())),
        )

    def _next(self, timeout: float) -> tuple[str, str, bytes | zenoh.SampleKind] | None:
        try:
            return self._queue.get(timeout=max(timeout, 0.0))
        except queue.Empty:
            return None

    def _wait_for_participants(self) -> None:
        deadline = time.monotonic() + self.spec.startup_timeout_s
        while not self.members <= self._alive:
            item = self._next(deadline - time.monotonic())
            if item is None:
                missing = sorted(self.members - self._alive)
                raise NodeFault(
                    f"nodes {missing} did not come alive within {self.spec.startup_timeout_s} s"
                )
            if item[0] == "cancel":
                raise NodeFault(item[1])
            if item[0] == "alive":
                self._handle_alive(item[1], item[2])  # type: ignore[arg-type]
            elif item[0] == "inject":
                self._take_injection(item[2])  # type: ignore[arg-type]
        if self.pacer is not None:
            self.pacer.start = time.monotonic()

    def _rounds(self) -> None:
        """Run the rounds. Round 0 ticks every participant (their ``Done`` says what they
        subscribe to); later rounds only those with a timer due or a message to collect
        (:class:`~core.rounds.Participation`); liveliness still watches everyone. The
        observers (:attr:`ClockSpec.observers`) take every tick but answer only sync rounds.

        The rounds advance in the ``Done`` subscriber's callback thread (:meth:`_on_done`): the
        ``Done`` that completes a round publishes the next tick there, without a hop to this
        thread (a wake-up, about 40 us: ``bench/round_budget.py``). This thread watches:
        liveliness, requests, a cancel, a round's timeout, the real-time pacing, and the end."""
        with self._lock:
            self._running = True
            self._start_round()
            self._advance_if_complete()
        try:
            while True:
                with self._lock:
                    deadline = self._deadline()
                    if self._cancelling is not None:
                        deadline = min(deadline, self._cancel_deadline)
                # the rounds move on in callbacks: wake at least every round_timeout_s to time
                # the round then under way (round 0's longer allowance must not hide a later one)
                wait = min(deadline - time.monotonic(), self.spec.round_timeout_s)
                item = self._next(wait)
                if item is None:
                    with self._lock:
                        self._check_round_time()
                    continue
                kind, key, payload = item
                if kind == "cancel":  # end the round first: the ticked nodes then handled all
                    with self._lock:  # of the round before, within a grace for a hung node
                        if not self._collecting:
                            raise NodeFault(key)
                        self._cancelling = key
                        self._cancel_deadline = time.monotonic() + CANCEL_GRACE_S
                elif kind in ("alive", "inject"):
                    self._take_watched(item)
                elif kind == "halted":
                    assert self._cancelling is not None
                    raise NodeFault(self._cancelling)
                elif kind == "failed":
                    assert self._failure is not None
                    raise self._failure
                elif kind == "finished":
                    return
                elif kind == "pace":
                    self._pace(self.planner.t)
                    with self._lock:
                        self._start_round()
                        self._advance_if_complete()
        finally:
            with self._lock:
                self._running = False  # no callback starts a round after this

    def _round_timeout(self) -> float:
        """How long the round under way may take (lock held): round 0, in which every node does
        its one-off work (a gateway predicts its paths' delay distributions: about 60 ms of CPU
        a path, 6 s for the 100 paths of 100 loops, all in one process for the threads engine),
        is still start-up and has ``startup_timeout_s``; every later round ``round_timeout_s``."""
        return self.spec.startup_timeout_s if self._tick.round == 0 else self.spec.round_timeout_s

    def _waited_for(self) -> frozenset[str]:
        """The nodes ticked for the round under way that have not answered yet (lock held)."""
        return (self._who & self.members) - set(self._dones)

    def _deadline(self) -> float:
        """When the round under way becomes a fault (monotonic, lock held): when a node it
        waits for has been silent for :meth:`_round_timeout` since its tick or its last
        progress beat, or has worked on it for ``work_timeout_s``."""
        if not self._collecting:
            return self._round_started + self._round_timeout()
        waited = self._waited_for()
        started = self._round_started
        heard = min((self._heard.get(n, started) for n in waited), default=started)
        return min(heard + self._round_timeout(), started + self.spec.work_timeout_s)

    def _check_round_time(self) -> None:
        """A node of the round under way has been silent for its time (:meth:`_round_timeout`)
        or has worked past ``work_timeout_s``, or a cancel is out of its grace: a fault naming
        the nodes (lock held)."""
        now = time.monotonic()
        if self._cancelling is not None and now >= self._cancel_deadline:
            raise NodeFault(self._cancelling)
        if not self._collecting:
            return
        tick, timeout = self._tick, self._round_timeout()
        where = f"round {tick.round} (t = {to_units(tick.t):.6f} {self.spec.time_unit})"
        waited = self._waited_for()
        started = self._round_started
        silent = sorted(n for n in waited if now >= self._heard.get(n, started) + timeout)
        if silent:
            raise NodeFault(f"node(s) {silent} did not answer {where} within {timeout} s")
        if waited and now >= started + self.spec.work_timeout_s:
            raise NodeFault(
                f"node(s) {sorted(waited)} still working on {where} after "
                f"{self.spec.work_timeout_s} s (the clock's work_timeout_s)"
            )

    def _start_round(self) -> None:
        """Tick the next round's nodes (lock held)."""
        planner = self.planner
        self._stamp_injections(planner.round, planner.t)
        digests = {k: tuple(sorted(v)) for k, v in sorted(self._announced.items())}
        expected = {k: len(v) for k, v in digests.items()}
        sync = planner.round % SYNC_ROUNDS == 0
        if planner.round == 0:
            who, named = self.members, None
        else:
            who = self.participation.of(planner.t, expected) & self.participants
            if sync:
                who |= self.observers
            named = tuple(sorted(who))
        tick = Tick(
            round=planner.round, t=planner.t, expected=expected, digests=digests, participants=named
        )
        self._tick, self._who, self._dones = tick, who, {}
        self._round_started = time.monotonic()
        if self._heard:
            self._heard = {}
        self._collecting = True
        self._publish_tick(tick, self.participants if sync else who)

    def _on_done(self, sample: zenoh.Sample) -> None:
        """Zenoh's callback for a ``Done``: take it, and if it completes the round, start the
        next one here (:meth:`_rounds`). What fails is handed to the loop to raise."""
        key, payload = str(sample.key_expr), sample.payload.to_bytes()
        with self._lock:
            if not (self._running and self._collecting):
                return
            try:
                self._take_done(key, payload)
                self._advance_if_complete()
            except Exception as err:  # the planner's faults, a closed session: the loop raises
                self._running, self._failure = False, err
                self._queue.put(("failed", "", b""))

    def _on_working(self, sample: zenoh.Sample) -> None:
        """Zenoh's callback for a progress beat (:class:`Working`): a node ticked for the round
        under way, and not done with it, is still working on it. Anything else is logged and
        dropped; a beat never moves the rounds."""
        key, payload = str(sample.key_expr), sample.payload.to_bytes()
        try:
            env = codec.decode_envelope(payload)
            if env.run != self.run_id:
                raise SchemaError(f"beat of run {env.run!r} on this run's key")
            beat = codec.decode_body(env, Working)
            if env.src != beat.node or key.rsplit("/", 1)[-1] != beat.node:
                raise SchemaError(f"beat for {beat.node!r} from {env.src!r} on {key}")
        except SchemaError as err:
            log.warning("clock: dropping invalid beat on %s: %s", key, err)
            return
        with self._lock:
            if (
                self._collecting
                and beat.round == self._tick.round
                and beat.node in self._who
                and beat.node not in self._dones
            ):
                self._heard[beat.node] = time.monotonic()
                log.debug(
                    "clock: %s still working on round %d (%.1f s)",
                    beat.node,
                    beat.round,
                    beat.busy_s,
                )

    def _take_done(self, key: str, payload: bytes) -> None:
        """Keep a valid ``Done`` of the round under way from a node ticked for it (lock held);
        anything else is logged and dropped."""
        try:
            env = codec.decode_envelope(payload)
            if env.run != self.run_id:
                raise SchemaError(f"Done of run {env.run!r} on this run's key")
            done = codec.decode_body(env, Done)
        except SchemaError as err:
            log.warning("clock: dropping invalid Done on %s: %s", key, err)
            return
        if done.node not in self._who or env.src != done.node:
            log.warning("clock: Done from %r, not ticked in this round, ignored", done.node)
            return
        if done.round != self._tick.round:
            return
        self._dones[done.node] = done
        self.dropped_invalid[done.node] = done.dropped_invalid

    def _advance_if_complete(self) -> None:
        """While every node ticked for the round under way has answered (a round may tick
        nobody), move on: the next tick, or hand the loop the end, the real-time pacing or a
        cancel (lock held)."""
        while self._collecting and (self._who & self.members) <= set(self._dones):
            self._collecting = False
            if self._cancelled is not None and self._cancelling is None:
                # cancel() came during this round, and the rounds move on faster than the loop
                # takes its request: this round was the one under way, so none starts after it
                self._cancelling = self._cancelled
            if self._cancelling is not None:
                self._running = False
                self._queue.put(("halted", "", b""))
                return
            planner = self.planner
            t_before = planner.t
            self._announced = {}
            for node, done in sorted(self._dones.items()):
                if node not in self.members:
                    continue  # dropped during the round
                self.ticked[node] = self.ticked.get(node, 0) + 1
                if node in self.participants:  # an observer's answer says nothing of its rounds
                    self.participation.learn(node, done.next_time, done.listens)
                for key, ds in done.digests.items():  # as many as it counts (Done checks)
                    self._announced.setdefault(key, []).extend(ds)
            planner.advance_with(
                {k: len(v) for k, v in self._announced.items()},
                {n: self.participation.next_times.get(n) for n in self.participants},
            )
            if planner.finished:
                self._running = False
                self._queue.put(("finished", "", b""))
            elif self.pacer is not None and planner.t > t_before:
                self._queue.put(("pace", "", b""))  # the loop waits for the wall clock
            else:
                self._start_round()

    def _pace(self, t: int) -> None:
        """Wait until ``t`` is due in wall time, still watching for faults."""
        assert self.pacer is not None
        while (wait := self.pacer.delay(t)) > 0:
            item = self._next(wait)
            if item is not None and item[0] == "cancel":
                raise NodeFault(item[1])
            if item is not None:
                self._take_watched(item)

    def _take_watched(self, item: tuple[str, str, bytes | zenoh.SampleKind]) -> None:
        """A liveliness change (a node dropped may complete the round under way) or a request
        of ``wncs inject``; anything else on the queue is not this method's."""
        kind, key, payload = item
        with self._lock:
            if kind == "alive":
                self._handle_alive(key, payload)  # type: ignore[arg-type]
                self._advance_if_complete()
            elif kind == "inject":
                self._take_injection(payload)  # type: ignore[arg-type]

    def _wait_for_exit(self, timeout: float) -> None:
        """Give the participants time to see the Stop and leave (the historian flushes)."""
        deadline = time.monotonic() + timeout
        while self._alive & self.members:
            item = self._next(deadline - time.monotonic())
            if item is None:
                return
            if item[0] == "alive":
                name, kind = item[1], item[2]
                if kind == zenoh.SampleKind.DELETE:
                    self._alive.discard(name)
                else:
                    self._alive.add(name)
