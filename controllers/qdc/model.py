"""The paper twin of seed 001: the networked closed loop and its simulations.

Seed 001 (Sun & El-Farra), sections III-V. Every controller structure of
:mod:`controllers.qdc.network` is a linear controller ``dz/dt = F z + G m``, ``u = H z + D m``
(``m`` the measured outputs, or the state for state feedback) with a linear reset ``z <- R z`` at
the update instants: :func:`closed_loop_matrices` gives the closed loop's flow and reset,
:func:`simulate_linear` iterates the exact sampled closed loop (matrix exponential, eq. (7)) and
:func:`simulate_nonlinear` runs the controllers against a non-linear plant (eq. (10);
``plants/integrate.py`` ``rk4`` between updates). What reproduces the paper's figures; the bus runs
:mod:`controllers.qdc.law`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm

from controllers.qdc.design import LinearUnits
from controllers.qdc.network import Network, NetworkConfig
from plants.integrate import rk4

__all__ = [
    "LinearRun",
    "NonlinearRun",
    "closed_loop_matrices",
    "simulate_linear",
    "simulate_nonlinear",
]


def closed_loop_matrices(
    plant: LinearUnits, network: Network
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Flow and reset of the linear closed loop in the coordinates ``w = (x, z)``.

    Returns
    -------
    Acl : ndarray
        ``dw/dt = Acl w`` between updates.
    Rcl : ndarray
        ``w(t_k) = Rcl w(t_k^-)`` at an update instant.
    """
    A, B, _ = plant.full()
    Mm = network.M
    Acl = np.block(
        [
            [A + B @ network.D @ Mm, B @ network.H],
            [network.G @ Mm, network.F],
        ]
    )
    rz, rx = network.reset_matrices()
    nx = A.shape[0]
    Rcl = np.block([[np.eye(nx), np.zeros((nx, network.nz))], [rx, rz]])
    return Acl, Rcl


@dataclass(frozen=True)
class LinearRun:
    """States ``w = (x, z)`` right after each update instant ``t_k = k h`` (row ``k``).

    Long unstable runs are kept finite by storing ``w_k = exp(log_scale[k]) * v_k``: ``v`` holds
    the rescaled states, ``log_scale`` the logarithm of the factor taken out (0 while ``|w|``
    stays within 1e+-100).
    """

    t: NDArray[np.float64]
    v: NDArray[np.float64]
    log_scale: NDArray[np.float64]
    nx: int

    @property
    def w(self) -> NDArray[np.float64]:
        """Plant and controller states at the update instants (may overflow to inf)."""
        with np.errstate(over="ignore"):
            return self.v * np.exp(self.log_scale)[:, None]

    @property
    def x(self) -> NDArray[np.float64]:
        """Plant states at the update instants."""
        return self.w[:, : self.nx]

    def log_norms(self) -> NDArray[np.float64]:
        """``log |w_k|`` (exact also where ``w`` itself would overflow)."""
        with np.errstate(divide="ignore"):
            norms: NDArray[np.float64] = np.log(np.linalg.norm(self.v, axis=1)) + self.log_scale
            return norms

    def growth_rate(self) -> float:
        """Average log-growth of ``|w|`` per period over the second half of the run.

        Negative when the run decays. The first half is left out so that transients do not count.
        """
        ln = self.log_norms()
        k = len(ln)
        a, b = k // 2, k - 1
        if b <= a or not np.isfinite(ln[a]):
            return -np.inf
        return float((ln[b] - ln[a]) / (b - a))


def simulate_linear(
    plant: LinearUnits,
    network: Network,
    h: float,
    x0: NDArray[np.float64],
    n_periods: int,
    *,
    z0: NDArray[np.float64] | None = None,
) -> LinearRun:
    """Exact sampled simulation of the switched linear closed loop (eq. (7) in plant coordinates).

    Between updates the plant and the controllers flow continuously (``expm(Acl h)``); at each
    update the embedded models are reset with the transmitted estimates. The state at ``t = 0`` is
    taken right after an update.

    Parameters
    ----------
    h : float
        Update period (> 0), hours.
    x0 : ndarray
        Initial plant state (deviation).
    n_periods : int
        Number of update periods.
    z0 : ndarray, optional
        Initial controller state (default: every estimate zero, i.e. the observers do not know
        ``x0``).
    """
    NetworkConfig(h=h)
    Acl, Rcl = closed_loop_matrices(plant, network)
    step = Rcl @ expm(Acl * h)
    nx = plant.full()[0].shape[0]
    w = np.concatenate([np.asarray(x0, dtype=float), network.initial_state() if z0 is None else z0])
    w = Rcl @ w
    out = np.empty((n_periods + 1, w.size))
    log_scale = np.zeros(n_periods + 1)
    out[0] = w
    scale = 0.0
    for k in range(1, n_periods + 1):
        w = step @ w
        nrm = np.linalg.norm(w)
        if nrm > 1e100 or 0.0 < nrm < 1e-100:
            w = w / nrm
            scale += float(np.log(nrm))
        out[k] = w
        log_scale[k] = scale
    t = cast("NDArray[np.float64]", np.arange(n_periods + 1) * h)  # int64 * float is float64
    return LinearRun(t=t, v=out, log_scale=log_scale, nx=nx)


