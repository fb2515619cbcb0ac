"""EW-RLS identification of the tank and the self-tuning non-linear PI (seed 002, section 3.3).

Estimator, seed 002 eq. (16)-(19) (:class:`EWRLS`, any number of parameters)::

    e(k)    = y(k) - x(k)^T beta(k-1)                                        (17)
    K(k)    = P(k-1) x(k) / (lambda + x(k)^T P(k-1) x(k))                    (18)
    beta(k) = beta(k-1) + K(k) e(k)                                          (16)
    P(k)    = [P(k-1) - K(k) x(k)^T P(k-1)] / lambda                         (19)

with three guards the paper leaves out: an update whose denominator ``lambda + x^T P x`` is not
finite or not above ``eps`` is skipped (division by zero); ``P`` is kept symmetric; and
**covariance resetting**, ``P <- P0`` when ``trace(P)`` leaves ``[p_min, p_max]`` (``p_max``
stops the windup of ``P`` under forgetting without excitation, ``p_min`` keeps a ``lambda = 1``
estimator alert). :meth:`EWRLS.reset_covariance` resets on demand.

Tank regression (:class:`TankEstimator`)
----------------------------------------
Eq. (3a), ``dh/dt = b u - a' sqrt(h)``, is linear in ``beta = (b, a')``. Integrated over a window
``[t_j, t_k]`` of samples (trapezoidal rule for ``sqrt(h)``; the command is held between samples,
so its integral is exact)::

    y = (h_k - h_j) / (t_k - t_j)
    x = ( mean of u over the window,  -trapezoidal mean of sqrt(h) )

``t_j`` is the newest sample at least ``window`` before ``t_k`` (``window = 0``: the previous
sample, the paper's numerical derivative). The relation is exact for any window (up to the
trapezoidal error), so a longer window costs no bias; it divides the derivative's noise
(``sqrt(2) sigma / T_s`` for one interval) by the number of samples it spans and lowers the bias
that feedback of the noise into ``u`` causes (on the simulated tank with 0.5 mm noise
at 0.05 s, ``window = 0`` let the estimated ratio ``b/a'`` wander by tens of percent; the
self-tuning law's default is ``t_s / 4``). To make one prior and one threshold fit any tank, the
regression is run on relative parameters ``(b/b_0, a'/a_0)`` with regressors scaled to unit length
(normalized least squares: each sample weighs the same whatever the flow).

The forgetting factor is given per nominal sampling period ``tau_ref``; a sample ``dt`` after the
previous one is weighted with ``lambda^(dt/tau_ref)``, so the memory in time
(``tau_ref / (1 - lambda)``) does not change when the sampling period does.

Excitation, identifiability and changes of the plant
-----------------------------------------------------
At rest ``b u = a' sqrt(h)`` and ``y = 0``: every regressor points the same way and only the ratio
``b/a' = sqrt(h)/u`` is identifiable, not ``b`` and ``a'`` apart (the *scale* of ``beta``). The
information about the scale is carried by ``(dh/dt)^2``, i.e. by transients (set-point steps,
disturbances). Three mechanisms follow from this:

* **Hold at low excitation.** The estimator keeps the forgetting-weighted information matrix ``R``
  of the unit regressors and measures the excitation by ``lambda_min(R) / trace(R)`` (0 when all
  recent regressors are collinear, at most 1/2). Below ``excitation_min`` it holds: neither
  ``beta`` nor ``P`` is updated (the estimator's gain is zero), so under noise the scale does not
  random-walk and ``P`` does not wind up along it.
* **Change detection and covariance reset.** Steady-state samples are homogeneous constraints
  ``beta^T x = 0``. After a change of the plant the new steady state gives a constraint in a
  slightly different direction, and the least-squares fit of old and new constraints together is
  ``beta -> 0``: the estimates would collapse along the scale (on the simulated tank, after
  ``a'`` rose by 50 % at rest, ``b`` and ``a'`` fell to 37 % and 30 % of their new values before
  the next set-point step, which then overshot by 0.3 % instead of 4.3 %). So a sample whose
  relative prior error ``|e| / |x|`` exceeds ``change_error`` is *suspect* and not used (an
  outlier is rejected); when suspect samples persist for ``change_time`` the plant is taken to
  have changed: ``P`` is reset to ``P0`` and the derivative window restarts (no sample straddles
  the change). The estimator then learns (no suspicion) until its prior error has stayed below
  ``change_error / 2`` for ``change_time``. It starts in that learning mode, since the initial
  guesses may be far off.
  An unmeasured disturbance outflow ``q_d`` violates eq. (3a) (it is not proportional to
  ``sqrt(h)``). In the section 4.1 scenario with its alternating draw-off steps, 0.2 mm/s (4 % of
  the outflow at 100 mm) moved the estimates by up to 6 %, 0.5 mm/s by up to 21 %, and 1 mm/s made
  them wander (4 change detections, ``b`` down to 0.22); the loop stayed stable (overshoots 2.6 to
  6.5 %) but the design is then not kept. An incremental (velocity-form) regression, which
  cancels constant draw-offs, was tried and not kept: it identified ``a'`` only to about 5 %.
* **Projection.** Estimates are clipped to ``[guess / param_range, guess * param_range]``.

With measurement noise, the ratio ``b/a'`` stays accurate even when ``b`` and ``a'`` are not (they
then move together), and a loop with the right ratio and a wrong scale only has its loop gain
scaled, which keeps it stable (``tests/unit/test_ewrls.py`` has the figures).

Self-tuning controller (:class:`SelfTuningNLPI`, ``type: stnlpi``)
------------------------------------------------------------------
The indirect scheme of Fig. 4: at every sample the estimator is updated with the level and the
command held over the last interval, and, when it updated (excitation high enough), the
non-linear PI's gains are redesigned from the estimates by eq. (10)-(12)
(:meth:`controllers.nlpi.NonlinearPI.set_model`); otherwise the gains are held. Because the PI's
integral is the integral of the error, a redesign keeps the command at rest continuous except for
the (correct) change of the linearizing term. The estimator assumes the command the law returns is
applied until the next sample (no actuation delay); with delays the regression is misaligned.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike
from pydantic import Field

from controllers.nlpi import (
    NonlinearPI,
    TwoDofOptions,
    _plant_param,
    _SpecConfig,
    design_targets,
)

__all__ = ["EWRLS", "TankEstimator", "STNLPIConfig", "SelfTuningNLPI"]


class EWRLS:
    """Exponentially weighted recursive least squares, seed 002 eq. (16)-(19).

    Parameters
    ----------
    beta0 : array_like
        Initial estimate.
    p0 : float or array_like
        Initial covariance: a scalar (times identity) or a matrix; also the reset value.
    forgetting : float
        ``lambda`` in ``(0, 1]``.
    p_min, p_max : float, optional
        Reset ``P`` to ``P0`` when its trace falls below ``p_min`` or rises above ``p_max``.
    eps : float
        Smallest accepted denominator of eq. (18).
    """

    def __init__(
        self,
        beta0: ArrayLike,
        p0: float | ArrayLike,
        forgetting: float = 1.0,
        *,
        p_min: float | None = None,
        p_max: float | None = None,
        eps: float = 1e-12,
    ) -> None:
        if not 0.0 < forgetting <= 1.0:
            raise ValueError(f"forgetting={forgetting} must be in (0, 1]")
        beta = np.array(beta0, dtype=float).reshape(-1)
        n = beta.size
        p = np.asarray(p0, dtype=float)
        P0 = p * np.eye(n) if p.ndim == 0 else p.reshape(n, n).copy()
        if not (np.all(np.isfinite(P0)) and np.all(np.linalg.eigvalsh(0.5 * (P0 + P0.T)) > 0)):
            raise ValueError("p0 must be positive (a positive-definite matrix)")
        self.forgetting = float(forgetting)
        self.p_min = p_min
        self.p_max = p_max
        self.eps = float(eps)
        self._beta0 = beta.copy()
        self._P0 = P0
        self.reset()

    def reset(self) -> None:
        """Back to the initial estimate and covariance."""
        self.beta = self._beta0.copy()
        self.P = self._P0.copy()
        self.n_updates = 0
        self.n_skipped = 0
        self.n_resets = 0

    def reset_covariance(self, p0: float | ArrayLike | None = None) -> None:
        """Set ``P`` to ``P0`` (or to ``p0``): the estimator becomes alert again."""
        if p0 is None:
            self.P = self._P0.copy()
        else:
            p = np.asarray(p0, dtype=float)
            self.P = p * np.eye(self.beta.size) if p.ndim == 0 else p.copy()
        self.n_resets += 1

    def update(self, x: ArrayLike, y: float, *, forgetting: float | None = None) -> float:
        """One step of eq. (16)-(19) with regressor ``x`` and measurement ``y``.

        Parameters
        ----------
        x : array_like
            Regressor ``x(k)``.
        y : float
            Measurement ``y(k)``.
        forgetting : float, optional
            ``lambda`` for this step only (default: the configured one).

        Returns
        -------
        float
            The prior error ``e(k)`` (eq. (17)); NaN if the step was skipped.
        """
        lam = self.forgetting if forgetting is None else forgetting
        xv = np.asarray(x, dtype=float).reshape(-1)
        if not (np.all(np.isfinite(xv)) and math.isfinite(y)):
            self.n_skipped += 1  # guard: no NaN or infinity into the state
            return math.nan
        e = float(y) - float(xv @ self.beta)  # (17)
        px = self.P @ xv
        denom = lam + float(xv @ px)
        if not (math.isfinite(denom) and denom > self.eps):
            self.n_skipped += 1  # guard: no division by (near) zero
            return math.nan
        k = px / denom  # (18)
        self.beta = self.beta + k * e  # (16)
        P = (self.P - np.outer(k, px)) / lam  # (19); K x^T P = k (P x)^T as P is symmetric
        self.P = 0.5 * (P + P.T)
        tr = float(np.trace(self.P))
        if (self.p_max is not None and tr > self.p_max) or (
            self.p_min is not None and tr < self.p_min
        ):
            self.reset_covariance()
        self.n_updates += 1
        return e


class TankEstimator:
    """EW-RLS of ``(b, a')`` of seed 002 eq. (3a) from sampled levels and held commands.

    Parameters
    ----------
    b0, a_prime0 : float
        Initial guesses (also the scales of the relative parameters and the projection's centre).
    forgetting : float
        ``lambda`` in ``(0, 1]`` per ``tau_ref`` of time.
    tau_ref : float
        Nominal sampling period the forgetting factor refers to.
    p0 : float
        Initial (and reset) covariance of the relative parameters, ``P0 = p0 I``.
    p_min, p_max : float, optional
        Covariance-reset bounds on ``trace(P)``.
    window : float
        Span of the numerical derivative (0: one sample interval).
    excitation_min : float
        Hold (no update) while ``lambda_min(R)/trace(R)`` is below this.
    change_error : float, optional
        Relative prior error above which a sample is suspect (None: no change detection).
    change_time : float
        How long suspect samples must persist to be taken for a change of the plant.
    param_range : float
        Estimates are kept within ``[guess / param_range, guess * param_range]``.
    """

    def __init__(
        self,
        b0: float,
        a_prime0: float,
        *,
        forgetting: float = 1.0,
        tau_ref: float = 1.0,
        p0: float = 100.0,
        p_min: float | None = None,
        p_max: float | None = None,
        window: float = 0.0,
        excitation_min: float = 1e-3,
        change_error: float | None = None,
        change_time: float = 0.0,
        param_range: float = 10.0,
    ) -> None:
        if not (b0 > 0.0 and a_prime0 > 0.0):
            raise ValueError(f"initial guesses b0={b0}, a_prime0={a_prime0} must be > 0")
        if not tau_ref > 0.0:
            raise ValueError(f"tau_ref={tau_ref} must be > 0")
        if not param_range > 1.0:
            raise ValueError(f"param_range={param_range} must be > 1")
        if not (window >= 0.0 and change_time >= 0.0):
            raise ValueError(f"window={window} and change_time={change_time} must be >= 0")
        self.scale = np.array((b0, a_prime0), dtype=float)
        self.rls = EWRLS((1.0, 1.0), p0, forgetting, p_min=p_min, p_max=p_max)
        self.tau_ref = float(tau_ref)
        self.window = float(window)
        self.excitation_min = float(excitation_min)
        self.change_error = change_error
        self.change_time = float(change_time)
        self._lo = 1.0 / param_range
        self._hi = float(param_range)
        self.reset()

    def reset(self) -> None:
        """Forget the data and go back to the initial guesses."""
        self.rls.reset()
        self.R = np.zeros((2, 2))
        self.excitation = 0.0
        self.error = math.nan
        self.updated = False
        self.learning = True
        self.n_changes = 0
        self._suspect = 0.0
        self._good = 0.0
        # samples (t, h, integral of u, integral of sqrt(h)) over the current window
        self._buf: deque[tuple[float, float, float, float]] = deque()
        self._sqrt_prev = 0.0

    @property
    def b(self) -> float:
        """Estimate of ``b``."""
        return float(self.rls.beta[0] * self.scale[0])

    @property
    def a_prime(self) -> float:
        """Estimate of ``a'``."""
        return float(self.rls.beta[1] * self.scale[1])

    def _restart(self, t: float, h: float, sq: float) -> None:
        self._buf.clear()
        self._buf.append((t, h, 0.0, 0.0))
        self._sqrt_prev = sq

    def update(self, t: float, h: float, u_held: float | None) -> bool:
        """Add the sample ``h`` at ``t``; ``u_held`` is the command held since the previous sample.

        Returns
        -------
        bool
            Whether the estimates were updated (enough data, enough excitation, no suspect error).
        """
        self.updated = False
        sq = math.sqrt(h if h > 0.0 else 0.0)
        if not self._buf or u_held is None:
            self._restart(t, h, sq)
            return False
        t_prev, _, cu_prev, cs_prev = self._buf[-1]
        dt = t - t_prev
        if not dt > 0.0:
            return False  # a repeated sample carries no derivative (and no division by zero)
        cu = cu_prev + u_held * dt
        cs = cs_prev + 0.5 * (sq + self._sqrt_prev) * dt
        self._sqrt_prev = sq
        self._buf.append((t, h, cu, cs))
        while len(self._buf) > 2 and t - self._buf[1][0] >= self.window:
            self._buf.popleft()  # keep the newest sample at least `window` before t
        t_j, h_j, cu_j, cs_j = self._buf[0]
        span = t - t_j
        if span < self.window or span <= 0.0:
            return False
        y = (h - h_j) / span
        x = np.array(((cu - cu_j) / span * self.scale[0], -(cs - cs_j) / span * self.scale[1]))
        norm = math.hypot(x[0], x[1])
        if not (norm > 0.0 and math.isfinite(norm) and math.isfinite(y)):
            return False  # empty tank and pump off: no information (and no division by zero)
        x /= norm
        y /= norm
        lam = self.rls.forgetting ** (dt / self.tau_ref)
        self.R = lam * self.R + np.outer(x, x)
        self.excitation = float(np.linalg.eigvalsh(self.R)[0] / (self.R[0, 0] + self.R[1, 1]))
        e = y - float(x @ self.rls.beta)
        self.error = e
        if self.change_error is not None:
            if not self.learning and abs(e) > self.change_error:
                self._suspect += dt  # hold: an outlier, or the plant changed
                if self._suspect >= self.change_time:
                    # a change: forget the covariance and the samples that straddle it
                    self.rls.reset_covariance()
                    self.learning = True
                    self._suspect = self._good = 0.0
                    self.n_changes += 1
                    self._restart(t, h, sq)
                return False
            self._suspect = 0.0
            if self.learning:
                self._good = self._good + dt if abs(e) < 0.5 * self.change_error else 0.0
                if self._good >= self.change_time:
                    self.learning = False
        if self.excitation < self.excitation_min:
            return False  # hold: too little excitation to trust
        if math.isnan(self.rls.update(x, y, forgetting=lam)):
            return False
        np.clip(self.rls.beta, self._lo, self._hi, out=self.rls.beta)
        self.updated = True
        return True


class STNLPIConfig(_SpecConfig):
    """Self-tuning non-linear PI (seed 002 section 3.3, Fig. 4): EW-RLS + eq. (10)-(12)."""

    type: Literal["stnlpi"] = "stnlpi"
    b0: float | None = Field(default=None, gt=0, description="initial guess of b; None: plant's")
    a_prime0: float | None = Field(
        default=None, gt=0, description="initial guess of a'; None: the plant's"
    )
    forgetting: float | None = Field(
        default=None,
        gt=0,
        le=1,
        description="EW-RLS lambda per nominal sampling period; None: a memory of two settling "
        "times, lambda = exp(-tau_s / (2 settling_time))",
    )
    p0: float = Field(default=100.0, gt=0, description="initial covariance of (b/b0, a'/a0)")
    p_min: float | None = Field(default=None, gt=0, description="reset P when trace(P) < p_min")
    p_max: float | None = Field(default=1e4, gt=0, description="reset P when trace(P) > p_max")
    derivative_window: float | None = Field(
        default=None, ge=0, description="span of the numerical derivative; None: settling_time/4"
    )
    excitation_min: float = Field(
        default=1e-3, ge=0, lt=0.5, description="hold estimates and gains below this excitation"
    )
    change_error: float | None = Field(
        default=0.1,
        gt=0,
        description="relative prior error that makes a sample suspect; None: no change detection",
    )
    change_time: float | None = Field(
        default=None,
        ge=0,
        description="persistence of suspect samples that is taken for a "
        "change of the plant (covariance reset); None: settling_time/10",
    )
    param_range: float = Field(
        default=10.0, gt=1, description="estimates kept within [guess/range, guess*range]"
    )


class SelfTuningNLPI:
    """Self-tuning (indirect adaptive) non-linear PI of seed 002 section 3.3 and Fig. 4.

    Parameters
    ----------
    pi : NonlinearPI
        The law; its gains are redesigned from the estimates.
    estimator : TankEstimator
        The EW-RLS estimator of ``(b, a')``.
    """

    def __init__(self, pi: NonlinearPI, estimator: TankEstimator) -> None:
        self.pi = pi
        self.estimator = estimator
        self._b0 = pi.b
        self._a0 = pi.a_prime
        self.reset()

    @classmethod
    def from_config(
        cls, config: STNLPIConfig, *, u_bar: float = 0.0, plant: Any = None, tau_s: float = 1.0
    ) -> SelfTuningNLPI:
        """Build from a configuration; guesses and limits default to the plant's; the forgetting
        factor refers to ``tau_s``. ``u_bar`` is not used."""
        b0 = config.b0 if config.b0 is not None else _plant_param(plant, "b", "stnlpi")
        a0 = (
            config.a_prime0
            if config.a_prime0 is not None
            else _plant_param(plant, "a_prime", "stnlpi")
        )
        zeta, omega_n = design_targets(config)
        options = TwoDofOptions.of(config, plant)
        pi = NonlinearPI(zeta=zeta, omega_n=omega_n, b=b0, a_prime=a0, options=options)
        tenth = config.settling_time / 10.0
        est = TankEstimator(
            b0,
            a0,
            forgetting=(
                math.exp(-tau_s / (2.0 * config.settling_time))
                if config.forgetting is None
                else config.forgetting
            ),
            tau_ref=tau_s,
            p0=config.p0,
            p_min=config.p_min,
            p_max=config.p_max,
            window=(
                config.settling_time / 4.0
                if config.derivative_window is None
                else config.derivative_window
            ),
            excitation_min=config.excitation_min,
            change_error=config.change_error,
            change_time=tenth if config.change_time is None else config.change_time,
            param_range=config.param_range,
        )
        return cls(pi, est)

    def resume(self, t: float) -> None:
        """The loop was open until ``t``: the PI integrates from ``t`` on re-closing."""
        self.pi.resume(t)

    def reset(self) -> None:
        """Back to the initial guesses; forget the integral and the data."""
        self.estimator.reset()
        self.pi.set_model(self._b0, self._a0)
        self.pi.reset()
        self._u_prev: float | None = None

    @property
    def b(self) -> float:
        """``b`` the gains are currently designed with."""
        return self.pi.b

    @property
    def a_prime(self) -> float:
        """``a'`` the gains are currently designed with."""
        return self.pi.a_prime

    def step(self, t: float, y: float, r: float) -> float:
        """Estimate with the sample, redesign if trusted (eq. (10)-(12)), then one PI execution."""
        est = self.estimator
        if est.update(t, y, self._u_prev):
            self.pi.set_model(est.b, est.a_prime)
        u = self.pi.step(t, y, r)
        self._u_prev = u
        return u
