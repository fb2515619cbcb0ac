"""Detection and characterisation of sustained oscillations in a loop's routine data.

The test is the autocorrelation-function (ACF) regularity test of Thornhill, Huang and Zhang
(2003), "Detection of multiple oscillations in control loops", J. Process Control 13(1), 91-100:
an oscillation makes the ACF of the data oscillate with the same period, and its zero crossings
come at regular intervals. With the crossings ``z_0 < z_1 < ...`` of the ACF (linear
interpolation between lags), the period estimates are ``T_i = z_(i+2) - z_i`` (two half
periods), and the oscillation is *regular* when::

    r = mean(T) / (3 std(T)) > 1                                           (Thornhill 2003)

Two additions make the verdict one a control engineer can act on:

* only ACF lobes that stand out of the noise count: the crossings are taken while the ACF's
  extremum between two of them exceeds ``significance / sqrt(N)`` (the standard deviation of a
  white-noise ACF is ``1/sqrt(N)``), at most ``max_crossings`` of them;
* *sustained* (a limit cycle, e.g. valve stiction) is told from *decaying* (an underdamped but
  stable loop, whose ACF is a damped cosine with equally regular crossings) by the ratio of the
  ACF lobes one period apart, ``decay = (|rho_(k+2)| / |rho_k|)`` (geometric mean): near 1 for a
  limit cycle (``1 - T/N`` from the ACF's own taper), the closed loop's damping per period
  otherwise. Sustained means ``decay >= min_decay``.

The amplitude reported is that of the sine with the variance of the periodic part:
``A = sqrt(2 rho(T) var(y))`` (``rho(T)``, the ACF one period later, is the periodic share of
the variance for a periodic signal plus noise); for a sine of amplitude ``A`` in white noise it
is ``A``.

Hägglund's IAE-based detector (Hägglund 1995, Control Eng. Practice 3(11), 1543-1551) needs the
controller's integral time and an acceptable error amplitude; it is not implemented here.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from agents.monitor.config import OscillationConfig

__all__ = ["OscillationResult", "acf", "detect_oscillation"]


@dataclass(frozen=True)
class OscillationResult:
    """Verdict of :func:`detect_oscillation` on one series.

    Attributes
    ----------
    oscillating : bool
        Regular (``r > 1``) and sustained (``decay >= min_decay``).
    regular : bool
        ``r > 1`` over at least ``min_periods`` period estimates.
    period : float or None
        Mean period, samples (``None`` with too few significant ACF crossings).
    regularity : float or None
        Thornhill's ``r``.
    decay : float or None
        ACF lobe ratio one period apart (1: sustained).
    amplitude : float or None
        Amplitude of the sine with the periodic part's variance (units of the series).
    periods : int
        Number of period estimates ``T_i`` used.
    crossings : tuple of float
        The ACF zero crossings used, lags in samples.
    text : str
        One line for the report.
    """

    oscillating: bool
    regular: bool
    period: float | None
    regularity: float | None
    decay: float | None
    amplitude: float | None
    periods: int
    crossings: tuple[float, ...]
    text: str

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        d = asdict(self)
        d["crossings"] = list(self.crossings)
        return d


def acf(y: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    """Biased sample autocorrelation ``rho(0) ... rho(max_lag)`` of the means-removed ``y``
    (``rho(h) = sum_t y_t y_(t+h) / sum_t y_t^2``), by FFT."""
    y = np.asarray(y, dtype=float).ravel()
    y = y - y.mean()
    n = y.size
    m = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfft(y, m)
    r = np.fft.irfft(f * np.conj(f), m)[: max_lag + 1]
    return r / r[0] if r[0] > 0 else np.zeros(max_lag + 1)


def _crossings(rho: NDArray[np.float64], threshold: float, limit: int) -> list[float]:
    """Zero crossings of ``rho`` while the lobe before each exceeds ``threshold`` in modulus."""
    out: list[float] = []
    sign = np.sign(rho)
    start = 0
    for k in range(1, rho.size):
        if sign[k] == 0 or sign[k] == sign[k - 1]:
            continue
        if sign[k - 1] == 0:
            continue
        lobe = float(np.max(np.abs(rho[start:k])))
        if lobe < threshold:
            break
        z = (k - 1) + rho[k - 1] / (rho[k - 1] - rho[k])
        out.append(float(z))
        start = k
        if len(out) >= limit:
            break
    return out


def detect_oscillation(
    y: NDArray[np.float64], config: OscillationConfig | None = None
) -> OscillationResult:
    """Thornhill's ACF regularity test with significance and decay checks (module docstring).

    Parameters
    ----------
    y : ndarray
        The analysed series (PV, or the control error SP - PV).
    config : OscillationConfig, optional
        Thresholds: ``min_regularity`` (1), ``min_decay``, ``significance``, ``max_crossings``,
        ``min_periods``.

    Returns
    -------
    OscillationResult
        ``oscillating`` False with a reason in ``text`` when there is no regular oscillation.
    """
    cfg = config or OscillationConfig()
    y = np.asarray(y, dtype=float).ravel()
    n = y.size
    none = OscillationResult(False, False, None, None, None, None, 0, (), "")
    if n < 20 or float(np.var(y)) <= 0.0:
        return OscillationResult(**{**asdict(none), "text": "no oscillation (too few samples)"})
    rho = acf(y, n // 2)
    zs = _crossings(rho, cfg.significance / math.sqrt(n), cfg.max_crossings)
    if len(zs) < cfg.min_periods + 2:
        return OscillationResult(
            **{
                **asdict(none),
                "crossings": tuple(zs),
                "text": f"no oscillation ({len(zs)} significant ACF zero crossings)",
            }
        )
    z = np.asarray(zs)
    periods = z[2:] - z[:-2]
    t_mean = float(np.mean(periods))
    t_std = float(np.std(periods, ddof=1))
    r = t_mean / (3.0 * max(t_std, 1e-9 * t_mean))
    regular = r > cfg.min_regularity
    # lobe peaks between crossings, one period apart
    peaks = []
    for a, b in zip(z[:-1], z[1:], strict=True):
        lobe = np.abs(rho[int(math.ceil(a)) : int(b) + 1])
        peaks.append(float(lobe.max()) if lobe.size else 0.0)
    ratios = [peaks[i + 2] / peaks[i] for i in range(len(peaks) - 2) if peaks[i] > 0]
    decay = float(np.exp(np.mean(np.log(np.clip(ratios, 1e-12, None))))) if ratios else None
    sustained = decay is not None and decay >= cfg.min_decay
    lag = int(round(t_mean))
    share = float(rho[lag]) if 0 < lag < rho.size else 0.0
    amplitude = math.sqrt(2.0 * max(share, 0.0) * float(np.var(y)))
    osc = regular and sustained
    if osc:
        text = (
            f"sustained oscillation: period {t_mean:.3g} samples, regularity r = {r:.3g} "
            f"(> {cfg.min_regularity:g}), ACF decay {decay:.2f} per period, amplitude "
            f"{amplitude:.3g}"
        )
    elif regular:
        text = (
            f"decaying oscillation (not sustained): period {t_mean:.3g} samples, r = {r:.3g}, "
            f"ACF decay {decay if decay is None else round(decay, 2)} per period "
            f"(< {cfg.min_decay:g}): an underdamped loop"
        )
    else:
        text = f"no regular oscillation (r = {r:.3g} <= {cfg.min_regularity:g})"
    return OscillationResult(
        oscillating=osc,
        regular=regular,
        period=t_mean,
        regularity=r,
        decay=decay,
        amplitude=amplitude if regular else None,
        periods=int(periods.size),
        crossings=tuple(zs),
        text=text,
    )
