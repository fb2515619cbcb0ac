"""A stretch of the run as the agent saw it, ready to replay on its model (issue 35, items 3
and 4).

The agent does not see its plant: it sees the set points it passed on and the samples the
network delivered (``loop/<l>/meas``: a value, the instant it was taken, the instant it
arrived; a lost sample is absent). A :class:`Window` keeps them from :attr:`~Window.kept` (where
its replay starts, :attr:`~Window.t0`, unless the agent had not kept samples so far back) to
:attr:`~Window.end`, with the set points from :attr:`~Window.t0`; the samples from
:attr:`~Window.since` are the ones its replay is compared with. :meth:`Window.seen` turns them
into the
:meth:`Window.seen` turns them into the
:class:`~agents.wncsca.identification.ClosedLoopExperiment` that the agent's trials replay: the
identification experiment fits its model to one (:mod:`agents.wncsca.experiment`), and the model
watch compares its model with one (:mod:`agents.wncsca.watch`).

**Where a replay starts.** A trial starts from the model's initial state (the scenario's ``x0``
and its first set points). A window whose replay starts at ``t0 = 0`` is replayed from there as
the run went. A later one assumes the plant settled at the set points it had at ``t0`` (the
caller picks a ``t0`` after which nothing moved them for a settling time, as a judged step
assumes: :mod:`agents.wncsca.steps`): the trial moves every set point there at once and lets
the model settle for ``settle`` first, so trial time is run time ``- t0 + settle``.

**The run's sampling grid.** In the run a loop's sensor samples on the grid its last retime
gave it (:meth:`Window.phase`: the phase most of its delivered samples share; a sample off it
was taken under another period, and is left out and counted in :attr:`Window.off_grid`). The
replay samples each loop on the same grid (its first sample at the replay's offset of that
phase) and gives each trial sample the delay its run sample travelled (``None``: lost); before
:attr:`~Window.since`, where a sample of the window's grid may be missing because nothing was
kept so far back or the loop sampled at another period then, the loop's median delivered delay.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from agents.wncsca.identification import ClosedLoopExperiment
from core.time import to_ticks, to_units

__all__ = ["Window"]


@dataclass(kw_only=True)
class Window:
    """What the agent saw of its loops from :attr:`t0` to :attr:`end` (see the module docstring).

    Attributes
    ----------
    t0, end : float
        Where its replay starts, and where it ends (time units from the run's start).
    base : mapping
        Loop -> its set point at ``t0`` (every loop the agent judges).
    changes : tuple of (t, loop, value)
        The set-point changes the agent passed on from ``t0``, in time order.
    periods : mapping
        Loop -> its sampling period in the window (time units).
    """

    t0: float
    end: float
    base: Mapping[str, float]
    changes: tuple[tuple[float, str, float], ...]
    periods: Mapping[str, float]
    since: float | None = None
    """The samples taken from here are compared with the replay (time units; ``None``: from
    :attr:`t0`)."""
    kept: float | None = None
    """Samples taken from here are kept (time units; ``None``: from :attr:`t0`); before it
    the replay's samples travel the median delay."""
    samples: dict[str, dict[int, tuple[float, int]]] = field(default_factory=dict)
    """Loop -> sampling instant (ticks) -> (value, delay in ticks) of its delivered samples."""

    @property
    def start(self) -> float:
        """Where the samples compared with the replay start (time units)."""
        return self.t0 if self.since is None else self.since

    @property
    def kept_from(self) -> float:
        """Where the samples kept start (time units)."""
        return self.t0 if self.kept is None else self.kept

    def record(self, loop: str, value: float, t_sampled: int, now: int) -> None:
        """A sample of ``loop`` taken at ``t_sampled`` and delivered at ``now`` (ticks)."""
        if loop not in self.periods or not to_ticks(self.kept_from) <= t_sampled < to_ticks(
            self.end
        ):
            return
        self.samples.setdefault(loop, {})[t_sampled] = (float(value), now - t_sampled)

    def phase(self, loop: str) -> int:
        """The phase (ticks, within the loop's period) most of its samples share (0: none)."""
        p = to_ticks(self.periods[loop])
        counts = Counter(t % p for t in self.samples.get(loop, {}))
        if not counts:
            return 0
        top = max(counts.values())
        return min(a for a, c in counts.items() if c == top)

    def _on_grid(self, loop: str) -> dict[int, tuple[float, int]]:
        p, a = to_ticks(self.periods[loop]), self.phase(loop)
        return {t: s for t, s in self.samples.get(loop, {}).items() if (t - a) % p == 0}

    @property
    def off_grid(self) -> int:
        """Delivered samples off their loop's grid (:meth:`phase`), left out."""
        return sum(len(s) - len(self._on_grid(n)) for n, s in self.samples.items())

    def delivered(self) -> int:
        """How many samples count (on their loop's grid), all loops."""
        return sum(len(self._on_grid(n)) for n in self.samples)

    def seen(self, delays: Mapping[str, float], settle: float = 0.0) -> ClosedLoopExperiment:
        """The window as its replay takes it (module docstring): ``delays`` are the loops'
        constant control-path delays (after the replayed sensor-path delays), ``settle`` how
        long the model settles at :attr:`base` first (0 for a replay from the run's start)."""
        lag = to_ticks(settle) - to_ticks(self.t0)  # trial ticks = run ticks + lag
        steps = tuple((0.0, loop, r0) for loop, r0 in self.base.items())
        steps += tuple(
            (to_units(to_ticks(t) + lag), loop, v)
            for t, loop, v in self.changes
            if to_ticks(t) < to_ticks(self.end)
        )
        end = to_ticks(self.end) + lag
        traces: dict[str, list[float | None]] = {}
        samples: dict[str, tuple[list[float], list[float]]] = {}
        offsets: dict[str, float] = {}
        for loop, period in self.periods.items():
            got = self._on_grid(loop)
            offset = (self.phase(loop) + lag) % to_ticks(period)
            traces[loop] = self._trace(loop, got, offset, lag, end)
            if offset:
                offsets[loop] = to_units(offset)
            compared = sorted(t for t in got if t >= to_ticks(self.start))
            if compared:
                samples[loop] = (
                    [to_units(t + lag) for t in compared],
                    [got[t][0] for t in compared],
                )
        return ClosedLoopExperiment(
            steps=steps,
            end_time=to_units(end),
            periods=dict(self.periods),
            delays={n: float(delays.get(n, 0.0)) for n in self.periods},
            traces=traces,
            samples=samples,
            offsets=offsets,
        )

    def _trace(
        self, loop: str, got: Mapping[int, tuple[float, int]], offset: int, lag: int, end: int
    ) -> list[float | None]:
        """Each replayed sample's sensor delay: the run's sample at the same instant; where
        there is none, ``None`` (lost) from :attr:`start` on, the median delivered delay before
        (nothing kept there, or the loop sampled at another period then)."""
        settling = to_units(int(np.median([d for _, d in got.values()]))) if got else 0.0
        kept, since = to_ticks(self.kept_from), to_ticks(self.start)
        out: list[float | None] = []
        for tau in range(offset, end, to_ticks(self.periods[loop])):
            t = tau - lag
            hit = got.get(t)
            if hit is not None and t >= kept:
                out.append(to_units(hit[1]))
            else:  # lost where compared; before, unknown (not kept, or another period then)
                out.append(None if t >= since else settling)
        return out

    def cost(self) -> dict[str, float]:
        """Each loop's RMS deviation of its delivered samples from its set point at
        :attr:`t0`, in the signal's unit."""
        out = {}
        for loop in sorted(self.samples):
            y = np.asarray([v for v, _ in self._on_grid(loop).values()], dtype=float)
            if y.size == 0:
                continue
            out[loop] = float(np.sqrt(np.mean((y - self.base[loop]) ** 2)))
        return out
