"""Maximum allowable update period of quasi-decentralized networked control (seed 001, sec. IV-V).

Switched-system formulation (seed 001 eq. (5)-(7)): with ``e_j^i = xbar_j - xhat_j^i``
(``e_i^i = 0``), ``e_j = (e_j^1, ..., e_j^n)``, ``e = (e_1, ..., e_n)`` and
``xi = (x, xbar, e)``, the closed loop of eq. (1) and (4) is ``dxi/dt = Lambda xi`` between
updates and ``e(t_k) = 0`` at the updates, so that ``xi(t_k) = M(h)^k xi_0`` with the test matrix
(eq. (8))::

    M(h) = I_o expm(Lambda h) I_o,       I_o = diag(I_m, I_m, O_mn)

and the zero solution is globally exponentially stable iff ``rho(M(h)) < 1``. Substituting eq. (4)
into eq. (1), with ``Abar_jl = A_jl + B_j K_jl`` (``Abar_jj = A_j + B_j K_j``),
``H_j = Abar_j - L_j C_j`` and the model matrices ``Atil_jl = Ahat_jl + Bhat_j K_jl``::

    dx_i/dt      = sum_j A_ij x_j + sum_j B_i K_ij xbar_j - sum_{j != i} B_i K_ij e_j^i
    dxbar_i/dt   = L_i C_i x_i + sum_j (Abar_ij - [i=j] L_i C_i) xbar_j - sum_{j != i} Abar_ij e_j^i
    de_j^i/dt    = L_j C_j x_j + sum_l (Abar_jl - [l=j] L_j C_j - Atil_jl) xbar_l
                   - sum_{l != j} Abar_jl e_l^j + sum_{l != i} Atil_jl e_l^i          (j != i)

which for two units gives exactly the blocks ``Lambda_11 ... Lambda_33`` printed in section V
(checked block by block in ``tests/unit/test_update_period.py``; the blocks ``e_i^i`` are kept as
the zero rows and columns the paper has, they only add zero eigenvalues to ``M``). The
zero-order-hold scheme has ``Atil = O``. The state-feedback architecture (Fig. 2(b)) has
``xbar = x`` and ``xi = (x, e)``; the centralized architecture (Fig. 2(c)) has ``xi = (x, xbar, e)``
with ``e = xbar - xhat`` for the single controller's model (see :mod:`controllers.qdc.network`).

Because ``I_o`` zeroes the ``e`` part, the non-zero eigenvalues of ``M(h)`` are those of the leading
``2m x 2m`` block of ``expm(Lambda h)`` (``m x m`` for state feedback), which is what
:func:`spectral_radius` computes (batched over ``h``).

Finding h_max
-------------
``M(0) = I_o`` has the eigenvalue 1, and for small ``h`` the eigenvalues of ``M(h)`` are
``1 + lambda h + O(h^2)`` with ``lambda`` those of the closed loop under continuous communication
(``Lambda`` restricted to ``(x, xbar)``). So the networked loop is stable for small ``h`` iff that
loop is Hurwitz; if it is not, ``h_max = 0``. ``rho(M(h))`` is not monotone in ``h`` in general
(windows of stability can reopen beyond the first loss of stability), so :func:`find_h_max` does
not bisect: it evaluates ``rho`` on a grid ``(0, h_hi]``, brackets **every** crossing of 1 and
refines each with ``scipy.optimize.brentq``; ``h_max`` is the **first** crossing, i.e. the largest
``hbar`` such that every period in ``(0, hbar)`` is stabilizing (later crossings are reported in
``crossings``). A window narrower than the grid spacing can be missed; ``inf`` means no crossing on
the grid. For the two CSTRs ``rho(M(h))`` crosses 1 only once on ``(0, 1] h``. ``Lambda`` has
unstable modes in its ``e`` part, so ``expm(Lambda h)`` is only accurate up to
:meth:`SwitchedSystem.reliable_h` (``25 / max Re eig(Lambda)``, about 1.2 h here), and the search
refuses a longer scan.

Plant-model mismatch (section V-A)
----------------------------------
``delta1 = (dH1_m - dH1) / dH1``: the embedded models are the Jacobians of eq. (10) with
``dH1_m = (1 + delta1) dH1`` taken at the true operating point, with the same ``B`` and gains; the
observers and the local controllers use the true matrices, as in the paper's ``Lambda``.

Map data for figures like seed 001 Fig. 2(a)-(c) (``rho`` over ``(delta1, h)`` for the three
architectures), Fig. 3(a) (``rho`` against ``h`` for several ``delta1`` and the zero-order hold) and
Fig. 4(a)-(b) (``rho`` over ``(delta1, lambda_12)`` at ``h = 0.04 h``, ``lambda_12`` the second pole
of ``A_1 - L_1 C_1``, the first fixed at -50) come from :func:`rho_map`, :func:`rho_curves` and
:func:`rho_map_observer_pole`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import BaseModel, ConfigDict, Field
from scipy.linalg import expm
from scipy.optimize import brentq

from controllers.qdc.design import (
    PAPER_CONTROLLER_POLES,
    PAPER_OBSERVER_POLES,
    LinearUnits,
    QDCDesign,
    QDCGains,
)
from plants.cstr_recycle import PAPER_PARAMS, CSTRRecycle, CSTRRecycleParams

__all__ = [
    "Architecture",
    "SwitchedSystem",
    "UpdatePeriodConfig",
    "HMaxResult",
    "build_lambda",
    "lambda_state_feedback",
    "lambda_centralized",
    "switched_system",
    "test_matrix",
    "spectral_radius",
    "find_h_max",
    "CSTRRecycleCase",
    "rho_map",
    "rho_curves",
    "rho_map_observer_pole",
    "PAPER_H_MAX",
    "PAPER_H_MAX_ZOH",
]

PAPER_H_MAX = 0.043
"""Seed 001 section V-A: the exact-model quasi-decentralized loop is stable for ``h < 0.043 h``."""
PAPER_H_MAX_ZOH = 0.042
"""Seed 001 section V-A, Fig. 3(a): zero-order-hold scheme stable for ``h <= 0.042 h``."""

Architecture = Literal["qdc", "qdc_zoh", "qdc_state", "centralized", "centralized_plant_observer"]
"""``qdc``: eq. (4) with models; ``qdc_zoh``: zero-order hold; ``qdc_state``: state feedback with
models (Fig. 2(b)); ``centralized``: Fig. 2(c) with the observer built from the model (as in [24]);
``centralized_plant_observer``: the same with an observer built from the true plant."""


class UpdatePeriodConfig(BaseModel):
    """Search settings for :func:`find_h_max`."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    h_hi: float = Field(default=0.2, gt=0, description="upper end of the scanned periods, hours")
    n_grid: int = Field(default=200, ge=2, description="grid points on (0, h_hi]")
    xtol: float = Field(default=1e-9, gt=0, description="brentq tolerance on h, hours")


