"""The controller node: runs a control law on the bus, for one loop or for several at once.

**One loop** (``loop: l``): it computes a move for every sample delivered on ``loop/<l>/meas``
with the set points current at that instant, and publishes it on ``loop/<l>/u``. Set points of all
loops of the plant are followed (:meth:`~scenario.Scenario.setpoint_key`: from operations,
or from the coordination agent when one governs the loops), because the steady-state feedforward
of one input depends on all of them (seed 000, eq. (5)-(7)). Under a coordination agent the loop
may be opened (``wncsca/rates``: steady state): the controller then computes nothing and the
plant holds the last move; on re-closing the law integrates from the re-closing instant
(``law.resume``).

**Several loops** (``loops: [a, b, ...]``, a multi-loop law such as the MRAC of seed 003): the law
takes every loop's measurement and set point (``step(t, y, r)`` with ``dict[loop, float]``) and
returns a move for every loop. The hold rule:

* the node keeps each loop's latest measurement; a delivered sample replaces it unless it was
  taken before the one held (a packet overtaken on the network is not used);
* in every round in which samples of its loops arrive, it first takes all of them in, then
  executes the law **once**, with the held value of every loop (a loop without a new sample
  contributes its last one), and publishes a move for **every** loop on ``loop/<l>/u``;
* it executes only once every loop has delivered at least one sample; until then it publishes
  nothing and the plant holds its initial inputs.

Samples delivered at one instant over paths with a delay arrive in one round (their delivery
timers fire in the instant's first round); over a zero-delay path, in the next round. So the law
executes once per instant at which samples arrive, except at an instant where both kinds
arrive: then once for the delayed samples and once more for the zero-delay ones. The ``direct``
engine executes exactly the same way. The set point of each loop is the law's reference input
(for the MRAC, ``u_c``; :class:`controllers.mrac.MultiLoopMRAC`). A coordination agent does not
open, close or re-time multi-loop controllers (refused when the scenario loads), except the update
period of their links (``link_periods``, below).

An **actuator-only** loop (``sensor: null``, for laws that move inputs they do not measure, such
as seed 001's units: :mod:`controllers.qdc_law`) has no samples: the hold rule waits only for the
loops with a sensor, ``y`` has no entry for it, and the law's move for it is published on its
``loop/<l>/u`` like the others. A **measurement-only** loop (``actuator: null``, for laws that take
measurements they move no input for, such as seed 004's PI-P cascade:
:mod:`controllers.cascade_law`) is sampled, held and passed to the law like any loop (its set
point too), but the law returns no move for it and the node publishes none.

**Links** (the scenario's ``links:``): the node transmits what its law's ``transmit(t)`` returns
on ``link/<k>/tx`` for every link it sends on, every ``period`` from ``t = 0`` (a timer, so in
the first round of its instant, before anything is received or executed there); what arrives on
``link/<k>/rx`` is handed to ``law.receive(t, link, values)`` as the message is dispatched (in
key order), so within a round receipts come before the execution on that round's samples. A
period assigned at run time (``wncsca/rates``, ``link_periods``) takes effect at once: the next
transmission is one new period after the last, or now if that has passed. A received vector
the law refuses (``ValueError``, e.g. the wrong length) is dropped and counted as invalid input.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from pydantic import BaseModel

from bus_schemas import Estimate, Move, Rates, Sample, Setpoint, keys
from bus_schemas.envelope import RawEnvelope
from controllers.registry import MultiLoopContext, build_law, build_multi_loop_law
from core.behaviour import Behaviour, Timer
from core.time import to_units

__all__ = ["ControllerBehaviour", "ControllerSpec"]


@dataclass(frozen=True)
class ControllerSpec:
    """What a controller node needs of its scenario, computed once
    (:func:`scenario.views.controller_spec`).

    Attributes
    ----------
    loops : tuple of str
        The loops it controls, in its law's order (one for a single-loop law).
    multi : bool
        Whether the law controls several loops at once (``loops:``).
    law : BaseModel
        The law's validated configuration (:mod:`controllers.registry` builds it).
    plant : object
        The plant model of the first loop, for laws designed from it.
    tau_s : float
        The loop's nominal sampling period (multi-loop: the shortest of its sampled loops).
    setpoints : mapping
        Initial set point of every loop of its plants (the feedforward depends on all of them).
    setpoint_keys : mapping
        Loop -> where its set-point changes arrive (operations, or the coordination agent).
    governed : bool
        Whether a coordination agent assigns rates (``wncsca/rates``).
    feedforward : object or None
        The single-loop law's steady-state feedforward (seed 000, eq. (5)-(7)), if it takes one.
    context : MultiLoopContext or None
        A multi-loop law's loops' signals and links.
    measured, moved : tuple of str
        A multi-loop law's loops with a sensor, with an actuator.
    sends : mapping
        Link it transmits on -> initial period, ticks (by link name).
    receives : tuple of str
        Links it receives.
    end : int
        End of the run, ticks.
    """

    loops: tuple[str, ...]
    multi: bool
    law: BaseModel
    plant: Any
    tau_s: float
    setpoints: Mapping[str, float]
    setpoint_keys: Mapping[str, str]
    governed: bool
    end: int
    feedforward: Any = None
    context: MultiLoopContext | None = None
    measured: tuple[str, ...] = ()
    moved: tuple[str, ...] = ()
    sends: Mapping[str, int] = field(default_factory=dict)
    receives: tuple[str, ...] = ()


class ControllerBehaviour(Behaviour):
    def __init__(self, name: str, spec: ControllerSpec) -> None:
        super().__init__(name)
        self.spec = spec
        self.loops = spec.loops
        self.multi = spec.multi
        self.loop = self.loops[0]
        self.setpoints = dict(spec.setpoints)
        self.closed = True
        self._samples: list[Sample] = []
        self._setpoints_changed = False
        self._senders: dict[str, Timer] = {}  # link -> its transmissions (multi-loop laws)
        if self.multi:
            self.feedforward = None
            self.law = build_multi_loop_law(
                spec.law, loops=self.loops, plant=spec.plant, tau_s=spec.tau_s, context=spec.context
            )
            self._held: dict[str, tuple[int, float]] = {}  # loop -> (t_sampled, value)
            self._arrived: list[tuple[str, Sample]] = []
            self._measured = list(spec.measured)
            self._moved = list(spec.moved)
            for name in self._measured:
                self.subscribe(keys.meas(name), Sample, self._on_meas_of(name))
            for name in sorted(set(spec.sends) | set(spec.receives)):
                if name in spec.sends:
                    send = self._sender(name)
                    self._senders[name] = self.every(spec.sends[name], send, end=spec.end)
                if name in spec.receives:
                    self.subscribe(keys.link_rx(name), Estimate, self._on_estimate(name))
        else:
            self.feedforward = spec.feedforward
            self.law = build_law(spec.law, u_bar=self._u_bar(), plant=spec.plant, tau_s=spec.tau_s)
            self.subscribe(keys.meas(self.loop), Sample, self._on_meas)
        for name in self.setpoints:
            self.subscribe(spec.setpoint_keys[name], Setpoint, self._on_setpoint(name))
        if spec.governed:
            self.subscribe(keys.wncsca_rates(), Rates, self._on_rates)

    def _u_bar(self) -> float:
        return self.feedforward.u_bar(self.setpoints) if self.feedforward is not None else 0.0

    def _on_meas(self, env: RawEnvelope, sample: Sample) -> None:
        self._samples.append(sample)

    def _on_meas_of(self, loop: str) -> Callable[[RawEnvelope, Sample], None]:
        def handle(env: RawEnvelope, sample: Sample) -> None:
            self._arrived.append((loop, sample))

        return handle

    def _on_setpoint(self, loop: str) -> Callable[[RawEnvelope, Setpoint], None]:
        def handle(env: RawEnvelope, sp: Setpoint) -> None:
            self.setpoints[loop] = sp.value
            self._setpoints_changed = True

        return handle

    def _sender(self, link: str) -> Callable[[], None]:
        """Transmit on ``link`` now (its :class:`~core.behaviour.Timer` fires it every period,
        up to the end, retimed by the agent: :meth:`_set_link_period`)."""

        def send() -> None:
            values = self.law.transmit(to_units(self.now))
            self.publish(keys.link_tx(link), Estimate(values=tuple(values), t_sent=self.now))

        return send

    def _on_estimate(self, link: str) -> Callable[[RawEnvelope, Estimate], None]:
        def handle(env: RawEnvelope, msg: Estimate) -> None:
            try:
                self.law.receive(to_units(self.now), link, list(msg.values))
            except ValueError as err:
                self.reject(self.current_key, f"{env.src}#{env.seq}: {err}")

        return handle

    def _set_link_period(self, link: str, period: int) -> None:
        """Transmit on ``link`` every ``period`` ticks from now on (see the module docstring)."""
        timer = self._senders[link]
        before = timer.period
        if timer.retime(period):  # the phase of its last transmission kept
            self.log.info("link %s: period %s -> %s ticks", link, before, period)

    def _on_rates(self, env: RawEnvelope, rates: Rates) -> None:
        for link, period in sorted(rates.link_periods.items()):
            if link in self._senders:
                self._set_link_period(link, period)
        if self.multi:
            return  # loops of multi-loop controllers are not opened or closed by the agent
        closed = rates.closed.get(self.loop, True)
        if closed and not self.closed:
            self.law.resume(to_units(self.now))
        if closed != self.closed:
            self.log.info("loop %s %s", self.loop, "closed" if closed else "opened (output held)")
        self.closed = closed

    def after_dispatch(self) -> None:
        if self.multi:
            self._execute_multi()
            return
        if self._setpoints_changed and self.feedforward is not None:
            self.law.set_feedforward(self._u_bar())
            self._setpoints_changed = False
        if self.closed:
            for sample in self._samples:
                u = self.law.step(to_units(self.now), sample.value, self.setpoints[self.loop])
                self.publish(keys.move(self.loop), Move(value=u, t_computed=self.now))
        self._samples.clear()

    def _execute_multi(self) -> None:
        """The hold rule of the module docstring: take this round's samples in, execute once."""
        if not self._arrived:
            return
        for loop, sample in self._arrived:
            held = self._held.get(loop)
            if held is None or sample.t_sampled >= held[0]:
                self._held[loop] = (sample.t_sampled, sample.value)
        self._arrived.clear()
        if len(self._held) < len(self._measured):
            return  # some loop has not delivered yet: no move
        y = {n: self._held[n][1] for n in self._measured}
        r = {n: self.setpoints[n] for n in self.loops}
        u = self.law.step(to_units(self.now), y, r)
        for name in self._moved:
            self.publish(keys.move(name), Move(value=u[name], t_computed=self.now))