@dataclass(frozen=True)
class NonlinearRun:
    """Non-linear closed loop sampled at the update instants and at ``dt_out``."""

    t: NDArray[np.float64]
    x: NDArray[np.float64]
    u: NDArray[np.float64]
    left_bound: bool
    """Whether the run stopped because ``|x - x_s|_inf`` exceeded the bound."""


def simulate_nonlinear(
    plant: Any,
    x_s: NDArray[np.float64],
    u_s: NDArray[np.float64],
    network: Network,
    h: float,
    x0: NDArray[np.float64],
    t_end: float,
    *,
    max_step: float | None = None,
    bound: float = np.inf,
    xbar0: NDArray[np.float64] | None = None,
) -> NonlinearRun:
    """The networked control systems against the non-linear plant (seed 001 eq. (10)).

    The local observers and controllers run continuously on the deviation variables
    ``y - y_s`` (``x - x_s`` for state feedback) and drive ``u = u_s + H z + D m``; every ``h``
    hours the units exchange their estimates and reset the embedded models. Plant and controllers
    are integrated together with ``plants.integrate.rk4`` between update instants.

    Parameters
    ----------
    plant : object
        Non-linear plant with ``rhs(t, x, u)``; its states, inputs and outputs must be ordered as
        the stacked unit states, inputs and outputs of the linear design (true for
        :class:`plants.cstr_recycle.CSTRRecycle`).
    x_s, u_s : ndarray
        Operating point (steady state) the design was linearized at.
    network : QDCNetwork or CentralizedNetwork
        The controller structure.
    h : float
        Update period (> 0), hours.
    x0 : ndarray
        Initial plant state (absolute).
    t_end : float
        End time, hours.
    max_step : float, optional
        Largest RK4 step (default ``min(h / 4, 0.005)``).
    bound : float
        Stop (``left_bound=True``) as soon as ``max |x - x_s|`` exceeds it.
    xbar0 : ndarray, optional
        Initial estimates (deviation; default zero).

    Returns
    -------
    NonlinearRun
        States and inputs at every update instant (``t_k = k h``).
    """
    NetworkConfig(h=h)
    x_s = np.asarray(x_s, dtype=float)
    u_s = np.asarray(u_s, dtype=float)
    nx = x_s.size
    Mm, H, D = network.M, network.H, network.D
    step = min(h / 4.0, 0.005) if max_step is None else max_step
    dummy = np.zeros(0)
    f = _closed_loop_rhs(plant, network, x_s, u_s)
    z = network.initial_state(xbar0)
    x = np.asarray(x0, dtype=float)
    z = network.update_from(z, x - x_s)
    ts, xs, us = [0.0], [x.copy()], [u_s + H @ z + D @ (Mm @ (x - x_s))]
    t, left, k = 0.0, False, 0
    while t < t_end - 1e-12:
        t1 = min((k + 1) * h, t_end)
        w = rk4(f, t, np.concatenate([x, z]), t1, dummy, max_step=step)
        x, z = w[:nx], w[nx:]
        k += 1
        t = t1
        if not np.all(np.isfinite(w)) or np.max(np.abs(x - x_s)) > bound:
            left = True
            ts.append(t)
            xs.append(x.copy())
            us.append(np.full(u_s.shape, np.nan))
            break
        z = network.update_from(z, x - x_s)
        ts.append(t)
        xs.append(x.copy())
        us.append(u_s + H @ z + D @ (Mm @ (x - x_s)))
    return NonlinearRun(t=np.array(ts), x=np.array(xs), u=np.array(us), left_bound=left)


_Rhs = Callable[[float, NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]


def _closed_loop_rhs(
    plant: Any, network: Network, x_s: NDArray[np.float64], u_s: NDArray[np.float64]
) -> _Rhs:
    """``dw/dt`` of the non-linear plant and the controllers together, ``w = (x, z)``."""
    nx = x_s.size
    Mm, F, G, H, D = network.M, network.F, network.G, network.H, network.D

    def f(t: float, w: NDArray[np.float64], _u: NDArray[np.float64]) -> NDArray[np.float64]:
        x, z = w[:nx], w[nx:]
        m = Mm @ (x - x_s)
        u = u_s + H @ z + D @ m
        return np.concatenate([plant.rhs(t, x, u), F @ z + G @ m])

    return f