@dataclass(frozen=True)
class SwitchedSystem:
    """``Lambda`` of eq. (7) and the size ``k`` of the part ``I_o`` keeps (``(x, xbar)``)."""

    Lambda: NDArray[np.float64]
    k: int

    def continuous_loop(self) -> NDArray[np.float64]:
        """Closed loop under continuous communication (``e = 0``): ``Lambda[:k, :k]``."""
        return self.Lambda[: self.k, : self.k]

    def reliable_h(self) -> float:
        """Largest ``h`` for which ``rho(M(h))`` is computed accurately, ``25 / max Re eig``.

        ``Lambda`` has unstable modes in the ``e`` part; beyond this ``h`` the entries of
        ``expm(Lambda h)`` exceed ``e^25`` and round-off (``~ e^25 * eps``) swamps the ``(x, xbar)``
        block whose eigenvalues decide stability.
        """
        top = float(np.max(np.linalg.eigvals(self.Lambda).real))
        return np.inf if top <= 0.0 else 25.0 / top


def _blocks(plant: LinearUnits, gains: QDCGains, model: LinearUnits, zoh: bool):
    n, p = plant.n, plant.p
    K = gains.K
    abar = [[plant.a(i, j) + plant.b(i) @ K[i][j] for j in range(n)] for i in range(n)]
    atil = [
        [
            np.zeros((p[j], p[ll])) if zoh else model.a(j, ll) + model.b(j) @ K[j][ll]
            for ll in range(n)
        ]
        for j in range(n)
    ]
    return abar, atil


