"""The controller node: runs a control law on the bus, for one loop or for several at once.

The node is the same for both; what differs (one move per sample, or the hold rule below) is the
law's :class:`~controllers.execution.Execution`: :class:`~controllers.execution.SingleLoop`
adapts a single-loop law, :class:`~controllers.execution.MultiLoop` runs a multi-loop one.

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
as seed 001's units: :mod:`controllers.qdc.law`) has no samples: the hold rule waits only for the
loops with a sensor, ``y`` has no entry for it, and the law's move for it is published on its
``loop/<l>/u`` like the others. A **measurement-only** loop (``actuator: null``, for laws that take
measurements they move no input for, such as seed 004's PI-P cascade:
:mod:`controllers.cascade.law`) is sampled, held and passed to the law like any loop (its set
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
from controllers.execution import Execution, MultiLoop, SingleLoop
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
    """The controller node (see the module docstring); its law executes by the rule of its
    :class:`~controllers.execution.Execution` (:class:`SingleLoop` or :class:`MultiLoop`)."""

    def __init__(self, name: str, spec: ControllerSpec) -> None:
        super().__init__(name)
        self.spec = spec
        self.loops = spec.loops
        self.setpoints = dict(spec.setpoints)
        self._setpoints_changed = False
        self._senders: dict[str, Timer] = {}  # link -> its transmissions (multi-loop laws)
        self.execution = _execution(spec, self.setpoints)
        self.law = self.execution.law
        for loop in self.execution.measured:
            self.subscribe(keys.meas(loop), Sample, self._on_meas_of(loop))
        for link in sorted(set(spec.sends) | set(spec.receives)):
            if link in spec.sends:
                self._senders[link] = self.every(spec.sends[link], self._sender(link), end=spec.end)
            if link in spec.receives:
                self.subscribe(keys.link_rx(link), Estimate, self._on_estimate(link))
        for loop in self.setpoints:
            self.subscribe(spec.setpoint_keys[loop], Setpoint, self._on_setpoint(loop))
        if spec.governed:
            self.subscribe(keys.wncsca_rates(), Rates, self._on_rates)

    def _on_meas_of(self, loop: str) -> Callable[[RawEnvelope, Sample], None]:
        def handle(env: RawEnvelope, sample: Sample) -> None:
            self.execution.take(loop, sample)

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
        change = self.execution.close(to_units(self.now), rates.closed)
        if change is not None:
            self.log.info("%s", change)

    def after_dispatch(self) -> None:
        changed, self._setpoints_changed = self._setpoints_changed, False
        for moves in self.execution.moves(to_units(self.now), self.setpoints, changed):
            for loop, u in moves.items():
                self.publish(keys.move(loop), Move(value=u, t_computed=self.now))


def _execution(spec: ControllerSpec, setpoints: Mapping[str, float]) -> Execution:
    """The law of ``spec``, built with the initial ``setpoints``, under its execution rule."""
    if spec.multi:
        law = build_multi_loop_law(
            spec.law, loops=spec.loops, plant=spec.plant, tau_s=spec.tau_s, context=spec.context
        )
        return MultiLoop(law, spec.loops, spec.measured, spec.moved)
    ff = spec.feedforward
    u_bar = ff.u_bar(setpoints) if ff is not None else 0.0
    law = build_law(spec.law, u_bar=u_bar, plant=spec.plant, tau_s=spec.tau_s)
    return SingleLoop(law, spec.loops[0], ff)
