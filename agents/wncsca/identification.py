"""The agent's identification of its own model from the loops' delivered samples (issue 35, item
3; seed 000 section II, the identification agent LMId).

An identification experiment perturbs the loops' set points with generalized binary noise
(:func:`agents.identify.excitation.gbn`) and collects what the network delivers: each sample's
value, the instant it was taken and how long it travelled (a lost one is absent). The agent does
not see the plant's inputs (the moves go from the controllers to the actuators), but it knows
its loops: so it fits the **closed loop**. For candidate parameters of its plant model, its trial
of the experiment (:meth:`agents.wncsca.trials.Trials.run_steps`: the same set-point sequence,
the same sampling periods, each sample's delay replayed from the experiment) gives the plant's
outputs at the samples' instants, and :func:`scipy.optimize.least_squares` fits them to the
delivered values over the free parameters (each scaled by its starting value), as
:mod:`agents.identify.greybox` does on an open-loop experiment. The fit's trials carry no
measurement noise: their outputs are read from the plant's true state on the monitoring grid,
with controllers acting on clean samples.

**The covariance comes from a parametric bootstrap**, not from ``s^2 (J^T J)^-1``. In a closed
loop the residuals are not white: a noisy sample moves the real controller and the plant after
it, in both loops of a coupled plant, which the noise-free trial does not follow. The
Gauss-Newton covariance takes the residuals as independent and understated the spread of the
reactor's U by about 2x (``bench/wncsca_identify_calibration.py``: the truth inside the stated
95 % interval in 12 of 20 seeds; a Newey-West sandwich within each loop, 16 of 20). So the
agent repeats its experiment ``bootstrap`` times on the fitted model (the same set points,
periods, delays and losses; each sensor with white noise of its residuals' RMS, a seed of the
agent's own per replicate, the controllers acting on the noisy samples), refits each, and takes
the replicates' covariance as the estimate's. It becomes the agent's uncertainty of the
identified parameters (a relative standard deviation each), so its guarantee covers what
identification left unknown. Both covariances are kept (:class:`Identified`).

The trial starts from the model's initial state: an experiment at the run's start is replayed
from there, a later one after the model settles at the set points it started from
(:meth:`agents.wncsca.window.Window.seen`). A candidate the model refuses (no equilibrium holds a
set point of the experiment) is a diverged residual, which the search steps back from.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from agents.identify.greybox import DIVERGED
from agents.wncsca.model import LoopModel
from agents.wncsca.uncertainty import plant_model
from core.time import to_ticks

__all__ = ["ClosedLoopExperiment", "Identified", "identify", "trial_outputs", "BOOTSTRAP"]

BOOTSTRAP = 20
"""Replicates of the parametric bootstrap that gives the estimate's covariance."""

REPLICATE_STREAM = 36
"""The bootstrap's noise seeds: ``[run seed, REPLICATE_STREAM, replicate]``."""


@dataclass(frozen=True)
class ClosedLoopExperiment:
    """An identification experiment as the agent saw it.

    Attributes
    ----------
    steps : tuple of (t, loop, value)
        The set-point sequence, from ``t = 0`` of the experiment (time units): every loop's
        set point at 0, then the perturbation's changes.
    end_time : float
        The experiment's length.
    periods : mapping
        Each loop's sampling period during it.
    delays : mapping
        Each loop's constant control-path delay (what a sample's own delay is added to).
    traces : mapping
        Loop -> each sample's sensor-path delay in order (``None``: lost), as delivered.
    samples : mapping
        Loop -> ``(t_sampled, y)`` of its delivered samples (time units from the experiment's
        start).
    """

    steps: tuple[tuple[float, str, float], ...]
    end_time: float
    periods: Mapping[str, float]
    delays: Mapping[str, float]
    traces: Mapping[str, list[float | None]]
    samples: Mapping[str, tuple[Sequence[float], Sequence[float]]]
    offsets: Mapping[str, float] = field(default_factory=dict)
    """Loop -> its first sampling instant in the replay (time units; none named: 0)."""