def build_lambda(
    plant: LinearUnits,
    gains: QDCGains,
    *,
    model: LinearUnits | None = None,
    scheme: Literal["model", "zoh"] = "model",
) -> SwitchedSystem:
    """``Lambda`` of eq. (6)-(7) for the quasi-decentralized output-feedback loop (eq. (4)).

    Parameters
    ----------
    plant : LinearUnits
        The true plant (``A_i``, ``A_ij``, ``B_i``, ``C_i``).
    gains : QDCGains
        ``K_i``, ``K_ij``, ``L_i``.
    model : LinearUnits, optional
        ``(Ahat, Bhat)`` of the embedded models (default: exact, ``plant``).
    scheme : {"model", "zoh"}
        ``zoh`` sets every model matrix ``Atil`` to zero.

    Returns
    -------
    SwitchedSystem
        ``Lambda`` on ``xi = (x, xbar, e)`` of size ``2m + mn``, ``k = 2m``.
    """
    model = plant if model is None else model
    n, p = plant.n, plant.p
    m = sum(p)
    off = np.concatenate([[0], np.cumsum(p)]).astype(int)
    K, L = gains.K, gains.L
    abar, atil = _blocks(plant, gains, model, scheme == "zoh")
    lc = [L[i] @ plant.c(i) for i in range(n)]

    def xs(i: int) -> slice:
        return slice(off[i], off[i + 1])

    def xb(i: int) -> slice:
        return slice(m + off[i], m + off[i + 1])

    def ee(j: int, i: int) -> slice:  # e_j^i
        s = 2 * m + j * m + off[i]
        return slice(s, s + p[j])

    N = 2 * m + m * n
    Lam = np.zeros((N, N))
    for i in range(n):
        b_i = plant.b(i)
        for j in range(n):
            Lam[xs(i), xs(j)] += plant.a(i, j)  # Lambda_11
            Lam[xs(i), xb(j)] += b_i @ K[i][j]  # Lambda_12
            Lam[xb(i), xb(j)] += abar[i][j] - (lc[i] if i == j else 0.0)  # Lambda_22
            if j != i:
                Lam[xs(i), ee(j, i)] -= b_i @ K[i][j]  # Lambda_13
                Lam[xb(i), ee(j, i)] -= abar[i][j]  # Lambda_23
        Lam[xb(i), xs(i)] += lc[i]  # Lambda_21
    for j in range(n):
        for i in range(n):
            if i == j:
                continue
            r = ee(j, i)
            Lam[r, xs(j)] += lc[j]  # Lambda_31
            for ll in range(n):
                Lam[r, xb(ll)] += abar[j][ll] - (lc[j] if ll == j else 0.0) - atil[j][ll]
                if ll != j:
                    Lam[r, ee(ll, j)] -= abar[j][ll]  # Lambda_33
                if ll != i:
                    Lam[r, ee(ll, i)] += atil[j][ll]
    return SwitchedSystem(Lambda=Lam, k=2 * m)


