"""Quasi-decentralized networked output-feedback control of seed 001 (Sun & El-Farra), sec. III, V.

Plant (seed 001 eq. (1)): ``n`` interconnected units::

    dx_i/dt = A_i x_i + B_i u_i + sum_{j != i} A_ij x_j,     y_i = C_i x_i

Gains (eq. (2)-(3), section V)
------------------------------
``u_i = K_i x_i + sum_j K_ij x_j`` with

* ``K_ij = -B_i^{-1} A_ij`` so that ``Abar_ij = A_ij + B_i K_ij = O`` (the "feedforward" that
  cancels the coupling; needs ``B_i`` square and nonsingular, as it is for the CSTRs of section V);
* ``K_i`` placing the eigenvalues of ``Abar_i = A_i + B_i K_i``. With ``B_i`` square and
  nonsingular any ``Abar_i`` is reachable, so the poles do not fix ``K_i``: the rest is a design
  choice, and the maximum update period depends on it. Method ``"diagonal"`` (default) takes
  ``Abar_i = diag(controller_poles[i])`` in the plant's own coordinates, i.e.
  ``K_i = B_i^{-1} (diag(p_i) - A_i)``: every state is decoupled and gets its own pole, in the
  order given (for the CSTRs ``(T_i, CA_i) -> (-5, -1)``). This is what
  ``scipy.signal.place_poles`` (and so ``control.place``) return for a square full-rank ``B``
  (with the poles sorted ascending), and it is invariant under diagonal scalings of states and
  inputs, so the paper's unstated "dimensionless" variables do not matter. Method ``"place"``
  calls ``scipy.signal.place_poles`` (robust eigenstructure assignment), also for non-square
  ``B_i``. Other assignments (``(T, CA) -> (-1, -5)``, double poles) give ``h_max`` from 0.039
  to 0.043 h with exact models and from 0.034 to 0.047 h with the hold (``bench/update_period.py``);
  the default is the one that reproduces the paper's 0.043 h and 0.042 h;
* ``L_i`` placing the eigenvalues of ``A_i - L_i C_i`` (observer). For one measured output the gain
  is unique (Ackermann's formula on the dual system); for more, ``scipy.signal.place_poles``.

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
outputs, or the state for state feedback) with a linear reset ``z <- R z`` at the update instants;
:func:`simulate_linear` iterates the exact sampled closed loop (matrix exponential) and
:func:`simulate_nonlinear` runs the controllers against a non-linear plant (``plants/integrate.py``
``rk4`` between updates).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal, cast

import numpy as np
from numpy.typing import NDArray
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator
from scipy.linalg import block_diag, expm

from plants.integrate import rk4

__all__ = [
    "Matrix",
    "LinearUnits",
    "QDCDesign",
    "QDCGains",
    "NetworkConfig",
    "PAPER_CONTROLLER_POLES",
    "PAPER_OBSERVER_POLES",
    "observer_gain",
    "QDCNetwork",
    "LocalQDC",
    "CentralizedNetwork",
    "check_poles",
    "ControllerPoles",
    "ObserverPoles",
    "LinearRun",
    "NonlinearRun",
    "closed_loop_matrices",
    "simulate_linear",
    "simulate_nonlinear",
]

Matrix = tuple[tuple[float, ...], ...]
"""A real matrix as a tuple of rows (hashable, for frozen pydantic models)."""

PAPER_CONTROLLER_POLES: tuple[tuple[float, ...], ...] = ((-5.0, -1.0), (-5.0, -1.0))
"""Seed 001 section V: eigenvalues of ``Abar_1`` and ``Abar_2`` at -5 and -1."""
PAPER_OBSERVER_POLES: tuple[tuple[float, ...], ...] = ((-50.0, -25.0), (-50.0, -25.0))
"""Seed 001 section V: eigenvalues of ``A_1 - L_1 C_1`` and ``A_2 - L_2 C_2`` at -50 and -25."""


def _mat(a: Any) -> Matrix:
    arr = np.atleast_2d(np.asarray(a, dtype=float))
    return tuple(tuple(float(v) for v in row) for row in arr)


def _arr(m: Matrix) -> NDArray[np.float64]:
    return np.array(m, dtype=float).reshape(len(m), len(m[0]) if m else 0)


class LinearUnits(BaseModel):
    """A linear plant of ``n`` interconnected units, seed 001 eq. (1).

    ``A[i][i]`` is ``A_i``, ``A[i][j]`` (``j != i``) the interconnection ``A_ij``; ``B[i]`` and
    ``C[i]`` are ``B_i`` and ``C_i``. Build it from arrays with :meth:`from_arrays`.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    A: tuple[tuple[Matrix, ...], ...] = Field(description="blocks A_i (diagonal) and A_ij")
    B: tuple[Matrix, ...] = Field(description="input matrices B_i")
    C: tuple[Matrix, ...] = Field(description="output matrices C_i")

    @model_validator(mode="after")
    def _shapes(self) -> LinearUnits:
        n = len(self.A)
        if n < 1 or any(len(row) != n for row in self.A):
            raise ValueError("A must be an n x n grid of blocks A[i][j]")
        if len(self.B) != n or len(self.C) != n:
            raise ValueError(
                f"B and C need one matrix per unit ({n}); got {len(self.B)}, {len(self.C)}"
            )
        p = [len(self.A[i][i]) for i in range(n)]
        for i in range(n):
            for j in range(n):
                shape = np.shape(self.A[i][j])
                if shape != (p[i], p[j]):
                    raise ValueError(f"A[{i}][{j}] has shape {shape}, expected {(p[i], p[j])}")
            if np.ndim(self.B[i]) != 2 or np.shape(self.B[i])[0] != p[i]:
                raise ValueError(f"B[{i}] has shape {np.shape(self.B[i])}, needs {p[i]} rows")
            if np.ndim(self.C[i]) != 2 or np.shape(self.C[i])[1] != p[i]:
                raise ValueError(f"C[{i}] has shape {np.shape(self.C[i])}, needs {p[i]} columns")
        return self

    @classmethod
    def from_arrays(
        cls, A: Sequence[Sequence[Any]], B: Sequence[Any], C: Sequence[Any]
    ) -> LinearUnits:
        """From nested sequences of numpy arrays (``A[i][j]``, ``B[i]``, ``C[i]``)."""
        return cls(
            A=tuple(tuple(_mat(a) for a in row) for row in A),
            B=tuple(_mat(b) for b in B),
            C=tuple(_mat(c) for c in C),
        )

    @classmethod
    def from_model(cls, model: Any) -> LinearUnits:
        """From any object with ``A``, ``B``, ``C`` attributes (e.g. ``TwoUnitLinearModel``)."""
        return cls.from_arrays(model.A, model.B, model.C)

    # -- array views ----------------------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of units."""
        return len(self.A)

    @property
    def p(self) -> tuple[int, ...]:
        """State dimension of each unit."""
        return tuple(len(self.A[i][i]) for i in range(self.n))

    def a(self, i: int, j: int) -> NDArray[np.float64]:
        """Block ``A_i`` (``i == j``) or ``A_ij`` as an array."""
        return _arr(self.A[i][j])

    def b(self, i: int) -> NDArray[np.float64]:
        """``B_i`` as an array."""
        return _arr(self.B[i])

    def c(self, i: int) -> NDArray[np.float64]:
        """``C_i`` as an array."""
        return _arr(self.C[i])

    def full(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The whole plant ``(A, B, C)`` with stacked states, inputs and outputs."""
        A = np.block([[self.a(i, j) for j in range(self.n)] for i in range(self.n)])
        B = block_diag(*(self.b(i) for i in range(self.n)))
        C = block_diag(*(self.c(i) for i in range(self.n)))
        return A, B, C


def check_poles(name: str, poles: tuple[tuple[float, ...], ...]) -> None:
    """Refuse (``ValueError`` naming ``name[i][k]``) a pole that is not real and negative."""
    for i, unit in enumerate(poles):
        for k, pole in enumerate(unit):
            if not pole < 0.0:
                raise ValueError(
                    f"{name}[{i}][{k}] = {pole} is not in the open left half-plane (must be < 0)"
                )


def _stable_poles(name: str, poles: tuple[tuple[float, ...], ...]) -> tuple[tuple[float, ...], ...]:
    check_poles(name, poles)
    return poles


ControllerPoles = Annotated[
    tuple[tuple[float, ...], ...],
    Field(description="eigenvalues of Abar_i = A_i + B_i K_i, one tuple per unit (real, < 0)"),
    AfterValidator(lambda v: _stable_poles("controller_poles", v)),
]
"""Design poles of the local controllers (validated: real and negative)."""
ObserverPoles = Annotated[
    tuple[tuple[float, ...], ...],
    Field(description="eigenvalues of A_i - L_i C_i, one tuple per unit (real, < 0)"),
    AfterValidator(lambda v: _stable_poles("observer_poles", v)),
]
"""Design poles of the local observers (validated: real and negative)."""


class QDCDesign(BaseModel):
    """Controller and observer design of seed 001 section V (see the module docstring)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    plant: LinearUnits
    controller_poles: ControllerPoles = PAPER_CONTROLLER_POLES
    observer_poles: ObserverPoles = PAPER_OBSERVER_POLES
    controller_method: Literal["diagonal", "place"] = Field(
        default="diagonal",
        description="diagonal: Abar_i = diag(controller_poles[i]); place: scipy place_poles",
    )
    cancel_coupling: bool = Field(
        default=True,
        description="K_ij = -B_i^-1 A_ij so that Abar_ij = O (else K_ij = O, decentralized)",
    )

    @model_validator(mode="after")
    def _consistent(self) -> QDCDesign:
        plant = self.plant
        for name, poles in (
            ("controller_poles", self.controller_poles),
            ("observer_poles", self.observer_poles),
        ):
            if len(poles) != plant.n or any(len(poles[i]) != plant.p[i] for i in range(plant.n)):
                raise ValueError(
                    f"{name} needs one pole per state of each unit {plant.p}; got "
                    f"{[len(u) for u in poles]}"
                )
        needs_inverse = self.cancel_coupling or self.controller_method == "diagonal"
        if needs_inverse:
            why = (
                "K_ij = -B_i^-1 A_ij must cancel the coupling (cancel_coupling=True)"
                if self.cancel_coupling
                else "controller_method='diagonal' sets K_i = B_i^-1 (diag(p_i) - A_i)"
            )
            for i in range(plant.n):
                b = plant.b(i)
                if b.shape[0] != b.shape[1]:
                    raise ValueError(
                        f"plant.B[{i}] has shape {b.shape}: must be square because {why}"
                    )
                if np.linalg.matrix_rank(b) < b.shape[0]:
                    raise ValueError(f"plant.B[{i}] is singular: must be nonsingular because {why}")
        return self

    def gains(self) -> QDCGains:
        """The gains ``K_i, K_ij, L_i`` of this design."""
        from scipy.signal import place_poles

        plant = self.plant
        n = plant.n
        K: list[list[NDArray[np.float64]]] = [[np.zeros(0)] * n for _ in range(n)]
        L = []
        for i in range(n):
            a_i, b_i = plant.a(i, i), plant.b(i)
            poles = np.asarray(self.controller_poles[i], dtype=float)
            if self.controller_method == "diagonal":
                # np.linalg.solve is typed floating[Any]: float64 for these float64 operands
                K[i][i] = cast("NDArray[np.float64]", np.linalg.solve(b_i, np.diag(poles) - a_i))
            else:
                K[i][i] = -place_poles(a_i, b_i, poles).gain_matrix
            for j in range(n):
                if j == i:
                    continue
                if self.cancel_coupling:
                    K[i][j] = cast("NDArray[np.float64]", -np.linalg.solve(b_i, plant.a(i, j)))
                else:
                    K[i][j] = np.zeros((b_i.shape[1], plant.p[j]))
            L.append(observer_gain(a_i, plant.c(i), self.observer_poles[i]))
        return QDCGains(K=tuple(tuple(row) for row in K), L=tuple(L))


@dataclass(frozen=True)
class QDCGains:
    """Designed gains: ``K[i][i] = K_i``, ``K[i][j] = K_ij``, ``L[i] = L_i``."""

    K: tuple[tuple[NDArray[np.float64], ...], ...]
    L: tuple[NDArray[np.float64], ...]

    def full_K(self) -> NDArray[np.float64]:  # noqa: N802 - the paper's symbol
        """The stacked state-feedback gain ``[[K_1, K_12], [K_21, K_2]]``."""
        full: NDArray[np.float64] = np.block([list(row) for row in self.K])
        return full

    def full_L(self) -> NDArray[np.float64]:  # noqa: N802
        """``diag(L_1, ..., L_n)``."""
        full: NDArray[np.float64] = block_diag(*self.L)
        return full


def observer_gain(
    A: NDArray[np.float64], C: NDArray[np.float64], poles: Sequence[float]
) -> NDArray[np.float64]:
    """Observer gain ``L`` with ``eig(A - L C) = poles``.

    One output: Ackermann's formula on the dual pair, ``L = phi(A) O^{-1} e_p`` (``O`` the
    observability matrix, ``phi`` the desired characteristic polynomial); the gain is unique and
    repeated poles are allowed. Several outputs: ``scipy.signal.place_poles`` on ``(A^T, C^T)``.

    Raises
    ------
    ValueError
        If ``(A, C)`` is not observable.
    """
    from scipy.signal import place_poles

    A = np.asarray(A, dtype=float)
    C = np.atleast_2d(np.asarray(C, dtype=float))
    p = A.shape[0]
    if C.shape[0] == 1:
        obs = np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(p)])
        if np.linalg.matrix_rank(obs) < p:
            raise ValueError("observer_gain: (A, C) is not observable")
        coeffs = np.real(np.poly(np.asarray(poles, dtype=complex)))
        phi = sum(c * np.linalg.matrix_power(A, p - k) for k, c in enumerate(coeffs))
        e_p = np.zeros((p, 1))
        e_p[-1, 0] = 1.0
        gain: NDArray[np.float64] = phi @ np.linalg.solve(obs, e_p)
        return gain
    gain = place_poles(A.T, C.T, np.asarray(poles, dtype=float)).gain_matrix.T
    return gain


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
        K = gains.K
        # model matrices Atil_jl = Ahat_jl + Bhat_j K_jl (zero for the zero-order hold)
        at = [
            [
                np.zeros((p[j], p[ll]))
                if scheme == "zoh"
                else model.a(j, ll) + model.b(j) @ K[j][ll]
                for ll in range(n)
            ]
            for j in range(n)
        ]
        out = feedback == "output"
        # controller-state layout
        self._xbar: list[slice | None] = []
        self._xhat: list[dict[int, slice]] = []
        k = 0
        for i in range(n):
            if out:
                self._xbar.append(slice(k, k + p[i]))
                k += p[i]
            else:
                self._xbar.append(None)
            self._xhat.append({})
            for j in range(n):
                if j != i:
                    self._xhat[i][j] = slice(k, k + p[j])
                    k += p[j]
        nz = k
        q = [plant.c(i).shape[0] if out else p[i] for i in range(n)]
        r = [plant.b(i).shape[1] for i in range(n)]
        m_off = np.concatenate([[0], np.cumsum(q)]).astype(int)
        u_off = np.concatenate([[0], np.cumsum(r)]).astype(int)
        x_off = np.concatenate([[0], np.cumsum(p)]).astype(int)
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
        R = np.eye(nz)
        for i in range(n):
            for j, sl in self._xhat[i].items():
                R[sl, :] = 0.0
                if out:
                    R[sl, self._xbar[j]] = np.eye(p[j])
        self.F, self.G, self.H, self.D = F, G, H, D
        self.M = plant.full()[2] if out else np.eye(int(x_off[-1]))
        self._state_fb = feedback == "state"
        self.R = R
        self._x_off = x_off

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
        by side; the platform's ``qdc`` law (:mod:`controllers.qdc_law`) runs this block.

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


# ---------------------------------------------------------------------------------------------
# closed-loop simulation
# ---------------------------------------------------------------------------------------------


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
    Mm, F, G, H, D = network.M, network.F, network.G, network.H, network.D
    step = min(h / 4.0, 0.005) if max_step is None else max_step
    dummy = np.zeros(0)

    def f(t: float, w: NDArray[np.float64], _u: NDArray[np.float64]) -> NDArray[np.float64]:
        x, z = w[:nx], w[nx:]
        m = Mm @ (x - x_s)
        u = u_s + H @ z + D @ m
        return np.concatenate([plant.rhs(t, x, u), F @ z + G @ m])

    z = network.initial_state(xbar0)
    x = np.asarray(x0, dtype=float)
    z = network.update_from(z, x - x_s)
    ts, xs, us = [0.0], [x.copy()], [u_s + H @ z + D @ (Mm @ (x - x_s))]
    t = 0.0
    left = False
    k = 0
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
