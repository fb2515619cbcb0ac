"""A loop of a scenario as linear systems for python-control (the notebook API's
:func:`linearized_loop`).

The plant is linearised at the equilibrium that holds the set points of all its loops
(:mod:`plants.linearization`: the plant's own equilibrium and Jacobians where it has them);
the loop's channel is sampled at its period with its whole delay from sample to applied move,
``tau_d + tau_a``, exactly (:mod:`plants.sampled`: zero-order hold, the fractional delay as two
pieces per period); its PI law is :func:`controllers.pi.pi_state_space` with the steady-state
feedforward linearised (``d u_bar / d r``, seed 000 eq. (5)-(7)). The other loops of the plant
are open: their inputs stay at the equilibrium. Limits and anti-windup are ignored: the model
holds for steps small enough that no move saturates. For the JCSTR level (a linear plant) it is
exact: its step response equals the direct engine's samples and moves (a test checks it).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from controllers.pi import PIConfig
from controllers.pi_linear import pi_state_space
from controllers.registry import uses_feedforward
from plants.linearization import equilibrium, linearize
from plants.sampled import sampled_with_delay
from scenario import Scenario

if TYPE_CHECKING:
    import control

__all__ = ["LinearLoop", "linearized_loop"]

_FF_STEP = 1e-4  # relative step of the feedforward's central difference


@dataclass(frozen=True)
class LinearLoop:
    """Loop ``loop`` of a scenario as linear systems, in deviations from the operating point.

    Attributes
    ----------
    plant : control.StateSpace
        The plant linearised at ``(x_bar, u_bar)``, continuous, every input and output.
    sampled : control.StateSpace
        Discrete (``dt = tau_s``): the loop's move (the actuator) to its sample (the sensor),
        the delay ``tau_d + tau_a`` included.
    controller : control.StateSpace or None
        Discrete PI law, inputs ``r`` and the sensor, output the actuator (``None`` when the
        loop's law is not a PI: only the plant and its sampled channel are given).
    closed : control.StateSpace or None
        The closed loop from ``r`` to the sensor and the actuator.
    """

    loop: str
    sensor: str
    actuator: str
    tau_s: float
    delay: float
    x_bar: dict[str, float]
    u_bar: dict[str, float]
    y_bar: float
    plant: control.StateSpace
    sampled: control.StateSpace
    controller: control.StateSpace | None
    closed: control.StateSpace | None

    def step_response(self, size: float, samples: int) -> control.TimeResponseData:
        """The closed loop's response to a set-point step of ``size`` at sample 0, over
        ``samples`` periods (outputs in deviations: add ``y_bar`` / ``u_bar``)."""
        import control

        if self.closed is None:
            raise ValueError(f"loop {self.loop!r}: no closed loop (its law is not a PI)")
        t = np.arange(samples) * self.tau_s
        return control.forced_response(self.closed, T=t, U=np.full(samples, size))


def linearized_loop(
    scenario: Scenario,
    loop: str,
    *,
    setpoints: Mapping[str, float] | None = None,
    tau_s: float | None = None,
    tau_d: float | None = None,
) -> LinearLoop:
    """Loop ``loop`` of ``scenario`` linearised and sampled (module docstring).

    ``setpoints`` (loop -> value) choose the operating point (default: the loops' initial set
    points); ``tau_s`` and ``tau_d`` replace the loop's sampling period and sensor-path delay.

    Raises
    ------
    ValueError
        If the loop is unknown, or has no sensor or no actuator.
    """
    import control

    if loop not in scenario.loops:
        raise ValueError(f"no loop {loop!r} (loops: {', '.join(sorted(scenario.loops))})")
    cfg = scenario.loops[loop]
    if cfg.sensor is None or cfg.actuator is None:
        raise ValueError(f"loop {loop!r} needs a sensor and an actuator to be closed")
    node = scenario.plants()[cfg.plant]
    model = node.build()
    mine = {
        n: lp
        for n, lp in scenario.loops_of_plant(cfg.plant).items()
        if lp.sensor is not None and lp.actuator is not None
    }
    sp = {n: float(lp.setpoint) for n, lp in mine.items() if lp.setpoint is not None}
    sp.update(setpoints or {})
    x0 = np.array([node.x0[s] for s in model.state_names], dtype=float)
    u0 = np.array([node.u0[s] for s in model.input_names], dtype=float)
    y_bar = {mine[n].sensor: v for n, v in sp.items() if n in mine}
    free = [model.input_names.index(mine[n].actuator) for n in sp if n in mine]
    x_bar, u_bar = equilibrium(model, y_bar, x0, u0, free)
    plant = linearize(model, x_bar, u_bar)
    h = float(tau_s if tau_s is not None else cfg.tau_s)
    delay = float(tau_d if tau_d is not None else cfg.tau_d) + cfg.tau_a
    iu = list(model.input_names).index(cfg.actuator)
    iy = list(model.output_names).index(cfg.sensor)
    channel = control.ss(
        plant.A,
        np.asarray(plant.B)[:, [iu]],
        np.asarray(plant.C)[[iy], :],
        [[0.0]],
        states=list(plant.state_labels),
        inputs=[cfg.actuator],
        outputs=[cfg.sensor],
    )
    sampled = sampled_with_delay(channel, h, delay)
    law = scenario.nodes[cfg.controller].law
    controller = closed = None
    if isinstance(law, PIConfig):
        gain = _feedforward_gain(scenario, loop, sp) if uses_feedforward(law) else 0.0
        controller = pi_state_space(
            law, h, feedforward_gain=gain, signals=("r", cfg.sensor, cfg.actuator)
        )
        closed = control.interconnect(
            [sampled, controller], inplist=["r"], outlist=[cfg.sensor, cfg.actuator]
        )
    return LinearLoop(
        loop=loop,
        sensor=cfg.sensor,
        actuator=cfg.actuator,
        tau_s=h,
        delay=delay,
        x_bar=dict(zip(model.state_names, map(float, x_bar), strict=True)),
        u_bar=dict(zip(model.input_names, map(float, u_bar), strict=True)),
        y_bar=float(np.asarray(model.outputs(x_bar))[iy]),
        plant=plant,
        sampled=sampled,
        controller=controller,
        closed=closed,
    )


def _feedforward_gain(scenario: Scenario, loop: str, setpoints: Mapping[str, float]) -> float:
    """``d u_bar / d r`` of the loop's feedforward at ``setpoints``, by central difference."""
    ff = scenario.feedforward(loop)
    d = _FF_STEP * max(1.0, abs(setpoints[loop]))
    up = {**setpoints, loop: setpoints[loop] + d}
    down = {**setpoints, loop: setpoints[loop] - d}
    return (ff.u_bar(up) - ff.u_bar(down)) / (2 * d)
