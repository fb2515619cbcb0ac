"""A plant model's own physical parameters from an experiment, by non-linear least squares on its
right-hand side (grey-box identification), with their covariance.

The experiment is what the plant was given and what was measured: the inputs held from each
move's instant (zero-order hold, as the plant node applies them), the initial state, and the
samples of some outputs at the instants they were taken (a sample delayed or lost on the network
still has its sampling instant; a lost one is simply absent). For candidate parameters the model
is integrated over the experiment with the platform's RK4 (:func:`plants.integrate.rk4`, the
same steps the plant node takes) and the residuals are the samples minus the model's outputs at
their instants. :func:`scipy.optimize.least_squares` minimises their sum of squares over the free
parameters, each scaled by its initial value (the search runs on ``p_i / p_i0``, all of order 1).

The covariance is the Gauss-Newton one at the optimum, ``s^2 (J^T J)^-1`` with
``s^2 = |r|^2 / (N - p)`` (Seber and Wild, Nonlinear Regression, eq. (2.22)); with Gaussian
measurement noise and an experiment that excites every free parameter, the estimate's error is
approximately normal with it, which the calibration test checks.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from plants.integrate import rk4

DIVERGED = 1e9
"""The residual of a sample a candidate's simulation diverged on: far from any data."""

__all__ = ["Experiment", "GreyBoxFit", "fit_grey_box", "simulate_experiment"]


@dataclass(frozen=True)
class Experiment:
    """What a plant was given and what was measured (see the module docstring).

    Attributes
    ----------
    x0 : sequence of float
        The state at ``t = t_moves[0]``, in the model's ``state_names`` order.
    t_moves : sequence of float
        Instants (time units, increasing) from which each row of ``u`` is held.
    u : array, shape (moves, inputs)
        The inputs held, in the model's ``input_names`` order.
    samples : mapping
        Output name -> ``(t, y)``: the instants its samples were taken and their values.
    max_step : float
        The RK4 step the plant node integrates with.
    """

    x0: Sequence[float]
    t_moves: Sequence[float]
    u: NDArray[np.float64]
    samples: Mapping[str, tuple[Sequence[float], Sequence[float]]]
    max_step: float = 0.005
    _events: list[tuple[float, int, str, int]] = field(default_factory=list, repr=False)

    def events(self) -> list[tuple[float, int, str, int]]:
        """``(t, kind, output, index)`` in time order: moves (kind 0) before samples (1)."""
        if not self._events:
            out = [(float(t), 0, "", i) for i, t in enumerate(self.t_moves)]
            for name, (ts, _) in self.samples.items():
                out += [(float(t), 1, name, k) for k, t in enumerate(ts)]
            self._events.extend(sorted(out))
        return self._events


def simulate_experiment(model: Any, experiment: Experiment) -> dict[str, NDArray[np.float64]]:
    """The model's outputs at the experiment's sampling instants (output name -> values, in the
    samples' order; NaN where the state left the finite numbers)."""
    x = np.asarray(experiment.x0, dtype=float)
    t = float(experiment.t_moves[0])
    u = np.asarray(experiment.u[0], dtype=float)
    index = {n: model.output_names.index(n) for n in experiment.samples}
    out = {n: np.full(len(experiment.samples[n][0]), np.nan) for n in experiment.samples}
    for t_event, kind, name, k in experiment.events():
        if t_event > t:
            x = rk4(model.rhs, t, x, t_event, u, max_step=experiment.max_step)
            t = t_event
        if kind == 0:
            u = np.asarray(experiment.u[k], dtype=float)
        elif np.isfinite(x).all():
            out[name][k] = float(model.outputs(x)[index[name]])
    return out


@dataclass(frozen=True)
class GreyBoxFit:
    """The estimated free parameters with their covariance and the fit's figures.

    Attributes
    ----------
    params : mapping
        Every parameter: the free ones estimated, the others as given.
    names : tuple of str
        The free parameters, in the covariance's order.
    covariance : ndarray
        Their covariance (in the parameters' units).
    sigma : float
        The residuals' standard deviation (the measurement noise, if the model is right).
    fit_pct : dict
        Per output, ``100 (1 - |y - y_model| / |y - mean(y)|)``.
    samples, evaluations : int
        Samples fitted; model simulations the search took.
    """

    params: Mapping[str, float]
    names: tuple[str, ...]
    covariance: NDArray[np.float64]
    sigma: float
    fit_pct: Mapping[str, float]
    samples: int
    evaluations: int

    def std(self, name: str) -> float:
        """The standard deviation of free parameter ``name``."""
        i = self.names.index(name)
        return float(np.sqrt(self.covariance[i, i]))

    def rel_sd(self, name: str) -> float:
        """The relative standard deviation of free parameter ``name``."""
        return self.std(name) / abs(float(self.params[name]))

    def interval(self, name: str, z: float = 1.96) -> tuple[float, float]:
        """The ``+-z`` standard deviations interval of ``name`` (1.96: its 95 % interval)."""
        v, s = float(self.params[name]), self.std(name)
        return v - z * s, v + z * s


def fit_grey_box(
    build: Callable[[Mapping[str, Any]], Any],
    params: Mapping[str, Any],
    free: Sequence[str],
    experiment: Experiment,
) -> GreyBoxFit:
    """Estimate the ``free`` parameters of the model ``build(params)`` from ``experiment``,
    starting from ``params`` (see the module docstring).

    Raises
    ------
    ValueError
        A free parameter that is not a non-zero number of ``params``, no samples, fewer samples
        than free parameters, or a model the starting parameters drive out of the finite numbers.
    """
    names = tuple(free)
    start = []
    for n in names:
        v = params.get(n)
        if isinstance(v, bool) or not isinstance(v, int | float) or v == 0:
            raise ValueError(f"fit_grey_box: {n!r} is not a non-zero numeric parameter ({v!r})")
        start.append(float(v))
    p0 = np.asarray(start)
    y = np.concatenate([np.asarray(v, dtype=float) for _, v in experiment.samples.values()])
    if len(y) <= len(names):
        raise ValueError(f"fit_grey_box: {len(y)} samples for {len(names)} parameters")
    evaluations = 0

    def residuals(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        nonlocal evaluations
        evaluations += 1
        model = build({**params, **dict(zip(names, (theta * p0).tolist(), strict=True))})
        sim = simulate_experiment(model, experiment)
        r = y - np.concatenate([sim[n] for n in experiment.samples])
        return np.where(np.isfinite(r), r, DIVERGED)

    if not (np.abs(residuals(np.ones(len(names)))) < DIVERGED).all():
        raise ValueError("fit_grey_box: the starting parameters do not simulate the experiment")
    result = scipy.optimize.least_squares(residuals, np.ones(len(names)), x_scale="jac")
    r = result.fun
    dof = len(y) - len(names)
    s2 = float(r @ r) / dof
    jtj = result.jac.T @ result.jac
    cov_theta = s2 * np.linalg.pinv(jtj)
    covariance = cov_theta * np.outer(p0, p0)
    estimate = {**params, **dict(zip(names, (result.x * p0).tolist(), strict=True))}
    fits = {}
    offset = 0
    for name, (_, values) in experiment.samples.items():
        yy = np.asarray(values, dtype=float)
        rr = r[offset : offset + len(yy)]
        offset += len(yy)
        spread = float(np.linalg.norm(yy - yy.mean()))
        fits[name] = 100.0 * (1.0 - float(np.linalg.norm(rr)) / spread) if spread > 0 else 0.0
    return GreyBoxFit(estimate, names, covariance, float(np.sqrt(s2)), fits, len(y), evaluations)
