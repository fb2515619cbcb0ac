"""The model watch: does the agent's model still fit its plant? (issue 35, item 4.)

The agent's guarantee is only as good as its model, and plants drift (heat exchangers foul,
valves wear). After every step it judged (:func:`agents.wncsca.steps.judge_step`), the agent
keeps what its loops delivered for the test's length (a :class:`~agents.wncsca.window.Window`)
and at its end compares it with its model:

* **Innovations.** The window replayed on the model (:meth:`Window.seen`: the model settled at
  the set points before the step, then the same step, sampling periods and delivered delays, no
  noise) predicts each delivered sample; the innovation ``e = y - y_model``, over its loop's
  noise level ``sigma`` (the identification's residual RMS, else the believed sensor noise),
  gives the window's statistic ``T = mean((e / sigma)^2)`` over every delivered sample of every
  loop. This is an output-error prediction over the window (the model's simulation of it), not
  a one-step-ahead one: the agent has no state estimate of its plant, and the window's whole
  response is what its guarantee predicted.
* **What no change looks like.** In a closed loop the innovations are coloured (a noisy sample
  moves the controller, and the plant after it), so ``T`` has no textbook distribution. The
  agent replays the same window ``replays`` times on its model as it states it: each replay with
  a parameter set of its stated uncertainty in turn (:func:`agents.wncsca.uncertainty.model_draws`)
  and sensor noise of ``sigma`` (a seed of its own each), and computes the same ``T`` of the
  replay against the noise-free prediction. Their mean ``m0`` and standard deviation ``s0`` give
  the window's score ``z = (T - m0) / s0``: 0 for a window as the model expects, large for one
  it does not explain.
* **A sequential test.** A one-sided CUSUM on the scores (Page 1954; Basseville & Nikiforov,
  *Detection of Abrupt Changes*, 1993, section 2.2): ``S = max(0, S + z - k)``, the model flagged
  when ``S > h`` (defaults ``k = 0.5``, ``h = 5``: a standard normal score drifts ``S`` down,
  one window far outside what the model explains flags at once, a persistent small misfit
  accumulates over windows). A flag resets ``S``.

Beside the test the agent states the measured overshoot of the step (its delivered samples)
against the model's on the same delays, so a reader sees what the misfit does to the promise.
What the agent does on a flag (identify again, or widen its stated uncertainty, then judge the
running configurations again) is the coordinator's
(:meth:`agents.wncsca.coordinator.Coordinator.watched`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import NDArray

from agents.wncsca.config import WatchConfig
from agents.wncsca.identification import ClosedLoopExperiment, trial_outputs
from agents.wncsca.model import LoopModel
from agents.wncsca.uncertainty import model_draws
from agents.wncsca.window import Window
from core.time import to_ticks

__all__ = ["Score", "StepFit", "Watch", "score", "STREAM", "SIGMA_FLOOR"]

STREAM = 37
"""The watch's replays' seeds: ``[run seed, STREAM, window, replay]``."""

SIGMA_FLOOR = 1e-3
"""The smallest noise level a loop is judged at, relative to its set point's magnitude (a
sensor's resolution of 0.1 % of its reading): a noise-free sensor's samples are still compared
with a replay that is not exact (delays before the window, the grid of another period)."""


@dataclass(frozen=True)
class StepFit:
    """A step of a watched window: ``loop`` from ``r_from`` to ``r_to`` at ``t`` (time units),
    its overshoot (%) in the delivered samples, and the model's on the same delays: as samples
    this noisy would read it (the median over the replays) and noise-free. A noisy sample
    reads an overshoot high (the largest of many noisy samples), so the first two compare."""

    loop: str
    r_from: float
    r_to: float
    t: float
    overshoot_measured: float
    overshoot_expected: float
    overshoot_model: float

    def describe(self) -> str:
        return (
            f"{self.loop} {self.r_from:g} -> {self.r_to:g} at t={self.t:g} overshot "
            f"{self.overshoot_measured:.1f} % in its delivered samples (the model on the same "
            f"delays: {self.overshoot_expected:.1f} % in samples this noisy, "
            f"{self.overshoot_model:.1f} % noise-free)"
        )


@dataclass(frozen=True)
class Score:
    """One window as the model watch judged it (module docstring).

    Attributes
    ----------
    steps : tuple of StepFit
        The steps the window follows, each with its overshoot measured and predicted.
    samples : int
        Delivered samples compared.
    rms : mapping
        Loop -> the innovations' RMS (signal units).
    sigma : mapping
        Loop -> the noise level they are judged against.
    statistic, expected, spread : float
        ``T``, and the replays' mean ``m0`` and standard deviation ``s0`` of it.
    z : float
        The window's score.
    """

    steps: tuple[StepFit, ...]
    samples: int
    rms: Mapping[str, float]
    sigma: Mapping[str, float]
    statistic: float
    expected: float
    spread: float
    z: float

    def describe(self) -> str:
        rms = ", ".join(
            f"{n} {v:.3g} against noise {self.sigma[n]:.3g}" for n, v in sorted(self.rms.items())
        )
        steps = "; ".join(s.describe() for s in self.steps)
        return (
            f"model watch after {steps}: innovations RMS {rms} over {self.samples} delivered "
            f"samples; T = {self.statistic:.3g} where the model expects {self.expected:.3g} +- "
            f"{self.spread:.2g} (score {self.z:.3g})"
        )


@dataclass
class Watch:
    """The CUSUM of the window scores (module docstring)."""

    config: WatchConfig
    cusum: float = 0.0
    windows: int = 0
    """Windows judged so far (each replay's seed names its window)."""

    def update(self, s: Score) -> bool:
        """Add a window's score; ``True``: the model is flagged (and the sum starts again)."""
        self.windows += 1
        self.cusum = max(0.0, self.cusum + s.z - self.config.allowance)
        if self.cusum > self.config.threshold:
            self.cusum = 0.0
            return True
        return False


def score(
    model: LoopModel,
    window: Window,
    delays: Mapping[str, float],
    sigma: Mapping[str, float],
    settle: float,
    replays: int,
    seed: int,
    index: int,
) -> Score | None:
    """The window's score on ``model`` (module docstring); ``sigma``: each loop's noise level,
    ``settle``: how long the model settles before the window, ``index``: the window's number in
    the run (its replays' seeds). ``None``: nothing delivered to compare, or the model cannot
    replay the window (no equilibrium holds a set point on it; fewer than three of its draws
    can)."""
    exp = window.seen(delays, settle)
    loops = tuple(sorted(exp.samples))
    if not loops or not any(to_ticks(t) >= to_ticks(window.start) for t, _, _ in window.changes):
        return None
    spec = model.trials.spec
    noise_of = {
        n: max(float(sigma.get(n, 0.0)), SIGMA_FLOOR * abs(float(window.base[n])), 1e-12)
        for n in loops
    }
    quiet: dict[str, dict[str, float]] = {p: {} for p in spec.plants}
    try:
        predicted = trial_outputs(model, exp, {}, noise=quiet)
    except ValueError:  # the model cannot replay the window (e.g. no equilibrium holds r)
        return None
    measured = {n: np.asarray(exp.samples[n][1], dtype=float) for n in loops}
    statistic, rms, count = _statistic(measured, predicted, noise_of)
    noisy: dict[str, dict[str, float]] = {p: {} for p in spec.plants}
    for n in loops:
        noisy[spec.loops[n].plant][spec.loops[n].sensor] = noise_of[n]
    draws = model_draws(spec, model.config, seed)
    null, noisy_replays = [], []
    for b in range(replays):
        seeds = np.random.SeedSequence([seed, STREAM, index, b])
        trial_seed = int(seeds.generate_state(1)[0])
        rng = np.random.default_rng(seeds)
        try:
            replay = trial_outputs(
                model, exp, draws.sets[b % len(draws.sets)], noise=noisy, seed=trial_seed
            )
        except ValueError:  # a draw the model refuses: no replay of it
            continue
        sampled = {n: replay[n] + noise_of[n] * rng.standard_normal(len(replay[n])) for n in loops}
        null.append(_statistic(sampled, predicted, noise_of)[0])
        noisy_replays.append(sampled)
    if len(null) < 3:
        return None
    expected = float(np.mean(null))
    spread = float(np.std(null, ddof=1))
    z = (statistic - expected) / spread if spread > 0 else _sign_inf(statistic - expected)
    steps = []
    for t, loop, r_from, r_to, tau, tau_last in _steps(window, exp):
        step = partial(_overshoot, exp, loop, r_from=r_from, r_to=r_to, t_step=tau, t_last=tau_last)
        in_noise = float(np.median([step(y.get(loop)) for y in noisy_replays]))
        fit = (step(measured.get(loop)), in_noise, step(predicted.get(loop)))
        steps.append(StepFit(loop, r_from, r_to, t, *fit))
    return Score(
        steps=tuple(steps),
        samples=count,
        rms=rms,
        sigma=noise_of,
        statistic=statistic,
        expected=expected,
        spread=spread,
        z=float(z),
    )


def _steps(
    window: Window, exp: ClosedLoopExperiment
) -> list[tuple[float, str, float, float, float, float]]:
    """The window's own steps as ``(t, loop, r_from, r_to, tau, tau_last)`` (``tau``: in the
    replay): its changes from :attr:`Window.start`, a ramp's moves (a loop's changes at most two
    periods apart) as one step from its first move (``tau``) to its last (``tau_last``)."""
    out: list[tuple[float, str, float, float, float, float]] = []
    setpoints = dict(window.base)
    replayed = exp.steps[len(window.base) :]  # after every loop's set point at 0
    last: dict[str, float] = {}
    for (t, loop, r_to), (tau, _, _) in zip(window.changes, replayed, strict=True):
        r_from = float(setpoints[loop])
        setpoints[loop] = r_to
        if to_ticks(t) < to_ticks(window.start):
            continue  # a change before the window: replayed, not judged
        ramping = out and out[-1][1] == loop and t - last[loop] <= 2 * window.periods[loop]
        last[loop] = t
        if ramping:
            t0, _, first, _, tau0, _ = out[-1]
            out[-1] = (t0, loop, first, float(r_to), tau0, float(tau))
        else:
            out.append((float(t), loop, r_from, float(r_to), float(tau), float(tau)))
    return out


def _statistic(
    y: Mapping[str, NDArray[np.float64]],
    predicted: Mapping[str, NDArray[np.float64]],
    sigma: Mapping[str, float],
) -> tuple[float, dict[str, float], int]:
    """``T`` of ``y`` against ``predicted``, each loop's innovation RMS, and the count (samples
    the prediction does not reach, NaN, are left out)."""
    total, count, rms = 0.0, 0, {}
    for n, values in sorted(y.items()):
        e = values - predicted[n]
        e = e[np.isfinite(e)]
        if e.size == 0:
            continue
        rms[n] = float(np.sqrt(np.mean(e**2)))
        total += float(np.sum((e / sigma[n]) ** 2))
        count += int(e.size)
    return (total / count if count else 0.0), rms, count


def _overshoot(
    exp: ClosedLoopExperiment,
    loop: str,
    y: NDArray[np.float64] | None,
    *,
    r_from: float,
    r_to: float,
    t_step: float,
    t_last: float,
) -> float:
    """The step's largest excursion past ``r_to`` after ``t_step`` (replay time; a ramp's last
    move at ``t_last``), in percent of the change (0 when none), over the instants of
    ``loop``'s delivered samples up to its next change."""
    if y is None or r_to == r_from:
        return 0.0
    later = [t for t, lp, _ in exp.steps if lp == loop and t > t_last]
    until = min(later, default=math.inf)
    t = np.asarray(exp.samples[loop][0], dtype=float)
    after = y[(t >= t_step) & (t < until) & np.isfinite(y)]
    if after.size == 0:
        return 0.0
    return max(0.0, float(np.max((after - r_to) / (r_to - r_from))) * 100.0)


def _sign_inf(x: float) -> float:
    return math.inf if x > 0 else (-math.inf if x < 0 else 0.0)
