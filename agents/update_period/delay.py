"""The update-period test with a delay on the transmitted estimates (an extension of seed 001).

Seed 001 assumes an update reaches the other units the instant it is sent. Over a wireless
network it arrives ``d`` later: unit ``j`` sends ``xbar_j(t_k)`` at ``t_k = k h`` and unit ``i``
resets its model ``xhat_j^i`` to that value at ``t_k + d``. For ``0 <= d < h`` the closed loop in
the coordinates ``w = (x, z)`` of :func:`controllers.qdc.model.closed_loop_matrices`
(``dw/dt = Acl w`` between updates, ``w(t_k^+) = Rcl w(t_k^-)`` for an instant update) then
satisfies::

    w(t_k + d^+) = (I - D) expm(Acl d) w(t_k) + D Rcl w(t_k)
    w(t_{k+1})   = expm(Acl (h - d)) w(t_k + d^+)

with ``D`` the diagonal selector of the rows an update resets (the rows where ``Rcl`` differs from
the identity): the reset rows take the values ``Rcl`` computes from the state captured at the
send instant, the others flow on. So ``w(t_{k+1}) = M_d(h) w(t_k)`` with the monodromy::

    M_d(h) = expm(Acl (h - d)) [ (I - D) expm(Acl d) + D Rcl ]

and the loop is exponentially stable iff ``rho(M_d(h)) < 1`` (the same argument as seed 001
eq. (8): the state at the send instants evolves by a constant matrix). For ``d = 0`` it is
``expm(Acl h) Rcl``, similar to the paper's ``M(h)`` (same non-zero spectrum; checked in
``tests/unit/test_update_delay.py``). A delay of one period or more (updates overtaking their
successors) is outside this form and is refused.

:func:`find_h_range` scans ``h`` on ``(d, h_hi]`` and returns the first interval of stabilizing
periods: with a delay the shortest periods need not be stabilizing any more, since every update is
``d`` old when it lands.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm
from scipy.optimize import brentq

__all__ = ["DelayedUpdates", "HRange", "find_h_range"]


@dataclass(frozen=True)
class DelayedUpdates:
    """A networked loop with periodic, delayed model updates.

    Parameters
    ----------
    Acl, Rcl : ndarray
        Flow and reset of the closed loop (:func:`controllers.qdc.model.closed_loop_matrices`).
    """

    Acl: NDArray[np.float64]
    Rcl: NDArray[np.float64]

    def __post_init__(self) -> None:
        n = self.Acl.shape[0]
        if self.Acl.shape != (n, n) or self.Rcl.shape != (n, n):
            raise ValueError(
                f"Acl and Rcl must be square and of one size, got {self.Acl.shape} and "
                f"{self.Rcl.shape}"
            )

    @property
    def reset_rows(self) -> NDArray[np.bool_]:
        """The rows an update resets (``D`` of the module docstring)."""
        rows: NDArray[np.bool_] = np.any(self.Rcl != np.eye(self.Rcl.shape[0]), axis=1)
        return rows

    def monodromy(self, h: float, d: float = 0.0) -> NDArray[np.float64]:
        """``M_d(h)``, the map of the state from one send instant to the next.

        Raises
        ------
        ValueError
            If ``h <= 0``, ``d < 0`` or ``d >= h`` (the message names the value).
        """
        _check(h, d)
        rows = self.reset_rows[:, None]
        landing = np.where(rows, self.Rcl, expm(self.Acl * d))
        monodromy: NDArray[np.float64] = expm(self.Acl * (h - d)) @ landing
        return monodromy

    def spectral_radius(self, h: ArrayLike, d: float = 0.0) -> NDArray[np.float64] | float:
        """``rho(M_d(h))`` for one period or an array of periods."""
        scalar = np.ndim(h) == 0
        hs = np.atleast_1d(np.asarray(h, dtype=float))
        for x in hs:
            _check(x, d)
        landing = np.where(self.reset_rows[:, None], self.Rcl, expm(self.Acl * d))
        out = np.empty(hs.size)
        for a in range(0, hs.size, 256):  # batched matrix exponentials
            chunk = hs[a : a + 256]
            flows = expm(self.Acl[None, :, :] * (chunk - d)[:, None, None])
            out[a : a + chunk.size] = np.max(np.abs(np.linalg.eigvals(flows @ landing)), axis=1)
        return float(out[0]) if scalar else out


def _check(h: float, d: float) -> None:
    if not (np.isfinite(h) and h > 0.0):
        raise ValueError(f"h: the update period must be finite and > 0, got {h!r}")
    if not (np.isfinite(d) and d >= 0.0):
        raise ValueError(f"delay: must be finite and >= 0, got {d!r}")
    if d >= h:
        raise ValueError(
            f"delay {d:g} >= update period {h:g}: an update would land after the next one is "
            "sent, outside the delayed-update test"
        )


@dataclass(frozen=True)
class HRange:
    """The first interval of stabilizing update periods for one delay."""

    delay: float
    h_min: float
    """Shortest stabilizing period found (just above ``delay``; ``nan`` if none)."""
    h_max: float
    """End of that interval (``inf`` if it reaches ``h_hi``; ``nan`` if none)."""
    h_grid: NDArray[np.float64] = field(repr=False)
    rho_grid: NDArray[np.float64] = field(repr=False)

    @property
    def feasible(self) -> bool:
        return bool(np.isfinite(self.h_min))


def find_h_range(
    system: DelayedUpdates,
    delay: float = 0.0,
    *,
    h_hi: float = 0.2,
    n_grid: int = 200,
    xtol: float = 1e-9,
) -> HRange:
    """The first interval of periods ``h > delay`` with ``rho(M_d(h)) < 1``.

    The scan covers ``(delay, h_hi]`` on ``n_grid`` points; its ends are refined with ``brentq``.
    For ``delay = 0`` and a loop stable under continuous communication the interval starts at 0
    and ``h_max`` is seed 001's maximum allowable update period.
    """
    if not (np.isfinite(delay) and delay >= 0.0):
        raise ValueError(f"delay: must be finite and >= 0, got {delay!r}")
    if not h_hi > delay:
        raise ValueError(f"h_hi {h_hi:g} must exceed the delay {delay:g}")
    grid = delay + (h_hi - delay) * np.arange(1, n_grid + 1) / n_grid
    rho = np.asarray(system.spectral_radius(grid, delay))
    stable = rho < 1.0
    if not stable.any():
        return HRange(delay, float("nan"), float("nan"), grid, rho)
    first = int(np.argmax(stable))

    def g(h: float) -> float:
        return float(system.spectral_radius(h, delay)) - 1.0

    if first == 0:
        h_min = delay
    else:
        h_min = float(brentq(g, grid[first - 1], grid[first], xtol=xtol))
    after = np.nonzero(~stable[first:])[0]
    if after.size == 0:
        return HRange(delay, h_min, float("inf"), grid, rho)
    last = first + int(after[0])
    h_max = float(brentq(g, grid[last - 1], grid[last], xtol=xtol))
    return HRange(delay, h_min, h_max, grid, rho)
