"""The controller node: runs a control law on the bus, for one loop or for several at once.

**One loop** (``loop: l``): it computes a move for every sample delivered on ``loop/<l>/meas``
with the set points current at that instant, and publishes it on ``loop/<l>/u``. Set points of all
loops of the plant are followed (:meth:`~runtime.scenario.Scenario.setpoint_key`: from operations,
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
govern multi-loop controllers (refused when the scenario loads).
"""

from __future__ import annotations

from collections.abc import Callable

from bus_schemas import Move, Rates, Sample, Setpoint, keys
from bus_schemas.envelope import RawEnvelope
from controllers.registry import build_law, build_multi_loop_law, uses_feedforward
from runtime.node import Node, NodeContext
from runtime.time import to_units

__all__ = ["ControllerNode"]


class ControllerNode(Node):
    def __init__(self, ctx: NodeContext) -> None:
        super().__init__(ctx)
        cfg = self.scenario.nodes[self.name]
        self.loops = cfg.loop_names
        self.multi = cfg.loops is not None
        self.loop = self.loops[0]
        loop = self.scenario.loops[self.loop]
        self.plant = loop.plant
        plants = sorted({self.scenario.loops[n].plant for n in self.loops})
        self.setpoints = {
            n: lp.setpoint for p in plants for n, lp in self.scenario.loops_of_plant(p).items()
        }
        self.closed = True
        self._samples: list[Sample] = []
        self._setpoints_changed = False
        plant = self.scenario.nodes[loop.plant].build()
        if self.multi:
            self.feedforward = None
            tau_s = min(self.scenario.loops[n].tau_s for n in self.loops)
            self.law = build_multi_loop_law(cfg.law, loops=self.loops, plant=plant, tau_s=tau_s)
            self._held: dict[str, tuple[int, float]] = {}  # loop -> (t_sampled, value)
            self._arrived: list[tuple[str, Sample]] = []
            for name in self.loops:
                self.subscribe(keys.meas(name), Sample, self._on_meas_of(name))
        else:
            self.feedforward = (
                self.scenario.feedforward(self.loop) if uses_feedforward(cfg.law) else None
            )
            self.law = build_law(cfg.law, u_bar=self._u_bar(), plant=plant, tau_s=loop.tau_s)
            self.subscribe(keys.meas(self.loop), Sample, self._on_meas)
        for name in self.setpoints:
            self.subscribe(self.scenario.setpoint_key(name), Setpoint, self._on_setpoint(name))
        if self.scenario.agent_node() is not None:
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

    def _on_rates(self, env: RawEnvelope, rates: Rates) -> None:
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
        if len(self._held) < len(self.loops):
            return  # some loop has not delivered yet: no move
        y = {n: self._held[n][1] for n in self.loops}
        r = {n: self.setpoints[n] for n in self.loops}
        u = self.law.step(to_units(self.now), y, r)
        for name in self.loops:
            self.publish(keys.move(name), Move(value=u[name], t_computed=self.now))
