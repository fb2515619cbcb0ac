"""The paper twin of seed 004's process: a chain of sampled stages and its closed loops.

Seed 004 (Lakshminarayanan et al. 2006, *Estimation of variance reduction opportunities through
cascade control*), Figure 1: a chain of linear sampled stages from the manipulated variable ``u``
to the primary controlled variable ``y1``; each stage output may serve as a secondary
measurement. With two stages (the paper's structure)::

    y2 = T2 u  + N2 a2,        T2 = q^-d2 T2~                       (Fig. 1)
    y1 = T1 y2 + N1 a1,        T1 = q^-d1 T1~

``a1``, ``a2`` are independent zero-mean white noise sequences (standard deviations
``noise_std``), ``N1``, ``N2`` rational with monic numerator and denominator (so ``a_j`` is the
innovation of its channel), ``d1`` (secondary to primary) and ``d2`` (``u`` to secondary) whole
samples of dead time. In general the chain has ``m`` stages, stage 0 nearest ``u`` and stage
``m-1`` the primary::

    y_0 = G_0 u       + N_0 a_0
    y_j = G_j y_(j-1) + N_j a_j          (j = 1 ... m-1),       G_j = q^-delay_j B_j / A_j

Every stage output is measured with additive white noise ``v_j`` (``meas_noise_std``; the paper
adds 5 % measurement noise to all outputs, :func:`with_measurement_noise`).

Linear feedback laws ``u = -sum_l K_l(q^-1) ym_l`` (about zero set points) cover both structures:

* simple feedback (SFB, Fig. 1): ``K_primary = Q``, closed loop eq. (1)::

      y1 = N1/(1 + Q T1 T2) a1 + T1 N2/(1 + Q T1 T2) a2

* cascade (Fig. 2): ``u = Q2 (r2 - y2)``, ``r2 = Q1 (r1 - y1)``, i.e. ``K_secondary = Q2``,
  ``K_primary = Q1 Q2``; closed loop eq. (2)::

      y1 = N1/(1 + Q1 T1 T2*) a1 + T1 N2*/(1 + Q1 T1 T2*) a2,
      T2* = Q2 T2/(1 + Q2 T2),   N2* = N2/(1 + Q2 T2)


:func:`closed_loop` returns these transfer functions exactly (rational arithmetic in ``q^-1``,
:mod:`plants.cascade.transfer`); their variances are in :mod:`plants.cascade.variance`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from plants.cascade.transfer import TF, trim

__all__ = [
    "StageConfig",
    "CascadeProcessConfig",
    "foptd_stage",
    "delays",
    "open_loop",
    "closed_loop",
]


class StageConfig(BaseModel):
    """One stage ``y_j = q^-delay B/A y_(j-1) + C/D a_j``, measured as ``y_j + v_j``.

    Its process ``G_j = q^-delay B/A`` (:meth:`process_tf`) and its disturbance ``N_j = C/D``
    (:meth:`noise_tf`) are the blocks of seed 004's Fig. 1.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(min_length=1, description="measurement name (column name in routine data)")
    delay: int = Field(ge=0, description="dead time from the stage input to its output, samples")
    num: tuple[float, ...] = Field(min_length=1, description="B: b0 + b1 q^-1 + ..., b0 != 0")
    den: tuple[float, ...] = Field(default=(1.0,), description="A: 1 + a1 q^-1 + ... (monic)")
    noise_num: tuple[float, ...] = Field(default=(1.0,), description="C: 1 + c1 q^-1 + ...")
    noise_den: tuple[float, ...] = Field(default=(1.0,), description="D: 1 + d1 q^-1 + ...")
    noise_std: float = Field(default=0.0, ge=0, description="standard deviation of a_j")
    meas_noise_std: float = Field(default=0.0, ge=0, description="standard deviation of v_j")

    @field_validator("num")
    @classmethod
    def _leading_gain(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if v[0] == 0.0:
            raise ValueError("num[0] must be non-zero (put dead time in 'delay')")
        return v

    @field_validator("den", "noise_num", "noise_den")
    @classmethod
    def _monic(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if len(v) == 0 or v[0] != 1.0:
            raise ValueError("must be monic: first coefficient 1.0")
        return v

    def process_tf(self) -> TF:
        """``G_j = q^-delay B / A``."""
        return TF(np.r_[np.zeros(self.delay), self.num], self.den)

    def noise_tf(self) -> TF:
        """``N_j = C / D``."""
        return TF(self.noise_num, self.noise_den)


class CascadeProcessConfig(BaseModel):
    """A chain of stages from the manipulated variable (first) to the primary output (last)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    stages: tuple[StageConfig, ...] = Field(min_length=1)
    dt: float = Field(default=1.0, gt=0, description="sampling interval (time unit of the run)")
    description: str = ""

    @model_validator(mode="after")
    def _check(self) -> CascadeProcessConfig:
        names = [s.name for s in self.stages]
        if len(set(names)) != len(names):
            raise ValueError(f"stages: names must be unique, got {names}")
        if self.stages[0].delay < 1:
            raise ValueError(
                f"stages[0] ({names[0]!r}).delay must be >= 1 (u acts one sample later at the "
                "earliest)"
            )
        return self

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.stages)

    @property
    def primary(self) -> str:
        """Name of the primary controlled variable (the last stage)."""
        return self.stages[-1].name

    def index(self, name: str) -> int:
        """Stage index of measurement ``name`` (``KeyError`` naming the known ones)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no stage named {name!r}; stages are {list(self.names)}") from None


def foptd_stage(
    name: str,
    *,
    gain: float,
    tau: float,
    dead_time: float,
    dt: float = 1.0,
    noise_pole: float = 0.0,
    noise_std: float = 0.0,
    drift_pole: float = 0.0,
    meas_noise_std: float = 0.0,
) -> StageConfig:
    """Stage ``gain e^(-dead_time s)/(tau s + 1)`` sampled with a zero-order hold.

    ``dead_time`` must be a multiple of ``dt``; the hold adds one sample, so the stage's
    ``delay`` is ``dead_time/dt + 1``. The disturbance is ``a_j/(1 - noise_pole q^-1)``, times
    ``1/(1 - drift_pole q^-1)`` (a slow drift; ``drift_pole = 1`` is the integrated, non-stationary
    disturbance of the paper's Example 2, which makes the signals upstream of it drift too).
    """
    k = round(dead_time / dt)
    if abs(k * dt - dead_time) > 1e-9 * max(1.0, dead_time):
        raise ValueError(f"{name}: dead_time {dead_time} is not a multiple of dt {dt}")
    phi = math.exp(-dt / tau)
    noise_den = np.array([1.0, -noise_pole]) if noise_pole else np.array([1.0])
    if drift_pole:
        noise_den = np.convolve(noise_den, [1.0, -drift_pole])
    return StageConfig(
        name=name,
        delay=k + 1,
        num=(gain * (1.0 - phi),),
        den=(1.0, -phi),
        noise_den=tuple(float(c) for c in trim(noise_den)),
        noise_std=noise_std,
        meas_noise_std=meas_noise_std,
    )


def delays(config: CascadeProcessConfig, secondary: str) -> tuple[int, int]:
    """``(d1, d2)``: dead time secondary -> primary and ``u`` -> secondary, samples."""
    s = config.index(secondary)
    if s == len(config.stages) - 1:
        raise ValueError(f"secondary {secondary!r} is the primary")
    d2 = sum(st.delay for st in config.stages[: s + 1])
    d1 = sum(st.delay for st in config.stages[s + 1 :])
    return d1, d2


def open_loop(config: CascadeProcessConfig) -> tuple[list[TF], list[list[TF | None]]]:
    """``P[l]`` (``u -> y_l``) and ``W[j][l]`` (``a_j -> y_l`` without the noise std; None if
    ``l < j``: a disturbance never reaches upstream stages in open loop)."""
    m = len(config.stages)
    g = [s.process_tf() for s in config.stages]
    p: list[TF] = []
    acc = TF([1.0])
    for j in range(m):
        acc = acc * g[j]
        p.append(acc)
    w: list[list[TF | None]] = [[None] * m for _ in range(m)]
    for j in range(m):
        acc = config.stages[j].noise_tf()
        w[j][j] = acc
        for k in range(j + 1, m):
            acc = acc * g[k]
            w[j][k] = acc
    return p, w


def closed_loop(
    config: CascadeProcessConfig,
    feedback: Mapping[str, TF],
    output: str | None = None,
    *,
    measured: bool = True,
) -> dict[tuple[str, str], TF]:
    """Closed-loop transfer functions from every noise source to one output.

    Parameters
    ----------
    config : CascadeProcessConfig
        The process.
    feedback : mapping
        ``{measurement name: K_l}`` of the linear law ``u = -sum_l K_l ym_l`` (see
        :meth:`controllers.cascade.model.SFBPIConfig.feedback` and
        :meth:`controllers.cascade.model.PIPCascadeConfig.feedback`).
    output : str, optional
        Stage name of the output (default: the primary), or ``"u"`` for the manipulated variable.
    measured : bool
        Response of the measured ``y_l + v_l`` (default) or of the true ``y_l``.

    Returns
    -------
    dict
        ``{("a", name): TF, ("v", name): TF}`` for unit-variance sources (multiply variances by
        ``noise_std**2``, ``meas_noise_std**2``).
    """
    m = len(config.stages)
    names = config.names
    output = output or config.primary
    g = [s.process_tf() for s in config.stages]
    p, _ = open_loop(config)
    ks = {config.index(n): k for n, k in feedback.items()}

    def between(j: int, last: int) -> TF:  # G_(j+1) ... G_last, the chain from y_j to y_last
        acc = TF([1.0])
        for i in range(j + 1, last + 1):
            acc = acc * g[i]
        return acc

    def loop_sum(idx: Iterable[int]) -> TF:  # sum_k K_k P_k over k in idx
        acc = TF([0.0])
        for k in idx:
            acc = acc + ks[k] * p[k]
        return acc

    one_plus_loop = loop_sum(ks) + 1.0
    is_u = output == "u"
    li = -1 if is_u else config.index(output)
    out: dict[tuple[str, str], TF] = {}
    # Structural forms without subtractions (exact cancellations are numerically fragile):
    #   y_l/a_j = N_j G_(j,l] (1 + sum_{k<j} K_k P_k)/(1 + L)       l >= j
    #   y_l/a_j = -P_l N_j M_j/(1 + L),  M_j = sum_{k>=j} K_k G_(j,k]  l < j
    #   u/a_j   = -N_j M_j/(1 + L)
    for j in range(m):
        nj = config.stages[j].noise_tf()
        mj = TF([0.0])
        for k in ks:
            if k >= j:
                mj = mj + ks[k] * between(j, k)
        if is_u:
            tf = -(nj * mj) / one_plus_loop
        elif li >= j:
            up = loop_sum(k for k in ks if k < j) + 1.0
            tf = nj * between(j, li) * up / one_plus_loop
        else:
            tf = -(p[li] * nj * mj) / one_plus_loop
        out[("a", names[j])] = tf
    #   y_l/v_k = -P_l K_k/(1 + L), and (1 + sum_{i != l} K_i P_i)/(1 + L) for measured l = k
    for k in range(m):
        if is_u:
            tf = -ks[k] / one_plus_loop if k in ks else TF([0.0])
        elif measured and k == li:
            tf = (loop_sum(i for i in ks if i != k) + 1.0) / one_plus_loop
        else:
            tf = -(p[li] * ks[k]) / one_plus_loop if k in ks else TF([0.0])
        out[("v", names[k])] = tf
    return out
