"""The network node: carries the loops that name it, with constant path delays.

Sensor samples (``plant/<p>/sensor/<s>``) are delivered on ``loop/<l>/meas`` after the loop's
``tau_d``; control moves (``loop/<l>/u``) on ``plant/<p>/actuator/<i>`` after ``tau_a``. A zero
delay forwards within the same instant (a microstep). A pending delivery is a timer, so in
real-time mode the delay passes in wall time through the same clock. This is the wired network;
the WSN gateway emulator extends it with multi-hop delay models, loss and energy.
"""

from __future__ import annotations

from typing import Any

from bus_schemas import Move, Sample, keys
from bus_schemas.envelope import RawEnvelope
from runtime.node import Node, NodeContext
from runtime.time import to_ticks

__all__ = ["NetworkNode"]


class NetworkNode(Node):
    def __init__(self, ctx: NodeContext) -> None:
        super().__init__(ctx)
        self.delivered = 0
        for name, loop in sorted(self.scenario.loops.items()):
            if loop.network != self.name:
                continue
            self.subscribe(
                keys.sensor(loop.plant, loop.sensor),
                Sample,
                self._path(keys.meas(name), to_ticks(loop.tau_d)),
            )
            self.subscribe(
                keys.move(name),
                Move,
                self._path(keys.actuator(loop.plant, loop.actuator), to_ticks(loop.tau_a)),
            )

    def _path(self, out_key: str, delay: int) -> Any:
        def forward(env: RawEnvelope, body: Any) -> None:
            if delay == 0:
                self.publish(out_key, body)
            else:
                self.at(self.now + delay, lambda: self.publish(out_key, body))

        return forward
