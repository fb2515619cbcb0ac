"""A black-box ARX model by least squares, with the covariance of its coefficients.

``y_k + a_1 y_{k-1} + ... + a_na y_{k-na} = b_1 u_{k-nk} + ... + b_nb u_{k-nk-nb+1} + e_k``, the
equation-error model of Ljung (System Identification, 2nd ed., eq. (4.7)); with white ``e`` the
least-squares estimate is consistent and its covariance is ``sigma^2 (Phi^T Phi)^-1`` (eq.
(7.34)/(9.18)), ``sigma^2`` the residuals' variance over ``N - (na + nb)`` degrees of freedom.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ARXFit", "fit_arx"]


@dataclass(frozen=True)
class ARXFit:
    """The estimated ``a`` (``na``) and ``b`` (``nb``) coefficients, their joint covariance (in
    the order ``a`` then ``b``), the residuals' standard deviation and the fit (percent of the
    output's variation the one-step prediction explains: ``100 (1 - |e| / |y - mean(y)|)``)."""

    a: NDArray[np.float64]
    b: NDArray[np.float64]
    covariance: NDArray[np.float64]
    sigma: float
    fit_pct: float
    nk: int

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard deviations of ``a`` then ``b``."""
        return np.sqrt(np.diag(self.covariance))


def fit_arx(u: ArrayLike, y: ArrayLike, na: int, nb: int, nk: int = 1) -> ARXFit:
    """The ARX model of ``y`` driven by ``u`` (equal-length sample sequences, one period apart).

    Raises
    ------
    ValueError
        Orders below their minimum, sequences of unequal length, or too few samples for the
        orders (fewer than twice the coefficients).
    """
    uu, yy = np.asarray(u, dtype=float), np.asarray(y, dtype=float)
    if na < 0 or nb < 1 or nk < 0 or uu.shape != yy.shape or uu.ndim != 1:
        raise ValueError(
            f"fit_arx: na >= 0, nb >= 1, nk >= 0 and u, y of one length ({uu.shape}, {yy.shape})"
        )
    start = max(na, nk + nb - 1)
    rows = len(yy) - start
    p = na + nb
    if rows < 2 * p:
        raise ValueError(f"fit_arx: {len(yy)} samples are too few for {p} coefficients")
    k = np.arange(start, len(yy))
    phi = np.column_stack(
        [-yy[k - i] for i in range(1, na + 1)] + [uu[k - nk - j] for j in range(nb)]
    )
    target = yy[k]
    theta, *_ = np.linalg.lstsq(phi, target, rcond=None)
    residuals = target - phi @ theta
    dof = rows - p
    sigma2 = float(residuals @ residuals) / dof
    covariance = sigma2 * np.linalg.inv(phi.T @ phi)
    spread = float(np.linalg.norm(target - target.mean()))
    fit = 100.0 * (1.0 - float(np.linalg.norm(residuals)) / spread) if spread > 0 else 0.0
    return ARXFit(theta[:na], theta[na:], covariance, float(np.sqrt(sigma2)), fit, nk)
