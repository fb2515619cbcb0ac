"""The exactly discretised linear loop of the fast method: Padé delays, the plant's modal form,
``phi1`` and the matrix exponentials of candidate periods (:mod:`agents.wncsca.fast`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

PADE_ORDER = 3
COND_LIMIT = 1e8  # eigenvector condition number above which expm is used instead


def pade(delay: float, order: int = PADE_ORDER) -> tuple[NDArray[np.float64], ...]:
    """State-space ``(Ap, Bp, Cp, Dp)`` of the Pade approximant of ``exp(-s delay)``,
    ``delay > 0``."""
    import scipy.signal

    n = order
    c = [
        math.factorial(2 * n - k)
        * math.factorial(n)
        / (math.factorial(2 * n) * math.factorial(k) * math.factorial(n - k))
        for k in range(n + 1)
    ]
    den = [c[k] * delay**k for k in range(n, -1, -1)]
    num = [c[k] * (-delay) ** k for k in range(n, -1, -1)]
    Ap, Bp, Cp, Dp = scipy.signal.tf2ss(num, den)
    return Ap, Bp, Cp, Dp


class Modal:
    """Exponentials of one LTI model ``xi' = F xi + G u + Gw w``: eigen-decomposition, or the
    matrix exponential itself when the eigenvectors are ill-conditioned."""

    def __init__(self, F: NDArray[np.float64], G: NDArray[np.float64], Gw: NDArray[np.float64]):
        self.F, self.G, self.Gw = F, G, Gw
        lam, V = np.linalg.eig(F)
        self.modal = bool(np.isfinite(lam).all()) and np.linalg.cond(V) < COND_LIMIT
        if self.modal:
            self.lam, self.V = lam, V
            self.Vi = np.linalg.inv(V)
            self.ViG = self.Vi @ G
            self.ViGw = self.Vi @ Gw


def phi1(
    z: NDArray[np.complex128] | NDArray[np.float64],
    ez: NDArray[np.complex128] | NDArray[np.float64] | None = None,
) -> Any:
    """``(exp(z) - 1) / z`` (1 at 0); ``ez = exp(z)`` when already known. ``z`` is complex, or
    real where the eigenvalues are (``np.linalg.eig`` returns real eigenvalues as a real
    array)."""
    if ez is None:
        ez = np.exp(z)
    small = np.abs(z) < 1e-5
    with np.errstate(divide="ignore", invalid="ignore"):
        out = (ez - 1.0) / z
    if small.any():
        out = np.where(small, 1.0 + z / 2.0 + z * z / 6.0, out)
    return out


def expm_pair(F: NDArray[np.float64], t: float) -> tuple[NDArray[np.float64], ...]:
    """``(Phi(t), Gamma(t))`` with ``Gamma(t) = int_0^t exp(F s) ds`` by one block ``expm``."""
    n = F.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = F * t
    M[:n, n:] = np.eye(n) * t
    E = scipy.linalg.expm(M)
    return E[:n, :n], E[:n, n:]


def distinct(mid: NDArray[np.int64], key: NDArray[Any]) -> tuple[NDArray[np.int64], ...]:
    """Indices of the distinct ``(mid, key)`` items and, per item, its distinct one (``key``: one
    number per item that fixes its times)."""
    _, kid = np.unique(key, return_inverse=True)
    _, first, inverse = np.unique(
        mid.astype(np.int64) * (int(kid.max()) + 1) + kid.reshape(-1),
        return_index=True,
        return_inverse=True,
    )
    return first, inverse.reshape(-1)


def distinct_ticks(
    mid: NDArray[np.int64], ticks: NDArray[np.int64]
) -> tuple[NDArray[np.int64], ...]:
    """:func:`distinct` for a key of non-negative integers (ticks): the same items in the same
    order (by model, then key), found with a table instead of a sort."""
    span = int(ticks.max(initial=0)) + 1
    key = mid.astype(np.int64) * span + ticks
    size = int(key.max(initial=0)) + 1
    if size > 8 * len(key) + 4096:  # a sparse key: sort
        return distinct(mid, ticks)
    seen = np.zeros(size, dtype=bool)
    seen[key] = True
    keys = np.flatnonzero(seen)
    lookup = np.zeros(size, dtype=np.int64)
    lookup[keys] = np.arange(len(keys))
    inverse = lookup[key]
    first = np.zeros(len(keys), dtype=np.int64)
    first[inverse[::-1]] = np.arange(len(key) - 1, -1, -1)  # the first item of each key
    return first, inverse


class Models:
    """The distinct LTI models of one batch, and their exponentials at per-item times."""

    def __init__(self, models: list[Modal]) -> None:
        self.models = models
        self.all_modal = all(m.modal for m in models)
        if self.all_modal:
            self.lam = np.stack([m.lam for m in models])
            self.V = np.stack([m.V for m in models])
            self.Vi = np.stack([m.Vi for m in models])
            self.ViG = np.stack([m.ViG[:, 0] for m in models])
            self.ViGw = np.stack([m.ViGw for m in models])

    def step(
        self, mid: NDArray[np.int64], t: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        """Per item ``Phi(t)``, ``Gamma(t) G`` and ``Gamma(t) Gw`` of model ``mid``."""
        first, inverse = distinct(mid, t)
        return tuple(v[inverse] for v in self._step(mid[first], t[first]))

    def _step(
        self, mid: NDArray[np.int64], t: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        if not self.all_modal:
            out = []
            for m, tt in zip(mid, t, strict=True):
                model = self.models[int(m)]
                phi, gam = expm_pair(model.F, float(tt))
                out.append((phi, (gam @ model.G)[:, 0], gam @ model.Gw))
            return tuple(np.stack(v) for v in zip(*out, strict=True))
        lam, V = self.lam[mid], self.V[mid]
        tt = t[:, None]
        ez = np.exp(lam * tt)
        phi = np.real((V * ez[:, None, :]) @ self.Vi[mid])
        c = tt * phi1(lam * tt, ez)
        g = np.real(np.einsum("inm,im->in", V, c * self.ViG[mid]))
        gw = np.real(V @ (c[:, :, None] * self.ViGw[mid]))
        return phi, g, gw

    def gamma_w(
        self, mid: NDArray[np.int64], t: NDArray[np.float64], dw: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Per item ``Gamma(t) Gw dw``."""
        gw: NDArray[np.float64] = np.einsum("inw,iw->in", self.step(mid, t)[2], dw)
        return gw

    def rows(
        self, mid: NDArray[np.int64], cy: NDArray[np.float64], t: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        """Output rows at times ``t`` (items x points) after a state ``xi``, input ``u`` held and
        affine input ``w``: ``y(t) = R xi + rg u + Rw w`` (``cy``: output row per model)."""
        return self._rows(mid, cy[mid], t)

    def _rows(
        self, mid: NDArray[np.int64], cy: NDArray[np.float64], t: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        if not self.all_modal:
            n_items, n_pts = t.shape
            n, nw = self.models[0].F.shape[0], self.models[0].Gw.shape[1]
            R = np.zeros((n_items, n_pts, n))
            rg = np.zeros((n_items, n_pts))
            Rw = np.zeros((n_items, n_pts, nw))
            for i in range(n_items):
                m = self.models[int(mid[i])]
                for q in range(n_pts):
                    phi, gam = expm_pair(m.F, float(t[i, q]))
                    R[i, q] = cy[i] @ phi
                    rg[i, q] = cy[i] @ gam @ m.G[:, 0]
                    Rw[i, q] = cy[i] @ gam @ m.Gw
            return R, rg, Rw
        lam = self.lam[mid][:, None, :]  # items, 1, n
        cyv = np.einsum("in,inm->im", cy, self.V[mid])[:, None, :]
        tt = t[:, :, None]
        ez = np.exp(lam * tt)
        R = np.real((cyv * ez) @ self.Vi[mid])
        c = cyv * tt * phi1(lam * tt, ez)
        rg = np.real(np.sum(c * self.ViG[mid][:, None, :], axis=2))
        Rw = np.real(c @ self.ViGw[mid])
        return R, rg, Rw
