"""Rational transfer functions in ``q^-1`` and their polynomial helpers (seed 004).

:class:`TF` is the exact rational arithmetic the sampled cascade process of
:mod:`plants.cascade.model` is written in: products, sums and feedback of ``num(q^-1)/den(q^-1)``,
with the integrators ``(1 - q^-1)`` of non-stationary disturbances and PI laws cancelled exactly,
impulse responses and their squared sums (the variances of :mod:`plants.cascade.variance`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from numpy.typing import NDArray

__all__ = ["TF", "trim"]

_IMPULSE_TOL = 1e-13
_MAX_IMPULSE = 400_000


class TF:
    """Rational transfer function ``num(q^-1) / den(q^-1)`` (coefficients of ``q^0, q^-1, ...``).

    Exact common factors ``(1 - q^-1)`` (integrators of non-stationary disturbances and of PI
    laws) are cancelled after every operation, so closed loops stay free of marginal poles.
    """

    __slots__ = ("num", "den")

    def __init__(self, num: Iterable[float], den: Iterable[float] = (1.0,)) -> None:
        n = np.atleast_1d(np.asarray(list(num), dtype=float))
        d = np.atleast_1d(np.asarray(list(den), dtype=float))
        if d.size == 0 or d[0] == 0.0:
            raise ValueError("TF: den[0] must be non-zero")
        n, d = n / d[0], d / d[0]
        self.num, self.den = _cancel_integrators(trim(n), trim(d))

    @classmethod
    def delay(cls, d: int) -> TF:
        """``q^-d``."""
        return cls(np.r_[np.zeros(d), 1.0])

    def __mul__(self, other: TF | float) -> TF:
        if not isinstance(other, TF):
            return TF(self.num * float(other), self.den)
        return TF(np.convolve(self.num, other.num), np.convolve(self.den, other.den))

    __rmul__ = __mul__

    def __add__(self, other: TF | float) -> TF:
        if not isinstance(other, TF):
            other = TF([float(other)])
        if np.array_equal(self.den, other.den):
            return TF(_padd(self.num, other.num), self.den)
        return TF(
            _padd(np.convolve(self.num, other.den), np.convolve(other.num, self.den)),
            np.convolve(self.den, other.den),
        )

    __radd__ = __add__

    def __neg__(self) -> TF:
        return TF(-self.num, self.den)

    def __sub__(self, other: TF | float) -> TF:
        return self + (-other)

    def feedback_sensitivity(self) -> TF:
        """``1 / (1 + self)``."""
        return TF(self.den, _padd(self.den, self.num))

    def __truediv__(self, other: TF) -> TF:
        return TF(np.convolve(self.num, other.den), np.convolve(self.den, other.num))

    def spectral_radius(self) -> float:
        """Largest pole modulus (poles are the roots of ``z^n den(z^-1)``)."""
        d = trim(self.den)
        if d.size <= 1:
            return 0.0
        return float(np.max(np.abs(np.roots(d))))

    def is_stable(self) -> bool:
        """All poles strictly inside the unit circle (margin 1e-9)."""
        return self.spectral_radius() < 1.0 - 1e-9

    def impulse(self, n: int | None = None) -> NDArray[np.float64]:
        """Impulse response ``h_0 ... h_(n-1)``; ``n=None``: until it has decayed to 1e-13.

        Raises
        ------
        ValueError
            If ``n`` is None and the transfer function is not stable.
        """
        from scipy.signal import lfilter

        if n is None:
            rho = self.spectral_radius()
            if rho >= 1.0 - 1e-9:
                raise ValueError(f"TF.impulse: unstable (largest pole modulus {rho:.6f})")
            tail = 0 if rho == 0.0 else math.ceil(math.log(_IMPULSE_TOL) / math.log(rho))
            n = min(_MAX_IMPULSE, self.num.size + self.den.size + 10 + 2 * tail)
        x = np.zeros(int(n))
        x[0] = 1.0
        return lfilter(self.num, self.den, x)

    def h2(self) -> float:
        """Sum of squared impulse-response coefficients (``inf`` if unstable)."""
        if not self.is_stable():
            return math.inf
        return float(np.sum(self.impulse() ** 2))

    def __repr__(self) -> str:
        return f"TF(num={self.num.tolist()}, den={self.den.tolist()})"


def trim(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Drop trailing coefficients that are zero to rounding."""
    if p.size == 0:
        return np.zeros(1)
    scale = float(np.max(np.abs(p))) or 1.0
    k = p.size
    while k > 1 and abs(p[k - 1]) <= 1e-14 * scale:
        k -= 1
    return p[:k].copy()


def _padd(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    n = max(a.size, b.size)
    out = np.zeros(n)
    out[: a.size] += a
    out[: b.size] += b
    return out


def _divide_by_integrator(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """``p(q^-1) / (1 - q^-1)`` for ``p`` with a root at ``q = 1`` (the quotient's coefficients
    are the partial sums of ``p``)."""
    return np.cumsum(p)[:-1] if p.size > 1 else np.zeros(1)


def _has_unit_root(p: NDArray[np.float64]) -> bool:
    return p.size > 1 and abs(float(np.sum(p))) <= 1e-9 * float(np.sum(np.abs(p)))


def _cancel_integrators(
    num: NDArray[np.float64], den: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    while _has_unit_root(num) and _has_unit_root(den):
        num, den = trim(_divide_by_integrator(num)), trim(_divide_by_integrator(den))
    return num, den
