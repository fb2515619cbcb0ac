"""The agent's closed-loop model: its judged loops' plants and controllers with every loop carried
by a wired path of constant delay, under the agent's set-point test, simulated by the ``direct``
engine through the :class:`~agents.wncsca.trials.Trials` it is handed (seed 000, III.C-III.E:
the WNCSCA judges a configuration by simulating its loops).

:meth:`LoopModel.overshoots` is the one question every search asks: "with these sampling periods
and these control-path delays, how far does each loop overshoot its set-point step?". The answer
is the worst case over the step's phase relative to the sampling instants (or the paper's fixed
phase), memoised, since the searches revisit trials.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from agents.wncsca.config import WncscaConfig
from agents.wncsca.trials import Trials
from core.record import RunRecord, loop_metrics
from core.time import to_ticks

__all__ = ["LoopModel", "Evaluation"]


@dataclass(frozen=True)
class Evaluation:
    """Overshoots of one trial: per loop, the worst over the phases tried (%; ``inf`` when the
    simulation diverged), and per phase."""

    periods: dict[str, float]
    delays: dict[str, float]
    overshoot_pct: dict[str, float]
    by_phase: tuple[dict[str, float], ...]

    def ok(self, limit: float, loops: Any = None) -> bool:
        """Every loop (or those named) within ``limit``."""
        names = self.overshoot_pct if loops is None else loops
        return all(self.overshoot_pct[n] <= limit for n in names)


class LoopModel:
    """A scenario's loops as the agent simulates them.

    Parameters
    ----------
    trials : Trials
        The simulator of the model (the scenario's plants, controllers and loops on wired
        paths, under the agent's set-point test).
    config : WncscaConfig
        The agent's configuration (test, phase handling).
    """

    def __init__(self, trials: Trials, config: WncscaConfig) -> None:
        self.trials = trials
        self.config = config
        # loops of multi-loop controllers on links are governed by their update period instead
        self.loops: tuple[str, ...] = tuple(trials.loops)
        self.benchmark = dict(trials.benchmark)
        self.fingerprint = hashlib.sha256(
            json.dumps(
                {"model": trials.fingerprint, "phase": config.phase, "phases": config.phases},
                sort_keys=True,
            ).encode()
        ).hexdigest()[:16]
        self._memo: dict[tuple[tuple[int, ...], tuple[int, ...]], Evaluation] = {}
        self.simulations = 0

    def evaluate(self, periods: Mapping[str, float], delays: Mapping[str, float]) -> Evaluation:
        """Overshoot of every loop with these periods (default: benchmark) and control-path
        delays (default: 0), each in time units."""
        per = {n: float(periods.get(n, self.benchmark[n])) for n in self.loops}
        dly = {n: float(delays.get(n, 0.0)) for n in self.loops}
        for n, p in per.items():
            if to_ticks(p) < 1:
                raise ValueError(f"period of loop {n!r} is shorter than one tick: {p}")
            if not dly[n] >= 0:
                raise ValueError(f"delay of loop {n!r} must be >= 0, got {dly[n]}")
        key = (
            tuple(to_ticks(per[n]) for n in self.loops),
            tuple(to_ticks(dly[n]) for n in self.loops),
        )
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        n_phases = 1 if self.config.phase == "fixed" else self.config.phases
        by_phase = tuple(self._simulate(per, dly, k, n_phases) for k in range(n_phases))
        worst = {n: max(ph[n] for ph in by_phase) for n in self.loops}
        result = Evaluation(per, dly, worst, by_phase)
        self._memo[key] = result
        return result

    def _simulate(
        self, periods: dict[str, float], delays: dict[str, float], k: int, n: int
    ) -> dict[str, float]:
        phase = (k, n) if self.config.phase == "worst" else None
        self.simulations += 1
        rec = self.trials.run(periods, delays, phase)
        return dict(zip(self.loops, self.overshoots_of(rec), strict=True))

    def overshoots_of(self, rec: RunRecord) -> list[float]:
        """Each loop's overshoot (%) in a trial's record, in :attr:`loops` order (``inf``:
        diverged)."""
        diverged = {
            name
            for name, plant in rec.plants.items()
            if not all(math.isfinite(v) for row in plant.x for v in row)
        }
        out = []
        for name in self.loops:
            os_pct = loop_metrics(rec, name)["overshoot_pct"]
            bad = os_pct is None or not math.isfinite(os_pct)
            out.append(math.inf if bad or rec.loops[name].plant in diverged else os_pct)
        return out