@dataclass(frozen=True)
class Identified:
    """The identified parameters (plant -> parameter -> value), their covariance in the order of
    :attr:`names` (``(plant, parameter)``), the residuals' standard deviation per loop, the fit
    per loop (``100 (1 - |r| / |y - mean(y)|)``) and the trials the search took."""

    params: Mapping[str, Mapping[str, float]]
    names: tuple[tuple[str, str], ...]
    covariance: NDArray[np.float64]
    sigma: Mapping[str, float]
    fit_pct: Mapping[str, float]
    trials: int
    gauss_newton: NDArray[np.float64]
    """The plain Gauss-Newton covariance ``s^2 (J'J)^-1`` (white residuals assumed), beside the
    bootstrap's :attr:`covariance`, which the agent states."""

    def std(self, plant: str, name: str) -> float:
        i = self.names.index((plant, name))
        return float(np.sqrt(self.covariance[i, i]))

    def rel_sd(self, plant: str, name: str) -> float:
        return self.std(plant, name) / abs(float(self.params[plant][name]))


def identify(
    model: LoopModel,
    free: Mapping[str, Sequence[str]],
    experiment: ClosedLoopExperiment,
    start: Mapping[str, Mapping[str, float]] | None = None,
    *,
    bootstrap: int = BOOTSTRAP,
) -> Identified:
    """Fit the ``free`` parameters (plant -> names) of the agent's model to ``experiment``,
    starting from ``start`` (default: the model's own values), their covariance from a
    parametric bootstrap of ``bootstrap`` replicates; see the module docstring.

    Raises
    ------
    ValueError
        A free parameter that is not a non-zero number of its plant's model, an experiment
        with fewer delivered samples than free parameters, or ``bootstrap < 2``.
    """
    spec = model.trials.spec
    names = tuple((p, n) for p, params in sorted(free.items()) for n in params)
    p0 = []
    for plant, name in names:
        value = (start or {}).get(plant, {}).get(name, spec.plants[plant].params.get(name))
        if isinstance(value, bool) or not isinstance(value, int | float) or value == 0:
            raise ValueError(f"identify: {plant}.{name} is not a non-zero parameter ({value!r})")
        p0.append(float(value))
    if bootstrap < 2:
        raise ValueError(f"identify: bootstrap must be >= 2, got {bootstrap}")
    fit = _Fit(model, experiment, names, np.asarray(p0))
    y = fit.measured()
    if len(y) <= len(names):
        raise ValueError(f"identify: {len(y)} samples for {len(names)} parameters")
    result = fit.solve(y, np.ones(len(names)))
    r = result.fun
    scale = np.outer(fit.scale, fit.scale)
    s2 = float(r @ r) / (len(y) - len(names))
    plain = s2 * np.linalg.pinv(result.jac.T @ result.jac) * scale
    sigma, fits, offset = {}, {}, 0
    for n in fit.loops:
        values = np.asarray(experiment.samples[n][1], dtype=float)
        rr = r[offset : offset + len(values)]
        offset += len(values)
        sigma[n] = float(np.sqrt(np.mean(rr**2)))
        spread = float(np.linalg.norm(values - values.mean()))
        fits[n] = 100.0 * (1.0 - float(np.linalg.norm(rr)) / spread) if spread > 0 else 0.0
    fitted = fit.outputs(result.x)
    replicates = np.asarray(
        [fit.solve(fit.replicate(result.x, sigma, fitted, b), result.x).x for b in range(bootstrap)]
    )
    covariance = np.atleast_2d(np.cov(replicates, rowvar=False)) * scale
    return Identified(fit.params_of(result.x), names, covariance, sigma, fits, fit.trials, plain)


