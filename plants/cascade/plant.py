"""What the bus runs: seed 004's primary/secondary process in continuous time, with disturbances.

The sampled process of :mod:`plants.cascade.model` (seed 004, Fig. 1) in continuous time, as a
plant node integrates it (fixed-step RK4 between events, :mod:`plants.integrate`), so a scenario
can produce *routine operating data* of a simple-feedback loop for the performance monitor. A
chain ``u -> y3 -> y2 -> y1`` (as :data:`plants.cascade.examples.EXAMPLE_3`)::

    tau3 dy3/dt = -y3 + K3 u  + n3                     first secondary (e.g. a coolant flow)
    tau2 dy2/dt = -y2 + K2 y3 + n2                     second secondary (e.g. a jacket temperature)
    y2 -> z1 -> ... -> zN                              transport, N equal lags of theta/N each
    tau1 dy1/dt = -y1 + K1 zN + n1                     primary (zN = y2 when N = 0)
    tau_dj dnj/dt = -nj + gj wj(t)                     disturbances, j = 1, 2, 3

Deviation variables about an operating point (set point 0, ``u = 0`` holds it). The transport
between ``y2`` and the primary is a chain of ``n_lag`` first-order lags ("tanks in series"), the
ODE form of a dead time ``theta``: its impulse response is an Erlang density with mean ``theta``,
so the process has an *apparent* dead time, not an exact one; the monitor's delays ``d1``, ``d2``
are then the number of samples before a move visibly reaches each measurement, as on a real plant
(``scenarios/cascade_routine.yaml`` states how its delays were read off the step response,
:func:`step_response`).

Disturbances
------------
``w1``, ``w2`` are independent unit-variance Gaussian knots every ``noise_period``, linearly
interpolated (continuous, so RK4 stays accurate), drawn from ``np.random.default_rng([seed, j,
chunk])`` in chunks of :data:`plants.knots.CHUNK` knots: ``w(t)`` is a pure function of ``t``, so
every engine integrating the same segments gets the same trajectory bit for bit, whatever order it
evaluates ``rhs`` in. The gain ``gj = dj_std sqrt(2 tau_dj / noise_period)`` makes ``nj`` a
first-order (drifting) disturbance of stationary standard deviation about ``dj_std`` (exact as
``noise_period / tau_dj -> 0``). The realization is fixed by ``params.seed``, not by the
scenario's seed (a plant model is built from its parameters alone); measurement noise is the
plant node's (``noise:`` per sensor, seeded from the scenario seed).

Defaults: a fast flow (``tau3 = 0.5``) with a small disturbance, a jacket (``tau2 = 2``) where a
strong drifting disturbance enters, a slow primary (``tau1 = 8``) behind a transport of
``theta = 4`` time units with a weaker disturbance: a cascade on ``y2`` pays off (as in
:data:`~plants.cascade.examples.EXAMPLE_1`), one on ``y3``, upstream of the main disturbance, much
less (as ``y3`` in :data:`~plants.cascade.examples.EXAMPLE_3`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.linalg import expm

from plants.knots import Knots

if TYPE_CHECKING:
    import control

__all__ = ["CascadeCTParams", "CascadeCT", "SampledCascadeCT", "sampled", "step_response"]


class CascadeCTParams(BaseModel):
    """Gains, time constants, transport and disturbances (time unit of the scenario)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    K3: float = Field(default=1.0, description="gain u -> y3")
    tau3: float = Field(default=0.5, gt=0, description="time constant of the first secondary")
    K2: float = Field(default=1.0, description="gain y3 -> y2")
    tau2: float = Field(default=2.0, gt=0, description="time constant of the secondary")
    K1: float = Field(default=1.0, description="gain y2 -> y1")
    tau1: float = Field(default=8.0, gt=0, description="time constant of the primary")
    theta: float = Field(default=4.0, ge=0, description="transport y2 -> y1 (mean of the lags)")
    n_lag: int = Field(default=8, ge=0, le=64, description="lags in series making the transport")
    d1_std: float = Field(default=0.2, ge=0, description="std of the primary disturbance n1")
    d1_tau: float = Field(default=30.0, gt=0, description="time constant of n1")
    d2_std: float = Field(default=0.3, ge=0, description="std of the secondary disturbance n2")
    d2_tau: float = Field(default=30.0, gt=0, description="time constant of n2")
    d3_std: float = Field(default=0.05, ge=0, description="std of the flow disturbance n3")
    d3_tau: float = Field(default=5.0, gt=0, description="time constant of n3")
    noise_period: float = Field(default=0.25, gt=0, description="spacing of the noise knots")
    seed: int = Field(default=0, ge=0, description="seed of the disturbance realization")

    @model_validator(mode="after")
    def _transport(self) -> CascadeCTParams:
        if (self.n_lag == 0) != (self.theta == 0.0):
            raise ValueError(
                f"n_lag: a transport theta = {self.theta} needs n_lag >= 1, and n_lag = "
                f"{self.n_lag} lags need theta > 0"
            )
        return self


