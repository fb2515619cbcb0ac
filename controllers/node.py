"""The controller node: runs one loop's control law on the bus.

It computes a move for every sample delivered on ``loop/<l>/meas`` with the set points current at
that instant, and publishes it on ``loop/<l>/u``. Set points of all loops of the plant are followed
(:meth:`~runtime.scenario.Scenario.setpoint_key`: from operations, or from the coordination agent
when one governs the loops), because the steady-state feedforward of one input depends on all of
them (seed 000, eq. (5)-(7)). Under a coordination agent the loop may be opened
(``wncsca/rates``: steady state): the controller then computes nothing and the plant holds the
last move; on re-closing the law integrates from the re-closing instant (``law.resume``).
"""

from __future__ import annotations

from collections.abc import Callable

from bus_schemas import Move, Rates, Sample, Setpoint, keys
from bus_schemas.envelope import RawEnvelope
from controllers.registry import build_law, uses_feedforward
from runtime.node import Node, NodeContext
from runtime.time import to_units

__all__ = ["ControllerNode"]


class ControllerNode(Node):
    def __init__(self, ctx: NodeContext) -> None:
        super().__init__(ctx)
        cfg = self.scenario.nodes[self.name]
        self.loop = cfg.loop
        loop = self.scenario.loops[self.loop]
        self.plant = loop.plant
        self.setpoints = {
            n: lp.setpoint for n, lp in self.scenario.loops_of_plant(loop.plant).items()
        }
        self.feedforward = (
            self.scenario.feedforward(self.loop) if uses_feedforward(cfg.law) else None
        )
        plant = self.scenario.nodes[loop.plant].build()
        self.law = build_law(cfg.law, u_bar=self._u_bar(), plant=plant, tau_s=loop.tau_s)
        self.closed = True
        self._samples: list[Sample] = []
        self._setpoints_changed = False
        self.subscribe(keys.meas(self.loop), Sample, self._on_meas)
        for name in self.setpoints:
            self.subscribe(self.scenario.setpoint_key(name), Setpoint, self._on_setpoint(name))
        if self.scenario.agent_node() is not None:
            self.subscribe(keys.wncsca_rates(), Rates, self._on_rates)

    def _u_bar(self) -> float:
        return self.feedforward.u_bar(self.setpoints) if self.feedforward is not None else 0.0

    def _on_meas(self, env: RawEnvelope, sample: Sample) -> None:
        self._samples.append(sample)

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
        if self._setpoints_changed and self.feedforward is not None:
            self.law.set_feedforward(self._u_bar())
            self._setpoints_changed = False
        if self.closed:
            for sample in self._samples:
                u = self.law.step(to_units(self.now), sample.value, self.setpoints[self.loop])
                self.publish(keys.move(self.loop), Move(value=u, t_computed=self.now))
        self._samples.clear()
