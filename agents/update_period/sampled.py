"""The update-period test for the loop as the platform runs it: sampled measurements, held moves.

Seed 001's test (eq. (8), :mod:`agents.update_period.analysis`) and its delayed extension
(:mod:`agents.update_period.delay`) take the local measurement and control as continuous. On the
platform (:mod:`controllers.qdc.law`, :mod:`runtime.direct`, :mod:`controllers.node`) each unit's
temperatures are sampled every ``tau_s`` and its moves held, and the estimates are exchanged every
``h = N tau_s``. This module builds the exact linear sampled-data model of that loop.

Loop (deviation variables; plant ``(A, B, C)`` from
:meth:`controllers.qdc.design.LinearUnits.full`, controller ``F, G, H`` the units' blocks
:meth:`controllers.qdc.network.QDCNetwork.local` of eq. (4))::

    dx/dt = A x + B u_held          u_held = H z(t_k^+)       (the plant holds the move)
    dz/dt = F z + G y_held          y_held = C x(t_k)         (the law holds the sample)

between sample instants ``t_k = k tau_s``, both propagated exactly (``expm`` of the block matrix
on ``(x, z, y_held, u_held)``), so one sample period maps the state at ``t_k^+`` as
``w(t_{k+1}^-) = T w(t_k^+)`` on ``w = (x, z)``.

Order at one instant (:mod:`runtime.direct` step 2 and 4, the controller node's timers and
rounds): every link due at ``t`` is sent first (``transmit``: the sender's ``xbar_j(t)``, before
anything is received or executed there), then the controller's receipts due at ``t`` are applied
(``receive``: ``xhat_j^i <- xbar_j``; delayed ones and zero-delay ones alike come before the
execution on that instant's samples), then the sample is taken in and the move computed from the
reset state (``step``) and applied from ``t`` on. Links start at ``t = 0`` with the samples, so
every send instant is a sample instant. With a link delay of ``D`` sample periods, unit ``j``'s
estimate sent at ``t_s`` resets ``xhat_j^i`` at ``t_s + D tau_s``: the values are captured at the
send instant and carried in the state until then. Over one update period ``h = N tau_s`` (from
just before the events of a send instant to just before those of the next), with ``m = D // N``
messages in flight at a send instant and the one sent ``m`` periods ago landing ``r = D % N``
samples into the period::

    M_{N,D} = Shift T^(N - r) Del T^r Cap

on ``(x, z, c_1, ..., c_m)`` (``c_k`` the estimates sent ``k`` periods ago): ``Cap`` captures
``c_0 = xbar`` (all units' estimates), ``Del`` resets every model ``xhat_j^i`` from the oldest
capture ``c_m``, ``Shift`` ages the captures by one period. For ``D = 0`` it is ``T^N Rz`` on
``(x, z)`` with ``Rz`` the instant reset of :class:`controllers.qdc.network.QDCNetwork`. The
sampled loop is exponentially stable iff ``rho(M_{N,D}) < 1``, the same argument as eq. (8): the
state at the send instants evolves by a constant matrix.

As ``tau_s -> 0`` (``N -> inf`` with ``N tau_s = h``) ``T^N -> expm(Acl h)`` of
:func:`controllers.qdc.model.closed_loop_matrices` and ``M_{N,0}`` tends to
``expm(Acl h) Rcl``, whose non-zero spectrum is that of the paper's ``M(h)`` (eq. (8)): the
sampled ``h_max`` tends to the paper's (0.04312 h with models, 0.04198 h with the hold, for the
CSTRs of section V). At the section's observer poles (-50 1/h) the difference is first order in
``tau_s``.

:func:`find_h_max_sampled` scans the periods ``N tau_s``, ``N = 1, 2, ...``: ``h_max`` is the
largest multiple of ``tau_s`` such that every shorter multiple is stabilizing (first loss of
stability); every change of stability on the grid is reported.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import block_diag, expm

from controllers.qdc.design import LinearUnits
from controllers.qdc.network import QDCNetwork

__all__ = ["SampledQDC", "SampledHMax", "find_h_max_sampled", "h_max_vs_tau_s"]


def _check_tau_s(tau_s: float) -> float:
    if isinstance(tau_s, bool) or not isinstance(tau_s, numbers.Real):
        raise ValueError(f"tau_s: the sampling period must be a number (hours), got {tau_s!r}")
    if not (np.isfinite(tau_s) and tau_s > 0.0):
        raise ValueError(
            f"tau_s: the sampling period must be finite and > 0 (hours), got {tau_s!r}"
        )
    return float(tau_s)


def _check_int(name: str, value: int, low: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(
            f"{name}: {what} must be an integer number of sample periods, got {value!r}"
        )
    if value < low:
        raise ValueError(f"{name}: {what} must be >= {low} sample periods, got {value}")
    return int(value)


class SampledQDC:
    """The platform's quasi-decentralized loop as an exact linear sampled-data system.

    Build it with :meth:`from_law_parts`; see the module docstring for the model.

    Parameters
    ----------
    A, B, C : ndarray
        The true plant (deviation variables).
    F, G, H : ndarray
        The stacked local controllers (``dz/dt = F z + G y``, ``u = H z``).
    capture : ndarray
        ``S`` with ``c = S z`` the transmitted estimates of all units, stacked.
    keep, place : ndarray
        The update of the models from received estimates: ``z <- keep z + place c``.
    tau_s : float
        Sampling period of the measurements (and of the moves), hours.

    Raises
    ------
    ValueError
        If ``tau_s`` is not finite and > 0, or the shapes do not fit together.
    """

    def __init__(
        self,
        A: NDArray[np.float64],
        B: NDArray[np.float64],
        C: NDArray[np.float64],
        F: NDArray[np.float64],
        G: NDArray[np.float64],
        H: NDArray[np.float64],
        capture: NDArray[np.float64],
        keep: NDArray[np.float64],
        place: NDArray[np.float64],
        tau_s: float,
    ) -> None:
        self.tau_s = _check_tau_s(tau_s)
        A, B, C, F, G, H = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (A, B, C, F, G, H))
        nx, nu, ny, nz = A.shape[0], B.shape[1], C.shape[0], F.shape[0]
        capture, keep, place = (np.asarray(a, dtype=float) for a in (capture, keep, place))
        nc = capture.shape[0]
        expected = {
            "A": (A, (nx, nx)),
            "B": (B, (nx, nu)),
            "C": (C, (ny, nx)),
            "F": (F, (nz, nz)),
            "G": (G, (nz, ny)),
            "H": (H, (nu, nz)),
            "capture": (capture, (nc, nz)),
            "keep": (keep, (nz, nz)),
            "place": (place, (nz, nc)),
        }
        for name, (arr, shape) in expected.items():
            if arr.shape != shape:
                raise ValueError(f"SampledQDC: {name} has shape {arr.shape}, expected {shape}")
        self.A, self.B, self.C, self.F, self.G, self.H = A, B, C, F, G, H
        self.capture, self.keep, self.place = capture, keep, place
        self.nx, self.nz, self.nc = nx, nz, nc
        n = nx + nz
        big = np.zeros((n + ny + nu, n + ny + nu))
        big[:nx, :nx] = A
        big[:nx, n + ny :] = B
        big[nx:n, nx:n] = F
        big[nx:n, n : n + ny] = G
        e = expm(big * self.tau_s)[:n]
        hold = np.zeros((ny + nu, n))
        hold[:ny, :nx] = C  # y_held = C x(t_k)
        hold[ny:, nx:] = H  # u_held = H z(t_k^+)
        self.T: NDArray[np.float64] = e[:, :n] + e[:, n:] @ hold
        """One sample period on ``w = (x, z)``: ``w(t_{k+1}^-) = T w(t_k^+)``."""
        self._powers: list[NDArray[np.float64]] = [np.eye(n)]

    @classmethod
    def from_law_parts(cls, plant: LinearUnits, network: QDCNetwork, tau_s: float) -> SampledQDC:
        """The loop of ``network``'s local controllers (what each unit's ``qdc`` law runs,
        :meth:`controllers.qdc.network.QDCNetwork.local`) around the true plant ``plant``.

        Parameters
        ----------
        plant : LinearUnits
            The true linearization (for the platform's laws, ``QDCLaw.plant_units``).
        network : QDCNetwork
            The analysed controller (output feedback, models or hold, possibly mismatched).
        tau_s : float
            Sampling period of the temperatures, hours.

        Raises
        ------
        ValueError
            If ``tau_s <= 0``, ``network`` is not the output-feedback structure, or its units'
            blocks do not make up its ``F, G, H`` (message names what).
        """
        tau_s = _check_tau_s(tau_s)
        if not isinstance(network, QDCNetwork):
            raise ValueError(f"network: expected a QDCNetwork, got {type(network).__name__}")
        locals_ = [network.local(i) for i in range(plant.n)]
        F = block_diag(*(loc.F for loc in locals_))
        G = block_diag(*(loc.G for loc in locals_))
        H = block_diag(*(loc.H for loc in locals_))
        for name, mine, theirs in (("F", F, network.F), ("G", G, network.G), ("H", H, network.H)):
            if mine.shape != theirs.shape or not np.array_equal(mine, theirs):
                raise ValueError(f"network: the units' local blocks do not make up its {name}")
        nz = F.shape[0]
        p = plant.p
        c_off = np.concatenate([[0], np.cumsum(p)]).astype(int)
        capture = np.zeros((int(c_off[-1]), nz))
        keep = np.eye(nz)
        place = np.zeros((nz, int(c_off[-1])))
        z_off = 0
        for i, loc in enumerate(locals_):
            xb = slice(z_off + loc.xbar.start, z_off + loc.xbar.stop)
            capture[c_off[i] : c_off[i + 1], xb] = np.eye(p[i])
            for j, sl in loc.xhat.items():
                rows = slice(z_off + sl.start, z_off + sl.stop)
                keep[rows, rows] = 0.0
                place[rows, c_off[j] : c_off[j + 1]] = np.eye(p[j])
            z_off += loc.nz
        A, B, C = plant.full()
        return cls(A, B, C, F, G, H, capture, keep, place, tau_s)

    def with_tau_s(self, tau_s: float) -> SampledQDC:
        """The same loop sampled every ``tau_s``."""
        return SampledQDC(
            self.A, self.B, self.C, self.F, self.G, self.H,
            self.capture, self.keep, self.place, tau_s,
        )  # fmt: skip

    def _power(self, k: int) -> NDArray[np.float64]:
        while len(self._powers) <= k:
            self._powers.append(self.T @ self._powers[-1])
        return self._powers[k]

    def monodromy(self, n_update: int, n_delay: int = 0) -> NDArray[np.float64]:
        """``M_{N,D}``: the state from one send instant (before its events) to the next.

        Parameters
        ----------
        n_update : int
            ``N``: the update period ``h = N tau_s`` in sample periods (>= 1).
        n_delay : int
            ``D``: the links' delay in sample periods (>= 0; 0 is the same instant).

        Returns
        -------
        ndarray
            Square, on ``(x, z, c_1, ..., c_m)``, ``m = D // N`` (just ``(x, z)`` for ``D < N``).

        Raises
        ------
        ValueError
            If ``n_update < 1`` or ``n_delay < 0`` (message names the argument).
        """
        N = _check_int("n_update", n_update, 1, "the update period")
        D = _check_int("n_delay", n_delay, 0, "the link delay")
        m, r = divmod(D, N)
        n, nc = self.nx + self.nz, self.nc
        z = slice(self.nx, n)
        size = n + m * nc
        # Cap: (x, z, c_1..c_m) -> (x, z, c_0, c_1..c_m), c_0 = S z
        cap = np.zeros((size + nc, size))
        cap[:n, :n] = np.eye(n)
        cap[n : n + nc, z] = self.capture
        cap[n + nc :, n:] = np.eye(m * nc)
        # Del: z <- keep z + place c_m (the oldest capture, the last slot)
        dl = np.eye(size + nc)
        dl[z, z] = self.keep
        dl[z, size:] = self.place
        flow = np.eye(size + nc)
        flow[:n, :n] = self._power(N - r)
        before = np.eye(size + nc)
        before[:n, :n] = self._power(r)
        full = flow @ dl @ before @ cap
        return full[:size]  # Shift: c_m is used; c_0..c_{m-1} become c_1..c_m

    def spectral_radius(self, n_update: int, n_delay: int = 0) -> float:
        """``rho(M_{N,D})``: the loop is exponentially stable iff it is below 1.

        Raises
        ------
        ValueError
            If ``n_update < 1`` or ``n_delay < 0`` (message names the argument).
        """
        return float(np.max(np.abs(np.linalg.eigvals(self.monodromy(n_update, n_delay)))))


@dataclass(frozen=True)
class SampledHMax:
    """Result of :func:`find_h_max_sampled` (periods in hours, counts in sample periods)."""

    tau_s: float
    n_delay: int
    n_max: int
    """Largest ``N`` with every ``N' <= N`` stabilizing (0 if ``N = 1`` is not)."""
    h_max: float
    """``n_max * tau_s``."""
    crossings: tuple[float, ...]
    """Every change of stability on the grid, ``rho = 1`` interpolated linearly in ``N`` between
    neighbouring multiples, as periods (hours), ascending."""
    n_grid: NDArray[np.int64] = field(repr=False)
    rho_grid: NDArray[np.float64] = field(repr=False)

    @property
    def bounded(self) -> bool:
        """Whether stability was lost on the scanned grid (else ``n_max`` is the grid's end)."""
        return bool(self.n_max < self.n_grid[-1])


def find_h_max_sampled(system: SampledQDC, *, n_delay: int = 0, h_hi: float = 0.2) -> SampledHMax:
    """The largest stabilizing update period on the grid ``N tau_s``, ``N = 1, 2, ...``.

    Parameters
    ----------
    system : SampledQDC
        The sampled loop (its ``tau_s`` fixes the grid).
    n_delay : int
        Link delay in sample periods (>= 0).
    h_hi : float
        Scan up to ``N tau_s <= h_hi`` (hours; at least one period).

    Returns
    -------
    SampledHMax
        ``h_max`` at the first loss of stability, every crossing, and ``rho`` on the grid.

    Raises
    ------
    ValueError
        If ``n_delay < 0`` or ``h_hi`` is not finite and > 0.
    """
    D = _check_int("n_delay", n_delay, 0, "the link delay")
    if not (np.isfinite(h_hi) and h_hi > 0.0):
        raise ValueError(f"h_hi: must be finite and > 0 (hours), got {h_hi!r}")
    n_hi = max(1, int(np.floor(h_hi / system.tau_s + 1e-9)))
    ns = np.arange(1, n_hi + 1)
    rho = np.array([system.spectral_radius(int(k), D) for k in ns])
    stable = rho < 1.0
    n_max = int(np.argmin(stable)) if not stable.all() else n_hi
    crossings = []
    for a in np.nonzero(stable[:-1] != stable[1:])[0]:
        f = (1.0 - rho[a]) / (rho[a + 1] - rho[a])
        crossings.append(float((ns[a] + f) * system.tau_s))
    return SampledHMax(
        tau_s=system.tau_s,
        n_delay=D,
        n_max=n_max,
        h_max=n_max * system.tau_s,
        crossings=tuple(crossings),
        n_grid=ns,
        rho_grid=rho,
    )


def h_max_vs_tau_s(
    plant: LinearUnits,
    network: QDCNetwork,
    tau_s_values: Sequence[float],
    *,
    n_delay: int = 0,
    h_hi: float = 0.2,
) -> list[SampledHMax]:
    """:func:`find_h_max_sampled` for each sampling period (the bench's table).

    Raises
    ------
    ValueError
        If a ``tau_s`` is not finite and > 0 or ``n_delay < 0``.
    """
    return [
        find_h_max_sampled(
            SampledQDC.from_law_parts(plant, network, tau_s), n_delay=n_delay, h_hi=h_hi
        )
        for tau_s in tau_s_values
    ]
