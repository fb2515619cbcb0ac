"""The networked controller structures of seed 001: the units' local control systems, stacked.

Seed 001 (Sun & El-Farra), sections III and V, with the gains of :mod:`controllers.qdc.design`.

Local control system of unit ``i`` (eq. (4))::

    u_i        = K_i xbar_i + sum_{j != i} K_ij xhat_j^i
    dxbar_i/dt = (A_i - L_i C_i) xbar_i + sum_{j != i} A_ij xhat_j^i + B_i u_i + L_i y_i
    dxhat_j^i/dt = Atil_j xhat_j^i + Atil_ji xbar_i + sum_{l != i, j} Atil_jl xhat_l^i
    xhat_j^i(t_k) = xbar_j(t_k)          (update with the transmitted estimate, every h)

with the model matrices ``Atil_j = Ahat_j + Bhat_j K_j`` and ``Atil_jl = Ahat_jl + Bhat_j K_jl``
built from a model ``(Ahat, Bhat)`` of the plant (possibly mismatched). ``scheme="zoh"`` sets every
model matrix to zero: the last received estimate is held (the zero-order-hold scheme of Fig. 3).
``feedback="state"`` replaces the observer by the measured local state (``xbar_i = x_i``), the
state-feedback architecture of Fig. 2(b) and of Sun & El-Farra (2008).

Centralized networked output feedback (section V, Fig. 2(c), after Montestruque & Antsaklis, the
seed's ref. [24]): one observer of the whole plant at the sensors, continuously on-line::

    dxbar/dt = Ao xbar + Bo u + L (y - C xbar),   u = K xhat,
    dxhat/dt = (Ahat + Bhat K) xhat,  xhat(t_k) = xbar(t_k)

where ``K`` stacks ``K_i, K_ij`` and ``L = diag(L_i)`` (the same gains as the quasi-decentralized
design), the controller's model ``xhat`` is reset with the transmitted estimate every ``h``, and
``(Ao, Bo)`` is the model ``(Ahat, Bhat)`` (``observer="model"``, default, as in [24] where the
observer is built from the plant model) or the true plant (``observer="plant"``).

Every structure is a linear controller ``dz/dt = F z + G m``, ``u = H z + D m`` (``m`` the measured
outputs, or the state for state feedback) with a linear reset ``z <- R z`` at the update instants
(the closed loop and its simulations: :mod:`controllers.qdc.model`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field

from controllers.qdc.design import LinearUnits, QDCGains

__all__ = ["NetworkConfig", "QDCNetwork", "LocalQDC", "CentralizedNetwork", "Network"]


class NetworkConfig(BaseModel):
    """Networked operation: the update period (validated by the simulations)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    h: float = Field(gt=0, description="update period between the control systems, hours")


# ---------------------------------------------------------------------------------------------
# controller structures: dz/dt = F z + G m, u = H z + D m, reset z <- R z every h
# ---------------------------------------------------------------------------------------------


