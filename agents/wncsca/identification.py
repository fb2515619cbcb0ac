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
:mod:`agents.identify.greybox` does on an open-loop experiment. The covariance is the
Gauss-Newton one, ``s^2 (J^T J)^-1``; it becomes the agent's uncertainty of the identified
parameters (a relative standard deviation each), so its guarantee covers what identification
left unknown.

The trial's outputs are read from its plant's true state on the monitoring grid (not from its
noisy samples), so the residuals are the plant's measurement noise and the model's error alone.
The trial starts from the model's initial state, so an experiment's time 0 is the run's: the
identification mode at the start of a run (the ICAM's own order: identification, then control).
An experiment later in a run would start the trial from the state the model settles to at the
experiment's first set points; that is not built yet.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from agents.identify.greybox import DIVERGED
from agents.wncsca.model import LoopModel
from agents.wncsca.uncertainty import plant_model
from core.time import to_ticks

__all__ = ["ClosedLoopExperiment", "Identified", "identify"]


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
) -> Identified:
    """Fit the ``free`` parameters (plant -> names) of the agent's model to ``experiment``,
    starting from ``start`` (default: the model's own values); see the module docstring.

    Raises
    ------
    ValueError
        A free parameter that is not a non-zero number of its plant's model, or an experiment
        with fewer delivered samples than free parameters.
    """
    spec = model.trials.spec
    names = tuple((p, n) for p, params in sorted(free.items()) for n in params)
    p0 = []
    for plant, name in names:
        value = (start or {}).get(plant, {}).get(name, spec.plants[plant].params.get(name))
        if isinstance(value, bool) or not isinstance(value, int | float) or value == 0:
            raise ValueError(f"identify: {plant}.{name} is not a non-zero parameter ({value!r})")
        p0.append(float(value))
    scale = np.asarray(p0)
    loops = tuple(sorted(experiment.samples))
    y = np.concatenate([np.asarray(experiment.samples[n][1], dtype=float) for n in loops])
    if len(y) <= len(names):
        raise ValueError(f"identify: {len(y)} samples for {len(names)} parameters")
    trials = 0

    def params_of(theta: NDArray[np.float64]) -> dict[str, dict[str, float]]:
        out: dict[str, dict[str, float]] = {}
        for (plant, name), v in zip(names, (theta * scale).tolist(), strict=True):
            out.setdefault(plant, {})[name] = v
        return out

    def residuals(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        nonlocal trials
        trials += 1
        outputs = _trial_outputs(model, experiment, params_of(theta))
        r = y - np.concatenate([outputs[n] for n in loops])
        return np.where(np.isfinite(r), r, DIVERGED)

    result = scipy.optimize.least_squares(residuals, np.ones(len(names)), x_scale="jac")
    r = result.fun
    s2 = float(r @ r) / (len(y) - len(names))
    covariance = s2 * np.linalg.pinv(result.jac.T @ result.jac) * np.outer(scale, scale)
    sigma, fits, offset = {}, {}, 0
    for n in loops:
        values = np.asarray(experiment.samples[n][1], dtype=float)
        rr = r[offset : offset + len(values)]
        offset += len(values)
        sigma[n] = float(np.sqrt(np.mean(rr**2)))
        spread = float(np.linalg.norm(values - values.mean()))
        fits[n] = 100.0 * (1.0 - float(np.linalg.norm(rr)) / spread) if spread > 0 else 0.0
    return Identified(params_of(result.x), names, covariance, sigma, fits, trials)


def _trial_outputs(
    model: LoopModel,
    experiment: ClosedLoopExperiment,
    params: Mapping[str, Mapping[str, float]],
) -> dict[str, NDArray[np.float64]]:
    """The model's outputs, with ``params``, at each delivered sample's instant (by loop)."""
    spec = model.trials.spec
    rec = model.trials.run_steps(
        experiment.periods,
        experiment.delays,
        list(experiment.steps),
        experiment.end_time,
        experiment.traces,
        params,
    )
    model.simulations += 1
    out = {}
    for loop, (t_sampled, _) in experiment.samples.items():
        judged = spec.loops[loop]
        plant = plant_model(spec.plants[judged.plant], params.get(judged.plant, {}))
        states = rec.plants[judged.plant]
        where = {t: i for i, t in enumerate(states.t)}
        k = plant.output_names.index(judged.sensor)
        values = []
        for t in t_sampled:
            i = where.get(to_ticks(float(t)))
            values.append(np.nan if i is None else float(plant.outputs(states.x[i])[k]))
        out[loop] = np.asarray(values)
    return out
