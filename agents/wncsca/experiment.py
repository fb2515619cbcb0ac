"""The agent's identification experiment on its loops (issue 35, item 3; seed 000 section II:
the ICAM's identification agent LMId "perturbs the plant with pseudo-random signals ... gathers
data and applies its model identification algorithm" in the ``identification`` mode).

:meth:`Experiment.plan` draws, for every loop named in the configuration's ``amplitude``, a
generalized binary noise (:func:`agents.identify.excitation.gbn`) on its set point: from its
initial value ``r0`` at ``t = 0`` the set point moves to ``r0 +- amplitude`` at the noise's clock
instants ``k * clock`` (``k >= 1``), never farther, and returns to ``r0`` at the experiment's
end. The draws come from a generator of the agent's own, seeded by the run's seed and
:data:`STREAM`, so the same scenario and seed give the same experiment on every engine.

While it runs, :meth:`Experiment.record` keeps every delivered sample of the agent's loops
(``loop/<l>/meas``): its value, the instant it was taken, and how long it travelled (the
delivery instant minus the sampling instant). :meth:`Experiment.seen` hands them to the fit
(:func:`agents.wncsca.identification.identify`) as a
:class:`~agents.wncsca.identification.ClosedLoopExperiment`: the set-point sequence, the
sampling periods, and each sampling instant's delay (``None``: the sample never arrived, or
arrived after the experiment ended). Sensors sample on the grid ``0, P, 2P, ...`` of the
identification mode's period ``P`` (the mode starts at ``t = 0``); a sample off that grid is
counted and left out.

The agent sees the sensor path only: a loop whose actuator path is wireless has that path's
delay in its trial as the constant control-path delay of the configuration the agent last
accepted. :meth:`Experiment.cost` states what the excitation cost: each loop's RMS deviation of
its delivered samples from ``r0`` during the experiment, in the signal's unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from agents.identify.excitation import gbn
from agents.wncsca.config import IdentifyConfig
from agents.wncsca.identification import ClosedLoopExperiment
from core.time import to_ticks, to_units

__all__ = ["Experiment", "STREAM"]

STREAM = 35
"""The identification experiment's stream of the agent's seeded generator (``[seed, STREAM]``)."""


@dataclass
class Experiment:
    """One identification experiment (see the module docstring).

    Attributes
    ----------
    config : IdentifyConfig
        What the scenario asked for.
    base : mapping
        Loop -> its set point when the experiment started (``r0``), every loop the agent judges.
    changes : tuple of (t, loop, value)
        The set-point changes the agent passes on, in time order (time units from the run's
        start); the last of each perturbed loop restores ``r0`` at :attr:`end`.
    periods : mapping
        Loop -> its sampling period during the experiment (time units).
    previous_mode : str
        The mode the experiment interrupted (restored when it ends).
    """

    config: IdentifyConfig
    base: Mapping[str, float]
    changes: tuple[tuple[float, str, float], ...]
    periods: Mapping[str, float]
    previous_mode: str
    samples: dict[str, dict[int, tuple[float, int]]] = field(default_factory=dict)
    """Loop -> sampling instant (ticks) -> (value, delay in ticks) of its delivered samples."""
    off_grid: int = 0
    """Delivered samples taken off the identification period's grid (left out)."""

    @classmethod
    def plan(
        cls,
        config: IdentifyConfig,
        setpoints: Mapping[str, float],
        periods: Mapping[str, float],
        seed: int,
        previous_mode: str,
    ) -> Experiment:
        """The experiment ``config`` asks for on loops at ``setpoints`` sampled at ``periods``
        (every loop the agent judges), its noise drawn from the agent's ``[seed, STREAM]``.

        Raises
        ------
        ValueError
            A perturbed loop without a set point or a sampling period.
        """
        rng = np.random.default_rng([seed, STREAM])
        n = max(int(math.floor(config.duration / config.clock + 1e-9)), 1)
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
                    changes.append((k * config.clock, loop, new))
                    value = new
            changes.append((config.duration, loop, r0))
        changes.sort(key=lambda c: (to_ticks(c[0]), c[1]))
        return cls(
            config=config,
            base={n: float(v) for n, v in sorted(setpoints.items())},
            changes=tuple(changes),
            periods={n: float(p) for n, p in sorted(periods.items())},
            previous_mode=previous_mode,
        )

    @property
    def end(self) -> float:
        """When the experiment ends (time units from the run's start)."""
        return self.config.duration

    def record(self, loop: str, value: float, t_sampled: int, now: int) -> None:
        """A sample of ``loop`` taken at ``t_sampled`` and delivered at ``now`` (ticks)."""
        if loop not in self.periods or t_sampled >= to_ticks(self.end):
            return
        if t_sampled % to_ticks(self.periods[loop]) != 0:
            self.off_grid += 1
            return
        self.samples.setdefault(loop, {})[t_sampled] = (float(value), now - t_sampled)

    def delivered(self) -> int:
        """How many samples were recorded, all loops."""
        return sum(len(s) for s in self.samples.values())

    def seen(self, delays: Mapping[str, float]) -> ClosedLoopExperiment:
        """What the fit takes (see the module docstring); ``delays`` are the loops' constant
        control-path delays (after the replayed sensor-path delays)."""
        steps = tuple((0.0, loop, r0) for loop, r0 in self.base.items())
        steps += tuple(c for c in self.changes if to_ticks(c[0]) < to_ticks(self.end))
        traces: dict[str, list[float | None]] = {}
        samples: dict[str, tuple[list[float], list[float]]] = {}
        for loop, period in self.periods.items():
            got = self.samples.get(loop, {})
            p = to_ticks(period)
            instants = range(0, to_ticks(self.end), p)
            traces[loop] = [to_units(got[t][1]) if t in got else None for t in instants]
            if got:
                t_sampled = sorted(got)
                samples[loop] = ([to_units(t) for t in t_sampled], [got[t][0] for t in t_sampled])
        return ClosedLoopExperiment(
            steps=steps,
            end_time=self.end,
            periods=dict(self.periods),
            delays={n: float(delays.get(n, 0.0)) for n in self.periods},
            traces=traces,
            samples=samples,
        )

    def cost(self) -> dict[str, float]:
        """Each loop's RMS deviation of its delivered samples from ``r0`` during the experiment
        (what the excitation cost in set-point error), in the signal's unit."""
        out = {}
        for loop, got in sorted(self.samples.items()):
            y = np.asarray([v for v, _ in got.values()], dtype=float)
            out[loop] = float(np.sqrt(np.mean((y - self.base[loop]) ** 2)))
        return out