class _Fit:
    """The output-error fit of :func:`identify`: trials of the experiment with candidate
    parameters and no measurement noise, their outputs at the delivered samples' instants."""

    def __init__(
        self,
        model: LoopModel,
        experiment: ClosedLoopExperiment,
        names: tuple[tuple[str, str], ...],
        scale: NDArray[np.float64],
    ) -> None:
        self.model, self.experiment, self.names, self.scale = model, experiment, names, scale
        self.loops = tuple(sorted(experiment.samples))
        spec = model.trials.spec
        self.quiet: dict[str, dict[str, float]] = {p: {} for p in spec.plants}
        self.trials = 0

    def params_of(self, theta: NDArray[np.float64]) -> dict[str, dict[str, float]]:
        out: dict[str, dict[str, float]] = {}
        for (plant, name), v in zip(self.names, (theta * self.scale).tolist(), strict=True):
            out.setdefault(plant, {})[name] = v
        return out

    def measured(self) -> NDArray[np.float64]:
        """The experiment's delivered values in the order of the residuals."""
        samples = self.experiment.samples
        return np.concatenate([np.asarray(samples[n][1], dtype=float) for n in self.loops])

    def outputs(self, theta: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """The quiet trial's outputs with parameters ``theta`` at the delivered instants."""
        self.trials += 1
        return trial_outputs(self.model, self.experiment, self.params_of(theta), noise=self.quiet)

    def solve(self, y: NDArray[np.float64], theta0: NDArray[np.float64]) -> Any:
        """``least_squares`` of ``y`` against the quiet trials' outputs from ``theta0``."""

        def residuals(theta: NDArray[np.float64]) -> NDArray[np.float64]:
            try:
                outputs = self.outputs(theta)
            except ValueError:  # parameters the model refuses (e.g. no equilibrium holds r)
                return np.full(len(y), DIVERGED)
            r = y - np.concatenate([outputs[n] for n in self.loops])
            return np.where(np.isfinite(r), r, DIVERGED)

        return scipy.optimize.least_squares(residuals, theta0, x_scale="jac")

    def replicate(
        self,
        theta: NDArray[np.float64],
        sigma: Mapping[str, float],
        fitted: Mapping[str, NDArray[np.float64]],
        b: int,
    ) -> NDArray[np.float64]:
        """Replicate ``b`` of the experiment on the fitted model: the same set points, periods
        and delays, each loop's sensor with white noise of its residuals' RMS (its own seed),
        the controllers acting on the noisy samples; its delivered samples at the experiment's
        instants (a loss the trial did not replay keeps the ``fitted`` output there)."""
        spec = self.model.trials.spec
        exp = self.experiment
        noise: dict[str, dict[str, float]] = {p: {} for p in spec.plants}
        for n in self.loops:
            noise[spec.loops[n].plant][spec.loops[n].sensor] = sigma[n]
        seed = int(np.random.SeedSequence([spec.seed, REPLICATE_STREAM, b]).generate_state(1)[0])
        rec = self.model.trials.run_steps(
            exp.periods,
            exp.delays,
            list(exp.steps),
            exp.end_time,
            exp.traces,
            self.params_of(theta),
            noise=noise,
            seed=seed,
            offsets=exp.offsets,
        )
        self.trials += 1
        out = []
        for n in self.loops:
            lp = rec.loops[n]
            got = {int(ts): float(v) for ts, v in zip(lp.t_sampled, lp.y, strict=True)}
            for t, f in zip(exp.samples[n][0], fitted[n], strict=True):
                out.append(got.get(to_ticks(float(t)), float(f)))
        return np.asarray(out)


def trial_outputs(
    model: LoopModel,
    experiment: ClosedLoopExperiment,
    params: Mapping[str, Mapping[str, float]],
    *,
    noise: Mapping[str, Mapping[str, float]],
    seed: int | None = None,
) -> dict[str, NDArray[np.float64]]:
    """The model's outputs (its plants' true outputs, not the noisy samples), with ``params``
    and measurement ``noise`` (under ``seed``, default the model's), at each delivered sample's
    instant (by loop)."""
    spec = model.trials.spec
    rec = model.trials.run_steps(
        experiment.periods,
        experiment.delays,
        list(experiment.steps),
        experiment.end_time,
        experiment.traces,
        params,
        noise=noise,
        seed=seed,
        offsets=experiment.offsets,
    )
    model.simulations += 1
    out = {}
    for loop, (t_sampled, _) in experiment.samples.items():
        judged = spec.loops[loop]
        plant = plant_model(spec.plants[judged.plant], params.get(judged.plant, {}))
        states = rec.plants[judged.plant]
        k = plant.output_names.index(judged.sensor)
        out[loop] = _output_at(states.t, states.x, partial(_output, plant, k), t_sampled)
    return out


def _output(plant: Any, k: int, x: Sequence[float]) -> float:
    return float(plant.outputs(x)[k])


def _output_at(
    grid: Sequence[int], states: Sequence[Sequence[float]], output: Any, at: Sequence[float]
) -> NDArray[np.float64]:
    """``output(state)`` at the instants ``at`` (time units) from the states on the monitoring
    ``grid`` (ticks): exact on the grid, linear between its points, NaN outside it."""
    ticks = np.asarray(grid, dtype=np.int64)
    values = np.full(len(at), np.nan)
    cache: dict[int, float] = {}

    def y(i: int) -> float:
        if i not in cache:
            cache[i] = float(output(states[i]))
        return cache[i]

    for j, t in enumerate(at):
        tick = to_ticks(float(t))
        i = int(np.searchsorted(ticks, tick))
        if i < len(ticks) and ticks[i] == tick:
            values[j] = y(i)
        elif 0 < i < len(ticks):
            w = (tick - ticks[i - 1]) / (ticks[i] - ticks[i - 1])
            values[j] = (1.0 - w) * y(i - 1) + w * y(i)
    return values
