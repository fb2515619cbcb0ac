"""Routine operation of seed 004's sampled process: the loop run sample by sample.

:func:`simulate` runs the loop sample by sample with any law object (``step(t, measurements)``),
e.g. the PI and PI-P laws of :mod:`controllers.cascade.model`, so that the monitor's prediction
can be compared with the cascade actually implemented on the same process and the same noise.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from plants.cascade.model import CascadeProcessConfig

__all__ = ["FeedbackLaw", "RoutineRun", "simulate"]


class FeedbackLaw(Protocol):
    """A control law executed once per sample: ``u = law.step(t, measurements)``."""

    def step(self, t: float, measurements: Mapping[str, float]) -> float: ...


class _Stage:
    """Direct-form difference equation ``A y = q^-delay B x`` with explicit history."""

    __slots__ = ("b", "a", "delay", "xh", "yh")

    def __init__(self, b: Sequence[float], a: Sequence[float], delay: int) -> None:
        self.b = list(b)
        self.a = list(a[1:])
        self.delay = delay
        self.xh = [0.0] * (delay + len(self.b))  # xh[i] = x(t - i)
        self.yh = [0.0] * len(self.a)  # yh[i] = y(t - 1 - i)

    def step(self, x: float) -> float:
        xh, yh = self.xh, self.yh
        xh.pop()
        xh.insert(0, x)
        y = 0.0
        for i, bi in enumerate(self.b):
            y += bi * xh[self.delay + i]
        for i, ai in enumerate(self.a):
            y -= ai * yh[i]
        if yh:
            yh.pop()
            yh.insert(0, y)
        return y


@dataclass(frozen=True)
class RoutineRun:
    """Result of :func:`simulate`: measured and true outputs by stage name, ``u``, time."""

    t: NDArray[np.float64]
    u: NDArray[np.float64]
    measured: dict[str, NDArray[np.float64]]
    true: dict[str, NDArray[np.float64]]

    def variance(self, name: str, *, measured: bool = True) -> float:
        """Sample variance (about the mean) of a stage output."""
        x = (self.measured if measured else self.true)[name]
        return float(np.var(x))


def simulate(
    config: CascadeProcessConfig,
    law: FeedbackLaw,
    n: int,
    rng: np.random.Generator,
    *,
    burn_in: int = 1000,
) -> RoutineRun:
    """Routine closed-loop operation at zero set points, sample by sample.

    At each sample ``t_k = k dt`` the stage outputs are computed from past inputs (stage 0 from
    ``u(t_(k-1))`` and earlier), measured with noise, and the law returns ``u(t_k)``.

    Parameters
    ----------
    config : CascadeProcessConfig
        The process.
    law : FeedbackLaw
        Any object with ``step(t, measurements) -> u`` (measurements by stage name).
    n : int
        Samples returned (after ``burn_in`` samples that are discarded).
    rng : numpy.random.Generator
        Source of ``a_j`` and ``v_j``; the same seed gives the same noise whatever the law, so
        SFB and cascade runs can be compared on the same disturbances.
    burn_in : int
        Leading samples dropped (the loop starts at rest).
    """
    from scipy.signal import lfilter

    if n < 1 or burn_in < 0:
        raise ValueError(f"simulate: n ({n}) must be >= 1 and burn_in ({burn_in}) >= 0")
    total = n + burn_in
    m = len(config.stages)
    a = rng.standard_normal((m, total))
    v = rng.standard_normal((m, total))
    dist = np.empty((m, total))
    for j, st in enumerate(config.stages):
        dist[j] = st.noise_std * lfilter(st.noise_num, st.noise_den, a[j])
        v[j] *= st.meas_noise_std
    stages = []
    for j, st in enumerate(config.stages):
        # stage 0 is fed u(t-1) at step t, hence one sample less of explicit delay
        stages.append(_Stage(st.num, st.den, st.delay - 1 if j == 0 else st.delay))
    names = config.names
    y_true = np.empty((m, total))
    y_meas = np.empty((m, total))
    u = np.empty(total)
    u_prev = 0.0
    dt = config.dt
    dist_l = dist.T.tolist()
    v_l = v.T.tolist()
    for k in range(total):
        x = u_prev
        meas: dict[str, float] = {}
        dk, vk = dist_l[k], v_l[k]
        for j in range(m):
            y = stages[j].step(x) + dk[j]
            y_true[j, k] = y
            ym = y + vk[j]
            y_meas[j, k] = ym
            meas[names[j]] = ym
            x = y
        u_prev = float(law.step(k * dt, meas))
        u[k] = u_prev
    sl = slice(burn_in, total)
    return RoutineRun(
        t=np.arange(n) * dt,
        u=u[sl].copy(),
        measured={nm: y_meas[j, sl].copy() for j, nm in enumerate(names)},
        true={nm: y_true[j, sl].copy() for j, nm in enumerate(names)},
    )