class CascadeCT:
    """The process as a plant object: ``rhs``, ``outputs``, ``equilibrium``, ``linearize``."""

    input_names: tuple[str, ...] = ("u",)
    output_names: tuple[str, ...] = ("y1", "y2", "y3")

    def __init__(self, params: CascadeCTParams) -> None:
        self.params = p = params
        self.state_names: tuple[str, ...] = (
            "y3",
            "y2",
            *(f"z{i}" for i in range(1, p.n_lag + 1)),
            "y1",
            "n1",
            "n2",
            "n3",
        )
        self._n = p.n_lag
        self._rate = p.n_lag / p.theta if p.n_lag else 0.0
        self._g1 = p.d1_std * math.sqrt(2.0 * p.d1_tau / p.noise_period)
        self._g2 = p.d2_std * math.sqrt(2.0 * p.d2_tau / p.noise_period)
        self._g3 = p.d3_std * math.sqrt(2.0 * p.d3_tau / p.noise_period)
        self._w1 = Knots(p.seed, 1)
        self._w2 = Knots(p.seed, 2)
        self._w3 = Knots(p.seed, 3)

    # -- disturbances ---------------------------------------------------------------------------
    def noise(self, t: float) -> tuple[float, float, float]:
        """``(w1(t), w2(t), w3(t))``: the interpolated unit knots at time ``t >= 0``."""
        s = t / self.params.noise_period
        k = math.floor(s)
        f = s - k
        w1, w2, w3 = self._w1, self._w2, self._w3
        return (
            w1[k] + f * (w1[k + 1] - w1[k]),
            w2[k] + f * (w2[k + 1] - w2[k]),
            w3[k] + f * (w3[k + 1] - w3[k]),
        )

    # -- dynamics -------------------------------------------------------------------------------
    def rhs(self, t: float, x: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
        """Time derivative of the state (module docstring) under input ``(u,)``."""
        return np.array(self.rhs_tuple(t, tuple(x.tolist()), tuple(u.tolist())))

    def rhs_tuple(self, t: float, x: Sequence[float], u: Sequence[float]) -> tuple[float, ...]:
        """:meth:`rhs` on plain floats (what the fixed-step integrator calls)."""
        p = self.params
        n = self._n
        y3, y2 = x[0], x[1]
        y1, n1, n2, n3 = x[n + 2], x[n + 3], x[n + 4], x[n + 5]
        w1, w2, w3 = self.noise(t)
        out = [(-y3 + p.K3 * u[0] + n3) / p.tau3, (-y2 + p.K2 * y3 + n2) / p.tau2]
        prev = y2
        for i in range(2, n + 2):
            out.append(self._rate * (prev - x[i]))
            prev = x[i]
        out.append((-y1 + p.K1 * prev + n1) / p.tau1)
        out.append((-n1 + self._g1 * w1) / p.d1_tau)
        out.append((-n2 + self._g2 * w2) / p.d2_tau)
        out.append((-n3 + self._g3 * w3) / p.d3_tau)
        return tuple(out)

    def outputs(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Measured outputs ``(y1, y2, y3)``."""
        return np.array((x[self._n + 2], x[1], x[0]), dtype=float)

    # -- equilibrium ----------------------------------------------------------------------------
    def equilibrium(
        self, y_bar: Mapping[str, float]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """State and input holding ``y1`` at ``y_bar["y1"]`` with the disturbances at zero.

        Raises
        ------
        ValueError
            If ``y1`` is missing or a gain is zero.
        """
        if "y1" not in y_bar:
            raise ValueError("CascadeCT.equilibrium: set point missing for output 'y1'")
        p = self.params
        if p.K1 == 0.0 or p.K2 == 0.0 or p.K3 == 0.0:
            raise ValueError("CascadeCT.equilibrium: a zero gain cannot hold a set point")
        r = float(y_bar["y1"])
        y2 = r / p.K1
        y3 = y2 / p.K2
        x = np.array([y3] + [y2] * (self._n + 1) + [r, 0.0, 0.0, 0.0])
        return x, np.array((y3 / p.K3,))

    # -- linearization --------------------------------------------------------------------------
    def jacobians(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``A = df/dx`` and ``B = df/du`` (the model is linear; disturbances are not inputs)."""
        p = self.params
        n = self._n
        i1, i_n1, i_n2, i_n3 = n + 2, n + 3, n + 4, n + 5
        k = n + 6
        a = np.zeros((k, k))
        b = np.zeros((k, 1))
        a[0, 0] = -1.0 / p.tau3
        a[0, i_n3] = 1.0 / p.tau3
        b[0, 0] = p.K3 / p.tau3
        a[1, 1] = -1.0 / p.tau2
        a[1, 0] = p.K2 / p.tau2
        a[1, i_n2] = 1.0 / p.tau2
        for i in range(2, n + 2):
            a[i, i - 1] = self._rate
            a[i, i] = -self._rate
        a[i1, i1] = -1.0 / p.tau1
        a[i1, n + 1] = p.K1 / p.tau1
        a[i1, i_n1] = 1.0 / p.tau1
        a[i_n1, i_n1] = -1.0 / p.d1_tau
        a[i_n2, i_n2] = -1.0 / p.d2_tau
        a[i_n3, i_n3] = -1.0 / p.d3_tau
        return a, b

    def linearize(self, x: NDArray[np.float64], u: NDArray[np.float64]) -> control.StateSpace:
        """The model as a ``control.StateSpace`` (outputs ``y1``, ``y2``, ``y3``)."""
        import control

        a, b = self.jacobians()
        c = np.zeros((3, a.shape[0]))
        c[0, self._n + 2] = 1.0
        c[1, 1] = 1.0
        c[2, 0] = 1.0
        return control.ss(
            a, b, c, np.zeros((3, 1)),
            states=list(self.state_names), inputs=list(self.input_names),
            outputs=list(self.output_names),
        )  # fmt: skip


def step_response(params: CascadeCTParams, dt: float, n: int) -> dict[str, NDArray[np.float64]]:
    """Unit-step responses of every state to ``u`` at ``t = dt, 2 dt, ..., n dt``, disturbances
    at zero (exact, by the matrix exponential): what a plant engineer reads the delays off.

    Returns
    -------
    dict
        State name -> response, shape ``(n,)``.
    """
    plant = CascadeCT(params)
    a, b = plant.jacobians()
    k = a.shape[0]
    big = np.zeros((k + 1, k + 1))
    big[:k, :k] = a * dt
    big[:k, k:] = b * dt
    e = expm(big)
    phi, gam = e[:k, :k], e[:k, k]
    x = np.zeros(k)
    out = np.empty((n, k))
    for i in range(n):
        x = phi @ x + gam
        out[i] = x
    return {name: out[:, j] for j, name in enumerate(plant.state_names)}


class SampledCascadeCT(NamedTuple):
    """The process sampled every ``dt`` with the input held (exact; :func:`sampled`).

    ``x[m + 1] = phi x[m] + gam u[m] + dist[m]``, ``x[m]`` the state at ``m dt``; ``dist[m]`` is
    what the disturbances add over ``[m dt, (m + 1) dt)`` from a zero state; outputs
    ``(y1, y2, y3) = c x``.
    """

    phi: NDArray[np.float64]
    gam: NDArray[np.float64]
    dist: NDArray[np.float64]
    c: NDArray[np.float64]


def sampled(params: CascadeCTParams, dt: float, n: int) -> SampledCascadeCT:
    """The exact sampled model over ``n`` samples, with this realization's disturbances.

    Between two knots the disturbance inputs are linear in time, so each knot interval is
    integrated exactly by the matrix exponential of the state augmented with the interpolated
    knot value and its slope (a first-order hold); a sample spans ``dt / noise_period`` knot
    intervals. What the plant node's RK4 approximates (step ``max_step``), at a small fraction
    of its cost: for tuning controllers on long records (``bench/monitor_cascade_switch.py``).

    Raises
    ------
    ValueError
        If ``dt`` is not a whole number of ``noise_period``.
    """
    q = round(dt / params.noise_period)
    if q < 1 or abs(q * params.noise_period - dt) > 1e-9 * dt:
        raise ValueError(
            f"sampled: dt = {dt} is not a whole number of noise_period = {params.noise_period}"
        )
    plant = CascadeCT(params)
    a, b = plant.jacobians()
    k = a.shape[0]
    nn = plant._n
    g = np.zeros((k, 3))
    g[nn + 3, 0] = plant._g1 / params.d1_tau
    g[nn + 4, 1] = plant._g2 / params.d2_tau
    g[nn + 5, 2] = plant._g3 / params.d3_tau
    h = params.noise_period
    big = np.zeros((k + 6, k + 6))  # (x, w interpolated, knot difference) in time s / h
    big[:k, :k] = a * h
    big[:k, k : k + 3] = g * h
    big[k : k + 3, k + 3 :] = np.eye(3)
    e = expm(big)
    phi_h, e_w, e_dw = e[:k, :k], e[:k, k : k + 3], e[:k, k + 3 :]
    knots = np.array(
        [[w[i] for i in range(n * q + 1)] for w in (plant._w1, plant._w2, plant._w3)]
    ).T
    v = knots[:-1] @ e_w.T + np.diff(knots, axis=0) @ e_dw.T  # (n q, k): per knot interval
    dist = np.zeros((n, k))
    for i in range(q):  # dist[m] = sum_i phi_h^(q-1-i) v[m q + i]
        dist = dist @ phi_h.T + v[i::q]
    big_u = np.zeros((k + 1, k + 1))
    big_u[:k, :k] = a * dt
    big_u[:k, k:] = b * dt
    eu = expm(big_u)
    c = np.zeros((3, k))
    c[0, nn + 2] = 1.0
    c[1, 1] = 1.0
    c[2, 0] = 1.0
    return SampledCascadeCT(phi=np.linalg.matrix_power(phi_h, q), gam=eu[:k, k], dist=dist, c=c)