class _LinearNetworkedController:
    """Common interface of the networked controller structures."""

    F: NDArray[np.float64]
    G: NDArray[np.float64]
    H: NDArray[np.float64]
    D: NDArray[np.float64]
    R: NDArray[np.float64]
    M: NDArray[np.float64]  # measurement matrix: m = M x (deviation variables)

    @property
    def nz(self) -> int:
        """Number of controller states."""
        return int(self.F.shape[0])

    def derivative(self, z: NDArray[np.float64], m: NDArray[np.float64]) -> NDArray[np.float64]:
        """Controller flow ``dz/dt`` between updates."""
        return self.F @ z + self.G @ m

    def control(self, z: NDArray[np.float64], m: NDArray[np.float64]) -> NDArray[np.float64]:
        """Stacked plant input (deviation) ``u = H z + D m``."""
        return self.H @ z + self.D @ m

    def update_from(self, z: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Controller state right after an update instant (``x``: plant state, deviation)."""
        rz, rx = self.reset_matrices()
        return rz @ z + rx @ x

    def reset_matrices(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Rz, Rx)`` with ``z(t_k) = Rz z(t_k^-) + Rx x(t_k)`` at an update instant."""
        raise NotImplementedError

    def initial_state(self, xbar0: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Controller state with every estimate (observer and models) at ``xbar0`` (default 0)."""
        raise NotImplementedError


class QDCNetwork(_LinearNetworkedController):
    """The local control systems of eq. (4) for all units, stacked.

    Parameters
    ----------
    plant : LinearUnits
        Plant matrices used by the local observers and controllers (``A_i``, ``A_ij``, ``B_i``).
    gains : QDCGains
        ``K_i``, ``K_ij``, ``L_i``.
    model : LinearUnits, optional
        Model ``(Ahat, Bhat)`` of the neighbours embedded in each unit (default: ``plant``).
    scheme : {"model", "zoh"}
        Embedded models, or hold of the last transmitted estimate (all model matrices zero).
    feedback : {"output", "state"}
        Observer-based output feedback (eq. (4)), or the measured local state (Fig. 2(b)).

    Notes
    -----
    Controller state: for each unit ``i`` in turn, ``xbar_i`` (output feedback only) then
    ``xhat_j^i`` for ``j != i`` ascending. The measurement ``m`` stacks ``y_i`` (output feedback) or
    ``x_i`` (state feedback); ``u`` stacks ``u_i``.
    """

    def __init__(
        self,
        plant: LinearUnits,
        gains: QDCGains,
        *,
        model: LinearUnits | None = None,
        scheme: Literal["model", "zoh"] = "model",
        feedback: Literal["output", "state"] = "output",
    ) -> None:
        if scheme not in ("model", "zoh"):
            raise ValueError(f"scheme must be 'model' or 'zoh', got {scheme!r}")
        if feedback not in ("output", "state"):
            raise ValueError(f"feedback must be 'output' or 'state', got {feedback!r}")
        model = plant if model is None else model
        self.plant, self.gains, self.model = plant, gains, model
        self.scheme, self.feedback = scheme, feedback
        n, p = plant.n, plant.p
        out = feedback == "output"
        self._xbar, self._xhat, nz = _layout(p, out)
        q = [plant.c(i).shape[0] if out else p[i] for i in range(n)]
        r = [plant.b(i).shape[1] for i in range(n)]
        m_off = np.concatenate([[0], np.cumsum(q)]).astype(int)
        u_off = np.concatenate([[0], np.cumsum(r)]).astype(int)
        x_off = np.concatenate([[0], np.cumsum(p)]).astype(int)
        at = _model_matrices(model, gains, scheme, p)
        self.F, self.G, self.H, self.D = self._flow(nz, at, m_off, u_off, out)
        self.M = plant.full()[2] if out else np.eye(int(x_off[-1]))
        self._state_fb = feedback == "state"
        self.R = self._reset(nz, out)
        self._x_off = x_off

    def _flow(
        self,
        nz: int,
        at: list[list[NDArray[np.float64]]],
        m_off: NDArray[np.int_],
        u_off: NDArray[np.int_],
        out: bool,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``F, G, H, D`` of the stacked local control systems (eq. (4)), unit by unit."""
        plant, gains = self.plant, self.gains
        n, K = plant.n, gains.K
        F = np.zeros((nz, nz))
        G = np.zeros((nz, int(m_off[-1])))
        H = np.zeros((int(u_off[-1]), nz))
        D = np.zeros((int(u_off[-1]), int(m_off[-1])))
        for i in range(n):
            us = slice(u_off[i], u_off[i + 1])
            ms = slice(m_off[i], m_off[i + 1])
            b_i = plant.b(i)
            # u_i = K_i xbar_i + sum_j K_ij xhat_j^i
            if out:
                xb = self._xbar[i]
                H[us, xb] = K[i][i]
            else:
                D[us, ms] = K[i][i]
            for j, sl in self._xhat[i].items():
                H[us, sl] = K[i][j]
            # observer of unit i
            if out:
                c_i, l_i = plant.c(i), gains.L[i]
                F[xb, xb] += plant.a(i, i) - l_i @ c_i
                for j, sl in self._xhat[i].items():
                    F[xb, sl] += plant.a(i, j)
                F[xb, :] += b_i @ H[us, :]
                G[xb, ms] += l_i
            # models of the neighbours j inside unit i
            for j, sl_j in self._xhat[i].items():
                for ll in range(n):
                    if ll == i:
                        if out:
                            F[sl_j, self._xbar[i]] += at[j][i]
                        else:
                            G[sl_j, ms] += at[j][i]
                    else:
                        F[sl_j, self._xhat[i][ll]] += at[j][ll]
        return F, G, H, D

    def _reset(self, nz: int, out: bool) -> NDArray[np.float64]:
        """``R``: at an update each model ``xhat_j^i`` takes ``xbar_j`` (output feedback) or 0."""
        R = np.eye(nz)
        for i in range(self.plant.n):
            for j, sl in self._xhat[i].items():
                R[sl, :] = 0.0
                if out:
                    R[sl, self._xbar[j]] = np.eye(self.plant.p[j])
        return R

    def reset_matrices(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Rz, Rx)`` with ``z(t_k) = Rz z(t_k^-) + Rx x(t_k)`` at an update instant.

        Each model ``xhat_j^i`` takes unit ``j``'s transmitted estimate: the observer estimate
        ``xbar_j`` (output feedback, a part of ``z``) or the measured state ``x_j`` (state
        feedback).
        """
        nx = int(self._x_off[-1])
        rx = np.zeros((self.nz, nx))
        if self._state_fb:
            for i in range(self.plant.n):
                for j, sl in self._xhat[i].items():
                    rx[sl, self._x_off[j] : self._x_off[j + 1]] = np.eye(self.plant.p[j])
        return self.R.copy(), rx

    def local(self, i: int) -> LocalQDC:
        """Unit ``i``'s local control system alone: its block of ``F``, ``G``, ``H``.

        ``F`` is block diagonal by unit (a unit's observer and embedded models use only its own
        measurement and states), so the stacked controller is exactly the ``n`` local ones side
        by side; the platform's ``qdc`` law (:mod:`controllers.qdc.law`) runs this block.

        Raises
        ------
        ValueError
            For the state-feedback structure (its local controller has no observer to transmit).
        """
        xb = self._xbar[i]
        if xb is None:
            raise ValueError("QDCNetwork.local: only the output-feedback structure has estimates")
        stop = max([xb.stop, *(s.stop for s in self._xhat[i].values())])
        block = slice(xb.start, stop)
        q = [self.plant.c(k).shape[0] for k in range(self.plant.n)]
        r = [self.plant.b(k).shape[1] for k in range(self.plant.n)]
        ms = slice(sum(q[:i]), sum(q[: i + 1]))
        us = slice(sum(r[:i]), sum(r[: i + 1]))
        F = self.F[block, block].copy()
        outside = np.delete(self.F[block, :], np.arange(block.start, block.stop), axis=1)
        if np.any(outside):
            raise ValueError(f"QDCNetwork.local: unit {i}'s controller is not a block of F")
        shift = block.start
        return LocalQDC(
            F=F,
            G=self.G[block, ms].copy(),
            H=self.H[us, block].copy(),
            xbar=slice(xb.start - shift, xb.stop - shift),
            xhat={j: slice(s.start - shift, s.stop - shift) for j, s in self._xhat[i].items()},
        )

    def estimates(self, z: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """The local observer estimates ``xbar_i`` (output feedback)."""
        return [z[s] for s in self._xbar if s is not None]

    def initial_state(self, xbar0: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        z = np.zeros(self.nz)
        if xbar0 is None:
            return z
        xbar0 = np.asarray(xbar0, dtype=float)
        for i in range(self.plant.n):
            if self._xbar[i] is not None:
                z[self._xbar[i]] = xbar0[self._x_off[i] : self._x_off[i + 1]]
            for j, sl in self._xhat[i].items():
                z[sl] = xbar0[self._x_off[j] : self._x_off[j + 1]]
        return z


@dataclass(frozen=True)
class LocalQDC:
    """One unit's local control system of eq. (4) (:meth:`QDCNetwork.local`).

    ``dz/dt = F z + G y_i``, ``u_i = H z`` (deviation variables); ``z[xbar]`` is the unit's
    observer estimate ``xbar_i`` (what it transmits), ``z[xhat[j]]`` its model ``xhat_j^i`` of
    unit ``j`` (reset to ``xbar_j`` when unit ``j``'s estimate arrives).
    """

    F: NDArray[np.float64]
    G: NDArray[np.float64]
    H: NDArray[np.float64]
    xbar: slice
    xhat: dict[int, slice]

    @property
    def nz(self) -> int:
        """Number of controller states."""
        return int(self.F.shape[0])


class CentralizedNetwork(_LinearNetworkedController):
    """Centralized networked output feedback (seed 001 Fig. 2(c), after its ref. [24]).

    Controller state ``z = (xbar, xhat)``: the plant-wide observer at the sensors and the
    controller's model, reset ``xhat <- xbar`` every ``h``; ``u = K xhat``.

    Parameters
    ----------
    plant : LinearUnits
        True plant (used by the observer when ``observer="plant"``; supplies ``C``).
    gains : QDCGains
        The same ``K`` (stacked ``K_i``, ``K_ij``) and ``L = diag(L_i)`` as the quasi-decentralized
        design.
    model : LinearUnits, optional
        The controller's model ``(Ahat, Bhat)`` (default: ``plant``).
    scheme : {"model", "zoh"}
        ``zoh`` holds ``xhat`` between updates.
    observer : {"model", "plant"}
        Matrices of the observer: the model (default, as in [24]) or the true plant.
    """

    def __init__(
        self,
        plant: LinearUnits,
        gains: QDCGains,
        *,
        model: LinearUnits | None = None,
        scheme: Literal["model", "zoh"] = "model",
        observer: Literal["model", "plant"] = "model",
    ) -> None:
        if observer not in ("model", "plant"):
            raise ValueError(f"observer must be 'model' or 'plant', got {observer!r}")
        model = plant if model is None else model
        self.plant, self.gains, self.model, self.scheme = plant, gains, model, scheme
        A, B, C = plant.full()
        Ah, Bh, _ = model.full()
        Ao, Bo = (Ah, Bh) if observer == "model" else (A, B)
        K, L = gains.full_K(), gains.full_L()
        nx = A.shape[0]
        At = np.zeros_like(Ah) if scheme == "zoh" else Ah + Bh @ K
        Z = np.zeros((nx, nx))
        self.F = np.block([[Ao - L @ C, Bo @ K], [Z, At]])
        self.G = np.vstack([L, np.zeros((nx, L.shape[1]))])
        self.H = np.hstack([np.zeros_like(K), K])
        self.D = np.zeros((K.shape[0], C.shape[0]))
        self.R = np.block([[np.eye(nx), Z], [np.eye(nx), Z]])
        self.M = C
        self._nx = nx

    def reset_matrices(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Rz, Rx)`` with ``z(t_k) = Rz z(t_k^-) + Rx x(t_k)``."""
        return self.R.copy(), np.zeros((self.nz, self._nx))

    def initial_state(self, xbar0: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        z = np.zeros(self.nz)
        if xbar0 is not None:
            z[: self._nx] = xbar0
            z[self._nx :] = xbar0
        return z


Network = QDCNetwork | CentralizedNetwork


def _layout(
    p: tuple[int, ...], out: bool
) -> tuple[list[slice | None], list[dict[int, slice]], int]:
    """The controller state's layout: for each unit ``i`` in turn, ``xbar_i`` (output feedback
    only) then ``xhat_j^i`` for ``j != i`` ascending; and its size ``nz``."""
    n = len(p)
    xbar: list[slice | None] = []
    xhat: list[dict[int, slice]] = []
    k = 0
    for i in range(n):
        if out:
            xbar.append(slice(k, k + p[i]))
            k += p[i]
        else:
            xbar.append(None)
        xhat.append({})
        for j in range(n):
            if j != i:
                xhat[i][j] = slice(k, k + p[j])
                k += p[j]
    return xbar, xhat, k


def _model_matrices(
    model: LinearUnits, gains: QDCGains, scheme: Literal["model", "zoh"], p: tuple[int, ...]
) -> list[list[NDArray[np.float64]]]:
    """The embedded models' matrices ``Atil_jl = Ahat_jl + Bhat_j K_jl`` (zero for the
    zero-order hold), for units of the plant's state dimensions ``p``."""
    n, K = len(p), gains.K
    return [
        [
            np.zeros((p[j], p[ll])) if scheme == "zoh" else model.a(j, ll) + model.b(j) @ K[j][ll]
            for ll in range(n)
        ]
        for j in range(n)
    ]
