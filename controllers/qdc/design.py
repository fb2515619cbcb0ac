"""The design of seed 001's quasi-decentralized controllers: the plant's units and the gains.

Seed 001 (Sun & El-Farra), sections III and V. Plant (seed 001 eq. (1)): ``n`` interconnected
units::

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

The controller structures built from these gains are in :mod:`controllers.qdc.network`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal, cast

import numpy as np
from numpy.typing import NDArray
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator
from scipy.linalg import block_diag

__all__ = [
    "Matrix",
    "LinearUnits",
    "QDCDesign",
    "QDCGains",
    "PAPER_CONTROLLER_POLES",
    "PAPER_OBSERVER_POLES",
    "observer_gain",
    "check_poles",
    "ControllerPoles",
    "ObserverPoles",
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
