"""Judging a requested set-point step before it is applied (issue 14, item 4).

The agent's periods are negotiated for the steps of its test; a step requested at run time
(``ops/setpoint``, ``wncs inject ... setpoint``, the scenario's ``setpoints:``) may be larger,
the other way round, or meet saturation the test never did (the JCSTR's downward temperature
steps: the jacket inflow hits zero). :func:`judge_step` simulates the requested step on the
non-linear model before it is let through:

* the trial starts from the scenario's initial state, moves every loop to its current set point
  at once, lets the plant settle for the test's length, then makes the requested step at a
  random phase of the loop's period, and judges the step's overshoot over the test's length;
* each of ``realizations`` trials replays its own delay sequence drawn from the accepted
  proposal's delay distributions (:class:`agents.wncsca.chance.LoopLaw`: the shape located at
  the loop's mean delay, losses held), seeded from the scenario seed, the loop and the value;
  trial ``r`` runs on the model's parameter set ``r mod M`` of its stated uncertainty
  (:func:`agents.wncsca.uncertainty.model_draws`; robust: its corners in turn), the model
  itself when none is stated;
* the candidates are tried in order: the control periods now in force, then the stepped loop
  at its benchmark period, then every loop at its benchmark period. The first candidate whose
  share of trials within the limit is at least ``confidence`` (at most ``floor((1 - confidence)
  n)`` exceed it) is the verdict: ``apply`` at the control periods, or ``tighten`` to the
  candidate's periods for the transient (the agent relaxes them after the test's length); when
  none passes, ``refuse`` with the predicted overshoot (the ``confidence``-quantile of the last
  candidate's trials).

The plant need not be settled at the current set points when the request comes; the trial
assumes it is (a step requested mid-transient is judged as if from steady state).

A refused step comes with its safe alternative (:func:`safe_alternative`, issue 35 item 5): the
fastest set-point ramp to the same value that the judge lets through, tried over
:data:`RAMP_LENGTHS` times the test's length. A ramp is a staircase of one set-point change per
control period of the loop (``judge_step(..., ramp=D)``), and its overshoot is the excursion past
the final value after the ramp, in percent of the whole change. On the JCSTR a 4 C downward
temperature step overshoots about 56 % (the jacket's hot inflow cannot go below zero, and the
reactor cools only through the jacket); ramped over 2 pu it overshoots about 14 %.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.wncsca.chance import PHASES, LoopLaw, probability_interval, risk_index
from agents.wncsca.model import LoopModel
from agents.wncsca.uncertainty import model_draws
from core.record import loop_metrics
from core.time import to_ticks, to_units

__all__ = [
    "RAMP_LENGTHS",
    "StepVerdict",
    "Alternative",
    "judge_step",
    "safe_alternative",
    "staircase",
    "test_length",
]

RAMP_LENGTHS = (0.125, 0.25, 0.5, 1.0, 2.0)
"""The ramps a refused step's alternative tries, in multiples of the test's length (shortest
first: the fastest safe ramp is offered)."""


@dataclass(frozen=True)
class StepVerdict:
    """``apply``, ``tighten`` (to ``periods``) or ``refuse`` a requested step, with the share of
    trials within the limit, its 95 % interval and the predicted (``confidence``-quantile)
    overshoot at the chosen (or, when refused, the last tried) periods."""

    verdict: str
    loop: str
    r_from: float
    r_to: float
    periods: dict[str, float]
    p: float
    interval: tuple[float, float]
    overshoot_pct: float
    tried: list[dict[str, Any]] = field(default_factory=list)

    def reason(self, limit: float) -> str:
        what = f"{self.loop} {self.r_from:g} -> {self.r_to:g}"
        odds = (
            f"P(overshoot <= {limit:g} %) = {self.p:.2f} (95 % CI {self.interval[0]:.2f}-"
            f"{self.interval[1]:.2f}), predicted overshoot {self.overshoot_pct:.1f} %"
        )
        per = ", ".join(f"{n} {p:g}" for n, p in sorted(self.periods.items()))
        if self.verdict == "apply":
            return f"step {what}: {odds} at the control periods ({per})"
        if self.verdict == "tighten":
            return f"step {what}: periods tightened to {per} for the transient; {odds}"
        return f"step {what} refused: {odds} even at the periods {per}"


@dataclass(frozen=True)
class Alternative:
    """A refused step made safe: the same change as a ramp over ``duration`` (time units),
    judged (``verdict``: ``apply`` or ``tighten``)."""

    verdict: StepVerdict
    duration: float

    def reason(self) -> str:
        v = self.verdict
        rate = abs(v.r_to - v.r_from) / self.duration
        per = ", ".join(f"{n} {p:g}" for n, p in sorted(v.periods.items()))
        return (
            f"safe alternative: ramp {v.loop} {v.r_from:g} -> {v.r_to:g} over "
            f"{self.duration:g} time units ({rate:.3g} per time unit, one step per control "
            f"period): P(overshoot <= limit) = {v.p:.2f}, predicted overshoot "
            f"{v.overshoot_pct:.1f} % at the periods {per}"
        )


def safe_alternative(judge: Callable[[float], StepVerdict], length: float) -> Alternative | None:
    """The fastest ramp of :data:`RAMP_LENGTHS` (times the test's ``length``) that ``judge``
    (:func:`judge_step` of the refused step, given the ramp's duration) lets through; ``None``
    if none."""
    for factor in RAMP_LENGTHS:
        step = judge(factor * length)
        if step.verdict != "refuse":
            return Alternative(step, factor * length)
    return None


def judge_step(
    model: LoopModel,
    laws: Mapping[str, LoopLaw],
    delays: Mapping[str, float],
    control: Mapping[str, float],
    setpoints: Mapping[str, float],
    loop: str,
    value: float,
    seed: int,
    ramp: float = 0.0,
) -> StepVerdict:
    """The verdict on stepping ``loop`` from ``setpoints[loop]`` to ``value`` (module
    docstring); ``delays`` are the loops' mean control-path delays, ``control`` the control
    periods in force; ``ramp > 0``: ramped over that long instead (time units)."""
    cfg = model.config
    limit, confidence = cfg.overshoot_limit, cfg.confidence
    n = max(2, cfg.checks)
    k_max = risk_index(n, confidence)
    settle = test_length(model)
    bench = dict(model.benchmark)
    candidates = [dict(control), {**control, loop: min(control[loop], bench[loop])}, bench]
    unique: list[dict[str, float]] = []
    for c in candidates:
        if c not in unique:
            unique.append(c)
    rng = np.random.default_rng([seed, zlib.crc32(loop.encode()), to_ticks(abs(value)) % 2**31])
    u_delay = {lp: rng.random(100_000) for lp in sorted(model.loops)}
    u_loss = {lp: rng.random(100_000) for lp in sorted(model.loops)}
    phases = rng.integers(0, PHASES, size=n)
    draws = model_draws(model.trials.spec, cfg, seed)
    tried: list[dict[str, Any]] = []
    last: tuple[dict[str, float], float, tuple[float, float], float] | None = None
    for periods in unique:
        overshoots = []
        for r in range(n):
            p = to_ticks(periods[loop])
            t_step = to_units((to_ticks(settle) // p) * p + (int(phases[r]) * p) // PHASES)
            steps = [(0.0, name, float(v)) for name, v in sorted(setpoints.items())]
            start = float(setpoints[loop])
            stairs = staircase(t_step, start, float(value), periods[loop], ramp)
            steps += [(t, loop, v) for t, v in stairs]
            end = t_step + ramp + settle
            traces = _traces(laws, delays, periods, end, u_delay, u_loss, r)
            params = draws.sets[r % len(draws.sets)] or None  # the model's draws in turn
            try:
                rec = model.trials.run_steps(periods, delays, steps, end, traces, params)
            except ValueError:  # a plant of the belief that cannot hold the set point fails
                overshoots.append(math.inf)
                continue
            model.simulations += 1
            if ramp > 0.0:
                overshoots.append(_ramp_overshoot(model, rec, loop, start, stairs))
            else:
                overshoots.append(_step_overshoot(rec, loop, t_step))
        os = np.asarray(overshoots)
        within = int(np.sum(os <= limit))
        ci = probability_interval(within, n)
        q = float(np.quantile(os, confidence)) if np.isfinite(os).all() else math.inf
        tried.append({"periods": dict(periods), "p": within / n, "overshoot_pct": q})
        last = (periods, within / n, ci, q)
        if n - within <= k_max:
            verdict = "apply" if periods == dict(control) else "tighten"
            return StepVerdict(
                verdict,
                loop,
                float(setpoints[loop]),
                float(value),
                dict(periods),
                within / n,
                ci,
                q,
                tried,
            )
    assert last is not None
    periods, share, ci, q = last
    return StepVerdict(
        "refuse", loop, float(setpoints[loop]), float(value), dict(periods), share, ci, q, tried
    )


def test_length(model: LoopModel) -> float:
    """The agent's test horizon (time units): how long a trial settles and judges a step."""
    return float(model.trials.spec.end_time)


def _traces(
    laws: Mapping[str, LoopLaw],
    delays: Mapping[str, float],
    periods: Mapping[str, float],
    end: float,
    u_delay: Mapping[str, np.ndarray],
    u_loss: Mapping[str, np.ndarray],
    r: int,
) -> dict[str, list[float | None]]:
    out: dict[str, list[float | None]] = {}
    for name, law in laws.items():
        count = int(end / periods[name]) + 2
        lo = (r * count) % max(1, len(u_delay[name]) - count)
        window = slice(lo, lo + count)
        out[name] = law.trace(
            float(delays.get(name, 0.0)), u_delay[name][window], u_loss[name][window]
        )
    return out


def staircase(
    t_step: float, start: float, value: float, period: float, ramp: float
) -> list[tuple[float, float]]:
    """The set-point changes of a step at ``t_step`` (one), or of a ramp over ``ramp``: one
    change per ``period`` (at least one), the last to ``value`` at ``t_step + ramp``."""
    if ramp <= 0.0:
        return [(t_step, value)]
    k = max(1, round(ramp / period))
    return [(t_step + ramp * i / k, start + (value - start) * i / k) for i in range(1, k + 1)]


def _ramp_overshoot(
    model: LoopModel, rec: Any, loop: str, start: float, staircase: list[tuple[float, float]]
) -> float:
    """The excursion of ``loop``'s output past the ramp's final value after it ends, in percent
    of the whole change (``inf``: diverged)."""
    spec = model.trials.spec
    judged = spec.loops[loop]
    plant = spec.plants[judged.plant].model
    states = rec.plants[judged.plant]
    t = np.asarray([to_units(v) for v in states.t])
    x = np.asarray(states.x, dtype=float)
    k = plant.output_names.index(judged.sensor)
    y = np.asarray([plant.outputs(row)[k] for row in x[t >= staircase[-1][0] - 1e-12]])
    final = staircase[-1][1]
    change = final - start
    if not np.isfinite(y).all() or change == 0.0:
        return math.inf if not np.isfinite(y).all() else 0.0
    past = (y - final) / change  # > 0 past the final value in the step's direction
    return max(0.0, float(np.max(past)) * 100.0)


def _step_overshoot(rec: Any, loop: str, t_step: float) -> float:
    steps = loop_metrics(rec, loop)["steps"]
    for s in steps:
        if abs(s["t"] - t_step) < 1e-9:
            v = s["overshoot_pct"]
            return math.inf if v is None or not math.isfinite(v) else float(v)
    return math.inf
