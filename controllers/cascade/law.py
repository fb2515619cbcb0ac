"""What the bus runs: the PI-P cascade of seed 004 (Fig. 2) as a multi-loop law.

A controller node with ``loops: [primary, secondary]`` and ``law: {type: pip_cascade, ...}``
runs :class:`controllers.cascade.model.PIPCascade`: a PI master on the primary loop's measurement
``y1`` sets the slave's set point ``r2 = Q1 (r1 - y1)``, and a proportional slave on the
secondary loop's measurement moves the primary loop's input, ``u = u_bias + Kc2 (r2 - y2)``. The
primary loop measures and moves (``sensor: y1, actuator: u``); the secondary loop only measures
(``actuator: null``, a **measurement-only** loop: it is sampled and delivered like any loop, but
the controller publishes no move for it). The primary loop's set point is ``r1``; the secondary
loop's set point is not used (the master's output is ``r2``).

The master integrates over the actual time between executions (backward Euler,
:class:`controllers.pi.PI`), starting with ``Kc1/Ti1 e dt`` at the first execution with ``dt``
the primary loop's sampling period, as :class:`~controllers.cascade.model.PIPCascade` does on the
sampled examples. Both loops should be sampled together (the same ``tau_s``, no path delays):
the node then executes once per sampling instant with both new samples (the hold rule of
:mod:`controllers.node`); otherwise each execution uses the latest sample of each.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from typing import Any, Literal

from controllers.cascade.model import PIPCascade, PIPCascadeConfig, PIPSettings

__all__ = ["PIPCascadeLawConfig", "PIPCascadeLaw", "cascade_variant", "ROUTINE_CASCADE"]


class PIPCascadeLawConfig(PIPSettings):
    """Settings of the PI-P cascade law (``type: pip_cascade``); the loops come from the node."""

    type: Literal["pip_cascade"]


class PIPCascadeLaw:
    """PI-P cascade over the loops ``[primary, secondary]``; ``step(t, y, r) -> {primary: u}``.

    Parameters
    ----------
    config : PIPCascadeLawConfig
        Gains and limits.
    loops : sequence of str
        ``[primary, secondary]``.
    tau_s : float
        The primary loop's sampling period (the master's first integral step).
    """

    multi_loop = True
    measurement_only_loops = True  # the secondary is measured, never moved

    def __init__(self, config: PIPCascadeLawConfig, loops: Sequence[str], *, tau_s: float) -> None:
        self.check_loops(config, loops)
        self.config = config
        self.primary, self.secondary = loops
        settings = config.model_dump(exclude={"type"})
        self._cascade = PIPCascade(
            PIPCascadeConfig(primary=self.primary, secondary=self.secondary, dt=tau_s, **settings)
        )

    @staticmethod
    def check_loops(config: PIPCascadeLawConfig, loops: Sequence[str]) -> None:
        """Exactly two loops: ``[primary, secondary]``."""
        if len(loops) != 2:
            raise ValueError(
                f"a PI-P cascade takes two loops [primary, secondary], got {list(loops)}"
            )

    @classmethod
    def from_config(
        cls,
        config: PIPCascadeLawConfig,
        *,
        loops: Sequence[str],
        plant: Any,
        tau_s: float,
        context: Any = None,
    ) -> PIPCascadeLaw:
        """Build from the scenario; the loops' signals (``context``) must be a primary that
        measures and moves and a secondary that only measures (``actuator: null``)."""
        cls.check_loops(config, loops)
        if context is not None:
            primary, secondary = loops
            sensor, actuator = context.signals[primary]
            if sensor is None or actuator is None:
                raise ValueError(
                    f"loops[0]: the primary loop {primary!r} must measure and move (sensor and "
                    "actuator)"
                )
            sensor, actuator = context.signals[secondary]
            if sensor is None or actuator is not None:
                raise ValueError(
                    f"loops[1]: the secondary loop {secondary!r} must measure and move nothing "
                    "(actuator: null): the master's output is its set point"
                )
        return cls(config, loops, tau_s=tau_s)

    def reset(self) -> None:
        """Forget the master's integral."""
        self._cascade.reset()

    def step(self, t: float, y: Mapping[str, float], r: Mapping[str, float]) -> dict[str, float]:
        """One execution: both loops' held measurements, the primary's set point ``r1``;
        returns the move of the primary loop (the secondary loop has none)."""
        return {self.primary: self._cascade.step(t, y, r[self.primary])}


def cascade_variant(
    data: Mapping[str, Any],
    *,
    loop: str,
    secondary: str,
    gains: Mapping[str, float],
    secondary_loop: str | None = None,
) -> dict[str, Any]:
    """A copy of a scenario mapping with loop ``loop``'s controller switched to the PI-P cascade.

    The same plant, disturbances, seeds and measurement noise; the loop's controller node gets
    ``loops: [loop, secondary_loop]`` and ``law: {type: pip_cascade, **gains}``, and a
    measurement-only loop ``secondary_loop`` (default ``<loop>_secondary``) samples plant output
    ``secondary`` with the loop's sampling period and network. Monitor nodes are left out (they
    assess the simple-feedback loop). Validate the result with
    :func:`scenario.load.parse_scenario`.
    """
    out = copy.deepcopy(dict(data))
    base = out["loops"][loop]
    name2 = secondary_loop or f"{loop}_secondary"
    out["name"] = f"{out['name']}_pip_{secondary}"
    out["nodes"] = {n: c for n, c in out["nodes"].items() if c.get("kind") != "monitor"}
    ctrl = out["nodes"][base["controller"]]
    ctrl.pop("loop", None)
    ctrl["loops"] = [loop, name2]
    ctrl["law"] = {"type": "pip_cascade", **gains}
    out["loops"][name2] = {
        "plant": base["plant"],
        "sensor": secondary,
        "actuator": None,
        "controller": base["controller"],
        "network": base["network"],
        "tau_s": base["tau_s"],
        "setpoint": 0.0,
    }
    return out


ROUTINE_CASCADE: dict[str, dict[str, dict[str, float]]] = {
    "cascade_routine": {
        "y2": {"Kc1": 2.98, "Ti1": 18.3, "Kc2": 8.78},
        "y3": {"Kc1": 4.38, "Ti1": 59.3, "Kc2": 1.31},
    },
    "cascade_routine_primary": {
        "y2": {"Kc1": 2.98, "Ti1": 18.1, "Kc2": 8.79},
        "y3": {"Kc1": 3.85, "Ti1": 29.6, "Kc2": 1.31},
    },
}
"""PI-P settings (``Kc1``, ``Ti1``, ``Kc2``) of ``scenarios/<name>.yaml`` per secondary output of
``cascade_ct``: variance-optimal on the exact sampled model over another realization
(``bench/monitor_cascade_switch.py --retune`` states the procedure and recomputes them)."""
