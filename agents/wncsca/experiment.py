"""The agent's identification experiment on its loops (issue 35, item 3; seed 000 section II:
the ICAM's identification agent LMId "perturbs the plant with pseudo-random signals ... gathers
data and applies its model identification algorithm" in the ``identification`` mode).

:meth:`Experiment.plan` draws, for every loop named in the configuration's ``amplitude``, a
generalized binary noise (:func:`agents.identify.excitation.gbn`) on its set point: from its
value ``r0`` when the experiment starts at ``t0`` (the run's start, or when the model watch found
the model wrong: :mod:`agents.wncsca.watch`) the set point moves to ``r0 +- amplitude`` at the
noise's clock instants ``t0 + k * clock`` (``k >= 1``), never farther, and returns to ``r0`` at
the experiment's end. The draws come from a generator of the agent's own, seeded by the run's
seed and :data:`STREAM` (and the experiment's index after the first), so the same scenario and
seed give the same experiments on every engine.

An experiment is a :class:`~agents.wncsca.window.Window` of the run: while it runs,
:meth:`~agents.wncsca.window.Window.record` keeps every delivered sample of the agent's loops
(``loop/<l>/meas``): its value, the instant it was taken, and how long it travelled.
:meth:`~agents.wncsca.window.Window.seen` hands them to the fit
(:func:`agents.wncsca.identification.identify`) as a
:class:`~agents.wncsca.identification.ClosedLoopExperiment`: the set-point sequence, the
sampling periods, and each sampling instant's delay (``None``: the sample never arrived, or
arrived after the experiment ended). An experiment at ``t = 0`` starts where the model starts;
a later one is replayed after the model settles at its first set points (the window's rule).

The agent sees the sensor path only: a loop whose actuator path is wireless has that path's
delay in its trial as the constant control-path delay of the configuration the agent last
accepted. :meth:`~agents.wncsca.window.Window.cost` states what the excitation cost: each loop's
RMS deviation of its delivered samples from ``r0`` during the experiment, in the signal's unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from agents.identify.excitation import gbn
from agents.wncsca.config import IdentifyConfig
from agents.wncsca.window import Window
from core.time import to_ticks

__all__ = ["Experiment", "STREAM"]

STREAM = 35
"""The identification experiment's stream of the agent's seeded generator (``[seed, STREAM]``)."""


@dataclass(kw_only=True)
class Experiment(Window):
    """One identification experiment (see the module docstring): a :class:`Window` of the run
    from :attr:`t0` to :attr:`end` whose set-point changes the agent planned.

    Attributes
    ----------
    config : IdentifyConfig
        What the scenario asked for.
    previous_mode : str
        The mode the experiment interrupted (restored when it ends).
    """

    config: IdentifyConfig
    previous_mode: str

    @classmethod
    def plan(
        cls,
        config: IdentifyConfig,
        setpoints: Mapping[str, float],
        periods: Mapping[str, float],
        seed: int,
        previous_mode: str,
        t0: float = 0.0,
        index: int = 0,
    ) -> Experiment:
        """The experiment ``config`` asks for from ``t0`` on loops at ``setpoints`` sampled at
        ``periods`` (every loop the agent judges), its noise drawn from the agent's
        ``[seed, STREAM]`` (the run's ``index``-th experiment, from 0: ``[seed, STREAM,
        index]`` after the first).

        Raises
        ------
        ValueError
            A perturbed loop without a set point or a sampling period.
        """
        rng = np.random.default_rng([seed, STREAM] if index == 0 else [seed, STREAM, index])
        n = max(int(math.floor(config.duration / config.clock + 1e-9)), 1)
        end = t0 + config.duration
        changes: list[tuple[float, str, float]] = []
        for loop, amplitude in sorted(config.amplitude.items()):
            if loop not in setpoints or loop not in periods:
                raise ValueError(f"identify.amplitude.{loop}: not a loop the agent judges")
            r0 = float(setpoints[loop])
            swing = gbn(n, config.switch, amplitude, rng)
            value = r0
            for k in range(1, n):
                new = r0 + float(swing[k])
                if new != value:
                    changes.append((t0 + k * config.clock, loop, new))
                    value = new
            changes.append((end, loop, r0))
        changes.sort(key=lambda c: (to_ticks(c[0]), c[1]))
        return cls(
            t0=t0,
            end=end,
            base={n: float(v) for n, v in sorted(setpoints.items())},
            changes=tuple(changes),
            periods={n: float(p) for n, p in sorted(periods.items())},
            config=config,
            previous_mode=previous_mode,
        )
