"""A continuous plant seen through a zero-order hold with an input delay, exactly discretised.

A sampled loop on the platform: the sensor samples ``y`` at ``t_k = k h``; the sample reaches the
controller ``tau_d`` later and the move ``u_k`` computed from it is held from ``t_k + tau_d`` until
the next move (DESIGN section 3's worked timeline). With ``tau_d = l h + theta``,
``0 <= theta < h``, the input over ``[t_k, t_{k+1})`` is ``u_{k-l-1}`` until ``t_k + theta`` and
``u_{k-l}`` after, so (Astrom & Wittenmark, *Computer-Controlled Systems*, section 2.3, the
sampled system with a time delay)::

    x_{k+1} = Phi x_k + Gamma0 u_{k-l} + Gamma1 u_{k-l-1}
    Phi    = e^{A h}
    Gamma0 = int_0^{h - theta} e^{A s} ds B
    Gamma1 = e^{A (h - theta)} int_0^{theta} e^{A s} ds B

and the delayed inputs become states. Seed 000's fast method (:mod:`agents.wncsca.fast`) uses
the same two pieces per period; this module gives them as a ``control.StateSpace`` for
python-control.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

if TYPE_CHECKING:
    import control

__all__ = ["zoh_with_delay", "sampled_with_delay"]


def _hold(A: NDArray[np.float64], B: NDArray[np.float64], t: float) -> tuple[NDArray, NDArray]:
    """``(e^{A t}, int_0^t e^{A s} ds B)`` from one block exponential."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    E = scipy.linalg.expm(M * t)
    return E[:n, :n], E[:n, n:]


def zoh_with_delay(
    A: NDArray[np.float64], B: NDArray[np.float64], h: float, tau_d: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], int]:
    """``(Phi, Gamma0, Gamma1, l)`` of the module docstring's equation for period ``h`` and
    delay ``tau_d`` (``Gamma1`` is zero when the delay is a whole number of periods).

    Raises
    ------
    ValueError
        If ``h <= 0`` or ``tau_d < 0``.
    """
    if not h > 0.0:
        raise ValueError(f"the sampling period must be > 0, got {h}")
    if not tau_d >= 0.0:
        raise ValueError(f"the delay must be >= 0, got {tau_d}")
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    whole = int(np.floor(tau_d / h + 1e-12))
    theta = max(tau_d - whole * h, 0.0)
    if theta < 1e-12 * h:
        theta = 0.0
    Phi, _ = _hold(A, B, h)
    E0, Gamma0 = _hold(A, B, h - theta)
    _, G_theta = _hold(A, B, theta)
    Gamma1 = E0 @ G_theta
    return Phi, Gamma0, Gamma1, whole


def sampled_with_delay(sys: control.StateSpace, h: float, tau_d: float) -> control.StateSpace:
    """The discrete system (``dt = h``) from the held moves ``u_k`` to the samples ``y_k`` of the
    continuous ``sys`` (no feedthrough), every input delayed by ``tau_d``.

    Its states are ``sys``'s, then the moves still in flight (``u_{k-1}``, ... ``u_{k-m}``, named
    ``<input>[k-j]``; ``m = l + 1`` when ``theta > 0``, else ``l``); inputs and outputs keep
    ``sys``'s names.
    """
    import control

    if not sys.isctime():
        raise ValueError("sampled_with_delay needs a continuous-time system")
    A, B, C = (np.asarray(sys.A, float), np.asarray(sys.B, float), np.asarray(sys.C, float))
    if np.any(np.asarray(sys.D) != 0.0):
        raise ValueError("sampled_with_delay needs a system without feedthrough (D = 0)")
    Phi, G0, G1, whole = zoh_with_delay(A, B, h, tau_d)
    n, nu = B.shape
    m = whole + 1 if np.any(G1) else whole
    N = n + m * nu
    Ad = np.zeros((N, N))
    Bd = np.zeros((N, nu))
    Ad[:n, :n] = Phi

    def feed(j: int, gain: NDArray[np.float64]) -> None:
        """``x_{k+1} += gain u_{k-j}``: the input itself (j = 0) or the j-th move in flight."""
        if j == 0:
            Bd[:n] += gain
        else:
            Ad[:n, n + (j - 1) * nu : n + j * nu] += gain

    feed(whole, G0)
    if m > whole:
        feed(whole + 1, G1)
    if m:  # shift register: u_{k-1} <- u_k, u_{k-j-1} <- u_{k-j}
        Bd[n : n + nu] = np.eye(nu)
        for j in range(1, m):
            Ad[n + j * nu : n + (j + 1) * nu, n + (j - 1) * nu : n + j * nu] = np.eye(nu)
    Cd = np.zeros((C.shape[0], N))
    Cd[:, :n] = C
    states = list(sys.state_labels) + [
        f"{u}[k-{j}]" for j in range(1, m + 1) for u in sys.input_labels
    ]
    return control.ss(
        Ad,
        Bd,
        Cd,
        np.zeros((C.shape[0], nu)),
        h,
        states=states,
        inputs=list(sys.input_labels),
        outputs=list(sys.output_labels),
    )