def lambda_state_feedback(
    plant: LinearUnits,
    gains: QDCGains,
    *,
    model: LinearUnits | None = None,
    scheme: Literal["model", "zoh"] = "model",
) -> SwitchedSystem:
    """``Lambda`` of the quasi-decentralized **state**-feedback loop (Fig. 2(b); ``xbar = x``).

    ``u_i = K_i x_i + sum_{j != i} K_ij xhat_j^i``; the model ``xhat_j^i`` follows
    ``Atil_j xhat_j^i + Atil_ji x_i + sum_l Atil_jl xhat_l^i`` and is reset to ``x_j``. With
    ``e_j^i = x_j - xhat_j^i`` and ``xi = (x, e)``::

        dx_i/dt   = sum_j Abar_ij x_j - sum_{j != i} B_i K_ij e_j^i
        de_j^i/dt = sum_l (Abar_jl - Atil_jl) x_l - sum_{l != j} B_j K_jl e_l^j
                    + sum_{l != i} Atil_jl e_l^i
    """
    model = plant if model is None else model
    n, p = plant.n, plant.p
    m = sum(p)
    off = np.concatenate([[0], np.cumsum(p)]).astype(int)
    K = gains.K
    abar, atil = _blocks(plant, gains, model, scheme == "zoh")

    def xs(i: int) -> slice:
        return slice(off[i], off[i + 1])

    def ee(j: int, i: int) -> slice:
        s = m + j * m + off[i]
        return slice(s, s + p[j])

    N = m + m * n
    Lam = np.zeros((N, N))
    for i in range(n):
        for j in range(n):
            Lam[xs(i), xs(j)] += abar[i][j]
            if j != i:
                Lam[xs(i), ee(j, i)] -= plant.b(i) @ K[i][j]
    for j in range(n):
        for i in range(n):
            if i == j:
                continue
            r = ee(j, i)
            for ll in range(n):
                Lam[r, xs(ll)] += abar[j][ll] - atil[j][ll]
                if ll != j:
                    Lam[r, ee(ll, j)] -= plant.b(j) @ K[j][ll]
                if ll != i:
                    Lam[r, ee(ll, i)] += atil[j][ll]
    return SwitchedSystem(Lambda=Lam, k=m)


def lambda_centralized(
    plant: LinearUnits,
    gains: QDCGains,
    *,
    model: LinearUnits | None = None,
    scheme: Literal["model", "zoh"] = "model",
    observer: Literal["model", "plant"] = "model",
) -> SwitchedSystem:
    """``Lambda`` of the centralized networked output-feedback loop (Fig. 2(c), ref. [24]).

    Observer ``dxbar/dt = Ao xbar + Bo u + L (y - C xbar)`` at the sensors, controller
    ``u = K xhat``, model ``dxhat/dt = Atil xhat`` (``Atil = Ahat + Bhat K``, or ``O`` for ``zoh``)
    reset to ``xbar``. With ``e = xbar - xhat``::

        dx/dt    = A x + B K xbar - B K e
        dxbar/dt = L C x + (Ao - L C + Bo K) xbar - Bo K e
        de/dt    = L C x + (Ao - L C + Bo K - Atil) xbar + (Atil - Bo K) e

    ``(Ao, Bo)`` is ``(Ahat, Bhat)`` for ``observer="model"`` (then, for an exact model, the last
    row is ``L C x - L C xbar + A e`` as in [24]) or ``(A, B)`` for ``observer="plant"``.
    """
    model = plant if model is None else model
    A, B, C = plant.full()
    Ah, Bh, _ = model.full()
    Ao, Bo = (Ah, Bh) if observer == "model" else (A, B)
    K, L = gains.full_K(), gains.full_L()
    At = np.zeros_like(A) if scheme == "zoh" else Ah + Bh @ K
    lc = L @ C
    Lam = np.block(
        [
            [A, B @ K, -B @ K],
            [lc, Ao - lc + Bo @ K, -Bo @ K],
            [lc, Ao - lc + Bo @ K - At, At - Bo @ K],
        ]
    )
    return SwitchedSystem(Lambda=Lam, k=2 * A.shape[0])


