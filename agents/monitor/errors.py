"""Errors of the control-loop performance monitor: data refused, model not identifiable.

Seed 004 (Lakshminarayanan et al. 2006), section "Theory", after eq. (15): the multivariate AR
model becomes unidentifiable if (i) ``y1`` and ``y2`` are very strongly correlated, (ii) no
disturbance enters the primary or the secondary loop, or (iii) the primary and secondary
disturbances are highly correlated. The monitor reports these as :class:`IdentificationError`
with a machine-readable :attr:`~IdentificationError.reason` and never returns numbers for them.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "MonitorError",
    "DataError",
    "QualityError",
    "IdentificationError",
    "REASONS",
    "NONSTATIONARY",
    "check_not_diverging",
]

REASONS: dict[str, str] = {
    "too_short": "fewer samples than the model needs",
    "not_finite": "missing (NaN) or infinite values",
    "constant": "a series is constant",
    "bad_delay": "delays inconsistent with the data or with each other",
    "collinear": "a series is an exact linear function of another (e.g. a scaled copy)",
    "silent_channel": "no disturbance enters a channel (a series is exactly predictable)",
    "correlated_innovations": "primary and secondary innovations almost perfectly correlated",
    "unstable_model": "the fitted autoregressive model is not stationary",
}
"""Reason codes of :class:`IdentificationError` and what they mean."""

NONSTATIONARY: dict[str, str] = {
    "drift": "a trend: the detrended data are stationary",
    "integrating": "a unit root near z = 1 that detrending does not remove (integrating "
    "process, random-walk disturbance, set-point moves)",
    "manual": "integrating while the controller output does not move: the loop is in manual",
    "diverging": "the spread grows over the record: an unstable loop",
}
"""Kinds of non-stationary records the Harris index refuses (``unstable_model``)."""


class MonitorError(ValueError):
    """Base class of the monitor's refusals."""


class DataError(MonitorError):
    """Routine data refused; names the column and (1-based data) row when there is one.

    Attributes
    ----------
    column : str or None
        Column concerned.
    row : int or None
        1-based data row (the header is not counted; the file line is ``row + 1``).
    """

    def __init__(self, message: str, *, column: str | None = None, row: int | None = None):
        super().__init__(message)
        self.column = column
        self.row = row


class QualityError(DataError):
    """Data refused by a data-quality check set to ``refuse`` (or whose exclusions leave too
    few rows): the file was read, its content is not fit for the analysis.

    Attributes
    ----------
    check : str
        The screening check (``frozen``, ``spike``, ...), as in
        :mod:`agents.monitor.screening`.
    """

    def __init__(
        self, message: str, *, check: str, column: str | None = None, row: int | None = None
    ):
        super().__init__(message, column=column, row=row)
        self.check = check


class IdentificationError(MonitorError):
    """The time-series model cannot be identified from the data.

    Attributes
    ----------
    reason : str
        One of :data:`REASONS`.
    detail : str
        Human-readable explanation naming the series concerned.
    kind : str or None
        A finer class where there is one: for ``unstable_model`` one of :data:`NONSTATIONARY`
        (or ``"slow"`` / ``"oscillating"`` from the model fit before classification).
    """

    def __init__(self, reason: str, detail: str, *, kind: str | None = None) -> None:
        if reason not in REASONS:
            raise ValueError(f"unknown reason {reason!r}")
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail
        self.kind = kind


def check_not_diverging(y: np.ndarray, name: str, *, ratio: float = 100.0) -> None:
    """Refuse a series whose spread grows ``ratio``-fold over the record (an unstable loop, or a
    drifting process): its variance, and every model of it, would be meaningless.

    Raises
    ------
    IdentificationError
        ``unstable_model``.
    """
    parts = np.array_split(np.asarray(y, dtype=float), 5)
    first, last = float(np.std(parts[0])), float(np.std(parts[-1]))
    if last > ratio * first:
        raise IdentificationError(
            "unstable_model",
            f"{name!r} spreads {last / max(first, 1e-300):.3g} times more in the last fifth of the "
            "record than in the first: the loop is unstable or the data are not stationary",
            kind="diverging",
        )
