"""The coordination agent's trials of its closed-loop model (seed 000, III.C-III.E).

:class:`Trials` holds the agent's :class:`~agents.wncsca.spec.ClosedLoopSpec` (its judged loops
on wired paths of constant delay, under the set-point test) and the
:class:`~agents.wncsca.spec.Simulator` it is handed (the scenario layer's, on the direct
engine). Each trial says only what changes: every loop's period and delay, the steps (the
test's, moved to a phase of the period, or a judged step's), the end, and delay traces to
replay (:mod:`agents.wncsca.chance`). The agent's model (:class:`agents.wncsca.model.LoopModel`)
and its searches simulate through it; the one seam below it is the ``Simulator``.
"""

from __future__ import annotations

from collections.abc import Mapping

from agents.wncsca.config import ParameterUncertainty
from agents.wncsca.spec import ClosedLoopSpec, Simulator, Step, Trial
from agents.wncsca.uncertainty import believing
from core.record import RunRecord
from core.time import to_ticks, to_units

__all__ = ["Trials"]


class Trials:
    """The trials of ``spec`` run by ``simulate`` (see the module docstring)."""

    def __init__(self, spec: ClosedLoopSpec, simulate: Simulator) -> None:
        self.spec = spec
        self._simulate = simulate
        self.loops: tuple[str, ...] = spec.names
        self.benchmark: dict[str, float] = spec.benchmark
        self.fingerprint = spec.fingerprint
        self._belief: dict[str, dict[str, float]] = {}
        """Plant -> parameters believed since the simulator was built (:meth:`believing`):
        every trial carries them, under its own draw."""
        self.design: dict[str, dict[str, float]] = {}
        """Plant -> the parameters its controllers' feedforward is pinned to (:meth:`pinned`;
        none: the feedforward is designed on each trial's plant, as built)."""

    def believing(
        self,
        params: Mapping[str, Mapping[str, float]],
        uncertainty: Mapping[str, Mapping[str, ParameterUncertainty]],
    ) -> Trials:
        """These trials on the model believed anew (:func:`agents.wncsca.uncertainty.believing`:
        an identification's estimate and its uncertainty), by the same simulator."""
        out = Trials(believing(self.spec, params, uncertainty), self._simulate)
        out._belief = {p: dict(v) for p, v in self._belief.items()}
        out.design = {p: dict(v) for p, v in self.design.items()}
        for plant, values in params.items():
            out._belief.setdefault(plant, {}).update(values)
        return out

    def pinned(self, design: Mapping[str, Mapping[str, float]]) -> Trials:
        """These trials with the controllers' feedforward designed on ``design`` (plant ->
        parameters) whatever plant a trial runs: the controllers were built on the plant as it
        was, and do not drift with it (the trials' plants still follow belief and draws)."""
        out = Trials(self.spec, self._simulate)
        out._belief = {p: dict(v) for p, v in self._belief.items()}
        out.design = {p: dict(v) for p, v in self.design.items()}
        for plant, values in design.items():
            out.design.setdefault(plant, {}).update(values)
        return out

    def _trial(
        self,
        periods: Mapping[str, float],
        delays: Mapping[str, float],
        steps: tuple[Step, ...],
        end_time: float,
        traces: Mapping[str, list[float | None]] | None = None,
        params: Mapping[str, Mapping[str, float]] | None = None,
        noise: Mapping[str, Mapping[str, float]] | None = None,
        seed: int | None = None,
        offsets: Mapping[str, float] | None = None,
    ) -> Trial:
        return Trial(
            periods={n: float(periods.get(n, self.benchmark[n])) for n in self.loops},
            delays={n: float(delays.get(n, 0.0)) for n in self.loops},
            steps=steps,
            end_time=float(end_time),
            traces=traces,
            params=self._believed(params),
            noise=noise,
            seed=seed,
            design=self.design or None,
            offsets=offsets,
        )

    def _believed(
        self, params: Mapping[str, Mapping[str, float]] | None
    ) -> Mapping[str, Mapping[str, float]] | None:
        """A trial's parameters over the belief (a draw's values win)."""
        if not self._belief:
            return params
        out = {p: dict(v) for p, v in self._belief.items()}
        for plant, values in (params or {}).items():
            out.setdefault(plant, {}).update(values)
        return out

    def _moved(self, step: Step, periods: Mapping[str, float], k: int, n: int) -> Step:
        """``step`` moved to ``k/n`` of its loop's period after a sampling instant (samples at
        0, P, 2P, ...: phase 0 is a step at a sampling instant)."""
        p = to_ticks(float(periods.get(step.loop, self.benchmark[step.loop])))
        t = to_ticks(step.t)
        return Step(to_units((t // p) * p + (k * p) // n), step.loop, step.value, step.announce)

    def run(
        self,
        periods: Mapping[str, float],
        delays: Mapping[str, float],
        phase: tuple[int, int] | None,
    ) -> RunRecord:
        """One trial of the test with these periods (default benchmark) and delays (default 0);
        with ``phase=(k, n)`` every test step is moved to ``k/n`` of its loop's period after a
        sampling instant."""
        steps = self.spec.steps
        if phase is not None:
            steps = tuple(self._moved(s, periods, *phase) for s in steps)
        return self._simulate(self._trial(periods, delays, steps, self.spec.end_time))

    def run_steps(
        self,
        periods: Mapping[str, float],
        delays: Mapping[str, float],
        steps: list[tuple[float, str, float]],
        end_time: float,
        traces: Mapping[str, list[float | None]] | None = None,
        params: Mapping[str, Mapping[str, float]] | None = None,
        noise: Mapping[str, Mapping[str, float]] | None = None,
        seed: int | None = None,
        offsets: Mapping[str, float] | None = None,
    ) -> RunRecord:
        """One trial with these set-point ``steps`` (``(t, loop, value)``, time units) instead
        of the test's, run to ``end_time``, with each loop's sensor-path delays replayed from
        ``traces`` (default: the constant ``delays``), the plants' parameters replaced by
        ``params`` (default: the model's) and their measurement noise by ``noise`` under
        ``seed`` (default: the model's own), each loop's first sample at its ``offsets`` (default
        0). The steps keep the test's first step's lead (``announce``)."""
        lead = self.spec.steps[0].announce
        judged = tuple(Step(float(t), loop, float(v), lead) for t, loop, v in steps)
        trial = self._trial(periods, delays, judged, end_time, traces, params, noise, seed, offsets)
        return self._simulate(trial)

    def run_replay(
        self,
        periods: Mapping[str, float],
        delays: Mapping[str, float],
        traces: Mapping[str, list[float | None]],
        phases: Mapping[tuple[int, str], int],
        denominator: int,
        params: Mapping[str, Mapping[str, float]] | None = None,
    ) -> RunRecord:
        """One trial of the test with each loop's sensor-path delays replayed from ``traces``
        (loop -> delay of each sample, ``None``: lost) and the step at ``(tick, loop)`` moved to
        ``phases[...] / denominator`` of its loop's period after a sampling instant (the
        realizations of :mod:`agents.wncsca.chance`), the plants' parameters replaced by
        ``params`` (a draw of the model's uncertainty; default the model's own)."""
        steps = []
        for step in self.spec.steps:
            j = phases.get((to_ticks(step.t), step.loop))
            steps.append(step if j is None else self._moved(step, periods, j, denominator))
        trial = self._trial(periods, delays, tuple(steps), self.spec.end_time, traces, params)
        return self._simulate(trial)