def switched_system(
    architecture: Architecture,
    plant: LinearUnits,
    gains: QDCGains,
    model: LinearUnits | None = None,
) -> SwitchedSystem:
    """``Lambda`` of one of the :data:`Architecture` s."""
    if architecture == "qdc":
        return build_lambda(plant, gains, model=model)
    if architecture == "qdc_zoh":
        return build_lambda(plant, gains, model=model, scheme="zoh")
    if architecture == "qdc_state":
        return lambda_state_feedback(plant, gains, model=model)
    if architecture == "centralized":
        return lambda_centralized(plant, gains, model=model, observer="model")
    if architecture == "centralized_plant_observer":
        return lambda_centralized(plant, gains, model=model, observer="plant")
    raise ValueError(f"architecture: unknown {architecture!r}")


def _periods(h: ArrayLike) -> NDArray[np.float64]:
    arr = np.atleast_1d(np.asarray(h, dtype=float))
    if arr.ndim != 1 or not np.all(arr > 0.0) or not np.all(np.isfinite(arr)):
        raise ValueError(f"h: update periods must be finite and > 0 (hours); got {h!r}")
    return arr


def test_matrix(system: SwitchedSystem, h: float) -> NDArray[np.float64]:
    """``M(h) = I_o expm(Lambda h) I_o`` (eq. (8)), full size.

    Raises
    ------
    ValueError
        If ``h <= 0`` (message names ``h``).
    """
    (hh,) = _periods(h)
    io = np.zeros(system.Lambda.shape[0])
    io[: system.k] = 1.0
    return (io[:, None] * expm(system.Lambda * hh)) * io[None, :]


test_matrix.__test__ = False  # type: ignore[attr-defined]  # not a pytest test


def spectral_radius(system: SwitchedSystem, h: ArrayLike) -> NDArray[np.float64] | float:
    """``rho(M(h))`` for one period or an array of periods (batched matrix exponentials).

    Raises
    ------
    ValueError
        If any ``h <= 0`` (message names ``h``).
    """
    scalar = np.ndim(h) == 0
    hs = _periods(h)
    out = np.empty(hs.size)
    k = system.k
    for a in range(0, hs.size, 256):
        chunk = hs[a : a + 256]
        e = expm(system.Lambda[None, :, :] * chunk[:, None, None])[:, :k, :k]
        out[a : a + chunk.size] = np.max(np.abs(np.linalg.eigvals(e)), axis=1)
    return float(out[0]) if scalar else out


@dataclass(frozen=True)
class HMaxResult:
    """Result of :func:`find_h_max`."""

    h_max: float
    """First crossing of ``rho(M(h)) = 1`` (``0`` if unstable for small ``h``, ``inf`` if none)."""
    crossings: tuple[float, ...]
    """Every crossing found on the grid, refined, ascending."""
    continuous_stable: bool
    """Whether the loop under continuous communication is Hurwitz."""
    h_grid: NDArray[np.float64] = field(repr=False)
    rho_grid: NDArray[np.float64] = field(repr=False)


def find_h_max(
    rho: Callable[[NDArray[np.float64]], NDArray[np.float64]] | SwitchedSystem,
    config: UpdatePeriodConfig | None = None,
    *,
    continuous_stable: bool | None = None,
) -> HMaxResult:
    """Maximum allowable update period: the first ``h > 0`` with ``rho(M(h)) = 1``.

    Scans ``rho`` on ``n_grid`` points of ``(0, h_hi]``, brackets every sign change of
    ``rho - 1`` and refines each with ``brentq`` (see the module docstring).

    Parameters
    ----------
    rho : callable or SwitchedSystem
        Vectorized ``h -> rho(M(h))``, or the switched system (then ``rho`` is
        :func:`spectral_radius` and stability for small ``h`` is decided from
        :meth:`SwitchedSystem.continuous_loop`).
    config : UpdatePeriodConfig, optional
        Grid and tolerance. For a switched system ``h_hi`` may not exceed
        :meth:`SwitchedSystem.reliable_h` (about 1.2 h for the CSTRs).
    continuous_stable : bool, optional
        Stability for small ``h`` when ``rho`` is a plain callable (default: ``rho`` at the first
        grid point is below 1).
    """
    cfg = UpdatePeriodConfig() if config is None else config
    if isinstance(rho, SwitchedSystem):
        system = rho
        if cfg.h_hi > system.reliable_h():
            raise ValueError(
                f"h_hi = {cfg.h_hi} exceeds the periods for which expm(Lambda h) is accurate "
                f"(h <= {system.reliable_h():.3g}, see SwitchedSystem.reliable_h)"
            )
        ev = np.linalg.eigvals(system.continuous_loop())
        continuous_stable = bool(np.max(ev.real) < 0.0)

        def fn(h: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.asarray(spectral_radius(system, h))

    else:
        fn = rho  # type: ignore[assignment]
    grid = np.linspace(0.0, cfg.h_hi, cfg.n_grid + 1)[1:]
    vals = np.asarray(fn(grid), dtype=float)
    if continuous_stable is None:
        continuous_stable = bool(vals[0] < 1.0)
    if not continuous_stable:
        return HMaxResult(0.0, (), False, grid, vals)
    g = vals - 1.0
    crossings: list[float] = []
    if g[0] >= 0.0:
        # unstable already at the first grid point although stable for h -> 0: search below it
        fine = np.geomspace(grid[0] * 1e-6, grid[0], 60)
        gf = np.asarray(fn(fine), dtype=float) - 1.0
        idx = np.nonzero((gf[:-1] < 0.0) & (gf[1:] >= 0.0))[0]
        if idx.size:
            a = int(idx[0])
            crossings.append(_refine(fn, fine[a], fine[a + 1], cfg.xtol))
        else:
            crossings.append(float(fine[0]))
    for a in np.nonzero(np.sign(g[:-1]) != np.sign(g[1:]))[0]:
        crossings.append(_refine(fn, grid[a], grid[a + 1], cfg.xtol))
    h_max = crossings[0] if crossings else np.inf
    return HMaxResult(float(h_max), tuple(crossings), True, grid, vals)


def _refine(fn: Callable, a: float, b: float, xtol: float) -> float:
    def f(h: float) -> float:
        return float(np.asarray(fn(np.array([h])))[0]) - 1.0

    fa, fb = f(a), f(b)
    if fa == 0.0:
        return float(a)
    if fb == 0.0 or np.sign(fa) == np.sign(fb):
        return float(b)
    return float(brentq(f, a, b, xtol=xtol))


# ---------------------------------------------------------------------------------------------
# the two CSTRs of section V
# ---------------------------------------------------------------------------------------------


class CSTRRecycleCase:
    """Seed 001 section V: the linearized two-CSTR plant, its design, and mismatched models.

    Parameters
    ----------
    params : CSTRRecycleParams
        True plant parameters (default: the paper's).
    controller_poles, observer_poles : tuple of tuples
        Design poles per unit (default: section V, ``(-5, -1)`` and ``(-50, -25)``).
    controller_method : {"diagonal", "place"}
        See :class:`controllers.qdc.design.QDCDesign`.
    """

    def __init__(
        self,
        params: CSTRRecycleParams = PAPER_PARAMS,
        *,
        controller_poles: tuple[tuple[float, ...], ...] = PAPER_CONTROLLER_POLES,
        observer_poles: tuple[tuple[float, ...], ...] = PAPER_OBSERVER_POLES,
        controller_method: Literal["diagonal", "place"] = "diagonal",
    ) -> None:
        self.params = params
        self.plant_nl = CSTRRecycle(params)
        self.x_s, self.u_s = self.plant_nl.unstable_steady_state()
        self.plant = LinearUnits.from_model(self.plant_nl.two_unit(self.x_s, self.u_s))
        self.design = QDCDesign(
            plant=self.plant,
            controller_poles=controller_poles,
            observer_poles=observer_poles,
            controller_method=controller_method,
        )
        self.gains = self.design.gains()
        self._models: dict[float, LinearUnits] = {}

    def model(self, delta1: float = 0.0) -> LinearUnits:
        """Linear model with ``dH1_m = (1 + delta1) dH1``, at the true operating point."""
        key = float(delta1)
        if key not in self._models:
            if key == 0.0:
                self._models[key] = self.plant
            else:
                pm = self.params.model_copy(update={"dH1": self.params.dH1 * (1.0 + key)})
                lin = CSTRRecycle(pm).two_unit(self.x_s, self.u_s)
                self._models[key] = LinearUnits.from_model(lin)
        return self._models[key]

    def with_observer_poles(self, observer_poles: tuple[tuple[float, ...], ...]) -> QDCGains:
        """Gains of the same design with other observer poles."""
        return self.design.model_copy(update={"observer_poles": observer_poles}).gains()

    def system(
        self,
        architecture: Architecture = "qdc",
        delta1: float = 0.0,
        gains: QDCGains | None = None,
    ) -> SwitchedSystem:
        """``Lambda`` for one architecture and model mismatch ``delta1``."""
        return switched_system(
            architecture, self.plant, self.gains if gains is None else gains, self.model(delta1)
        )

    def h_max(
        self,
        architecture: Architecture = "qdc",
        delta1: float = 0.0,
        config: UpdatePeriodConfig | None = None,
        gains: QDCGains | None = None,
    ) -> HMaxResult:
        """Maximum allowable update period for one architecture and ``delta1``."""
        return find_h_max(self.system(architecture, delta1, gains), config)


def rho_map(
    case: CSTRRecycleCase,
    h_values: ArrayLike,
    delta_values: ArrayLike,
    architecture: Architecture = "qdc",
) -> NDArray[np.float64]:
    """``rho(M(h))`` on a ``(delta1, h)`` grid (Fig. 2(a)-(c)); shape ``(len(delta), len(h))``."""
    hs = _periods(h_values)
    ds = np.atleast_1d(np.asarray(delta_values, dtype=float))
    return np.array([spectral_radius(case.system(architecture, d), hs) for d in ds])


def rho_curves(
    case: CSTRRecycleCase,
    h_values: ArrayLike,
    delta_values: Sequence[float],
    *,
    include_zoh: bool = True,
) -> dict[str, NDArray[np.float64]]:
    """``rho(M(h))`` against ``h`` for several ``delta1`` and the zero-order hold (Fig. 3(a)).

    Keys ``"delta1=<value>"`` and ``"zoh"`` (the hold does not depend on ``delta1``).
    """
    hs = _periods(h_values)
    out = {
        f"delta1={d:g}": np.asarray(spectral_radius(case.system("qdc", d), hs))
        for d in delta_values
    }
    if include_zoh:
        out["zoh"] = np.asarray(spectral_radius(case.system("qdc_zoh", 0.0), hs))
    return out


def rho_map_observer_pole(
    case: CSTRRecycleCase,
    lambda12_values: ArrayLike,
    delta_values: ArrayLike,
    *,
    h: float = 0.04,
    fixed_pole: float = -50.0,
    architecture: Architecture = "qdc",
) -> NDArray[np.float64]:
    """``rho(M(h))`` over ``(delta1, lambda_12)`` at fixed ``h`` (Fig. 4(a)-(b)).

    ``lambda_12`` is the second eigenvalue of ``A_1 - L_1 C_1`` (the first is ``fixed_pole``);
    ``L_2`` keeps its design. Shape ``(len(delta), len(lambda12))``. Use
    ``architecture="qdc_zoh"`` for the zero-order-hold line of Fig. 4(b).
    """
    (hh,) = _periods(h)
    lams = np.atleast_1d(np.asarray(lambda12_values, dtype=float))
    ds = np.atleast_1d(np.asarray(delta_values, dtype=float))
    out = np.empty((ds.size, lams.size))
    obs2 = case.design.observer_poles[1]
    for b, lam in enumerate(lams):
        gains = case.with_observer_poles(((fixed_pole, float(lam)), obs2))
        for a, d in enumerate(ds):
            out[a, b] = spectral_radius(case.system(architecture, d, gains), hh)
    return out
