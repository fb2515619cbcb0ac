"""Data-quality screening of a loop's routine data before the analysis (issue 16, item 2).

Historian exports of real loops carry data no variance analysis should trust; each check below
is named in the report with the rows concerned, and acts as its setting in
:class:`agents.monitor.config.ScreeningConfig` says: ``warn`` (report only), ``exclude`` (spikes:
replaced by linear interpolation between their neighbours, which keeps the sampling regular;
other checks: the analysis keeps the longest stretch of rows none of them flags), ``refuse``
(:class:`~agents.monitor.errors.DataError` naming the check, the column and the rows).

* ``frozen`` -- runs of ``frozen_run`` or more equal values (a dead transmitter, a stale
  historian tag, compression with a dead band and step hold), in the PV and the secondaries.
* ``compressed`` -- ``compressed_run`` or more samples on one straight line (a historian that
  stores only the points outside a dead band and interpolates linearly between them).
* ``spike`` -- samples far from the running median of five (the Hampel filter's residual),
  measured in robust units of the series' own increments: ``z = |y_t - med5(y)_t| / s`` with
  ``s = 1.4826 MAD`` of the non-zero first differences, a spike when ``z > spike_threshold``.
  The increments' scale keeps sharp but genuine features (the corners of a stiction triangle,
  ``z ~ 0.7``; the peaks of a sine, ``z ~ 0.2``) far from the threshold, while one wild sample
  is hundreds of units off (Hampel 1974; Pearson 2002, "Outliers in process modeling and
  identification", IEEE Trans. Control Syst. Technol. 10(1), 55-63).
* ``quality`` and ``mode`` -- rows whose quality column is not one of the "good" values, or
  whose mode column is not one of the "auto" values (:func:`label_mask`).
* ``offset`` -- the PV does not track the set point: ``|mean(SP - PV)| > offset_ratio std(PV)``
  (a loop in manual, saturated, or mis-ranged; a controller with integral action removes any
  mean offset). ``exclude`` does not apply: it is a property of the whole record.
* ``saturation`` -- the controller output sits at a limit (given, or the extreme values of the
  record) for more than ``saturation_fraction`` of the samples: the loop is not in control there.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike, NDArray

from agents.monitor.config import ScreeningConfig
from agents.monitor.errors import DataError, QualityError

__all__ = ["Finding", "Screening", "screen", "label_mask", "runs", "spike_scores"]

_SHOWN_RANGES = 5


@dataclass(frozen=True)
class Finding:
    """One data-quality finding.

    Attributes
    ----------
    check : str
        ``frozen``, ``compressed``, ``spike``, ``quality``, ``mode``, ``offset``, ``saturation``.
    column : str
        The column concerned.
    action : str
        ``warn``, ``exclude`` or ``refuse`` (what was done).
    rows : tuple of (int, int)
        1-based inclusive data-row ranges concerned (the first few).
    count : int
        Samples concerned.
    fraction : float
        ``count`` over the rows screened.
    text : str
        One line for the report.
    """

    check: str
    column: str
    action: str
    rows: tuple[tuple[int, int], ...]
    count: int
    fraction: float
    text: str

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {
            "check": self.check,
            "column": self.column,
            "action": self.action,
            "rows": [list(r) for r in self.rows],
            "count": self.count,
            "fraction": self.fraction,
            "text": self.text,
        }


@dataclass(frozen=True)
class Screening:
    """Outcome of :func:`screen`: findings, the rows kept, the series to analyse.

    ``start`` and ``stop`` index the screened arrays (0-based, ``stop`` exclusive);
    ``first_row`` / ``last_row`` are the same rows as 1-based data rows of the source.
    """

    findings: tuple[Finding, ...]
    start: int
    stop: int
    row_offset: int
    series: dict[str, NDArray[np.float64]] = field(repr=False)

    @property
    def first_row(self) -> int:
        return self.row_offset + self.start + 1

    @property
    def last_row(self) -> int:
        return self.row_offset + self.stop

    @property
    def flags(self) -> tuple[str, ...]:
        """Checks that found something, each once, in order."""
        return tuple(dict.fromkeys(f.check for f in self.findings))

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {
            "findings": [f.to_dict() for f in self.findings],
            "flags": list(self.flags),
            "rows": [self.first_row, self.last_row],
        }


def runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``(start, stop)`` (0-based, stop exclusive) of every run of True in ``mask``."""
    m = np.asarray(mask, dtype=bool)
    if not m.size:
        return []
    d = np.diff(np.r_[0, m.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def label_mask(labels: Iterable[str], accepted: Iterable[str]) -> NDArray[np.bool_]:
    """True where a label is one of ``accepted``: compared as numbers when both parse as
    numbers (``"1"`` equals ``"1.0"``), else as stripped case-insensitive text."""
    acc_text = {a.strip().lower() for a in accepted}
    acc_num = {v for v in (_number(a) for a in acc_text) if v is not None}
    out = []
    for lab in labels:
        t = lab.strip().strip('"').strip().lower()
        v = _number(t)
        out.append(t in acc_text or (v is not None and v in acc_num))
    return np.asarray(out, dtype=bool)


def _number(text: str) -> float | None:
    try:
        v = float(text)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def _running_median5(y: NDArray[np.float64]) -> NDArray[np.float64]:
    padded = np.pad(y, 2, mode="edge")
    return np.median(sliding_window_view(padded, 5), axis=1)


def spike_scores(y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Robust z of every sample against the running median of five (module docstring); zeros
    when the series has no non-zero increments."""
    y = np.asarray(y, dtype=float).ravel()
    dy = np.diff(y)
    nz = dy[dy != 0.0]
    if nz.size < 10:
        return np.zeros(y.size)
    scale = 1.4826 * float(np.median(np.abs(nz - np.median(nz))))
    if scale <= 0.0:
        scale = float(np.median(np.abs(nz)))
    if scale <= 0.0:
        return np.zeros(y.size)
    return np.abs(y - _running_median5(y)) / scale


def _frozen(y: NDArray[np.float64], length: int) -> NDArray[np.bool_]:
    same = np.diff(y) == 0.0
    mask = np.zeros(y.size, dtype=bool)
    for a, b in runs(same):
        if b - a + 1 >= length:
            mask[a : b + 1] = True
    return mask


def _straight(y: NDArray[np.float64], length: int) -> NDArray[np.bool_]:
    dy = np.diff(y)
    if dy.size < 2:
        return np.zeros(y.size, dtype=bool)
    tol = 1e-9 * max(1.0, float(np.max(np.abs(y))))
    nz = np.abs(dy[dy != 0.0])
    if nz.size:
        tol = max(tol, 1e-3 * float(np.median(nz)))
    line = (np.abs(np.diff(dy)) <= tol) & (dy[1:] != 0.0)
    mask = np.zeros(y.size, dtype=bool)
    for a, b in runs(line):
        if b - a + 2 >= length:
            mask[a : b + 2] = True
    return mask


def _ranges(mask: NDArray[np.bool_], offset: int) -> tuple[tuple[int, int], ...]:
    return tuple((a + offset + 1, b + offset) for a, b in runs(mask)[:_SHOWN_RANGES])


def _where(rows: tuple[tuple[int, int], ...], total: int) -> str:
    text = ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in rows)
    more = total - len(rows)
    return f"rows {text}" + (f" and {more} more stretches" if more > 0 else "")


def _repair(y: NDArray[np.float64], bad: NDArray[np.bool_]) -> NDArray[np.float64]:
    good = ~bad
    idx = np.arange(y.size)
    return np.interp(idx, idx[good], y[good]) if good.any() else y.copy()


def screen(
    series: Mapping[str, ArrayLike],
    *,
    pv: str,
    sp: str | None = None,
    op: str | None = None,
    secondaries: Sequence[str] = (),
    quality: ArrayLike | None = None,
    mode: ArrayLike | None = None,
    op_limits: tuple[float, float] | None = None,
    config: ScreeningConfig | None = None,
    min_rows: int = 1,
    row_offset: int = 0,
) -> Screening:
    """Screen a loop's series and return what to analyse (module docstring).

    Parameters
    ----------
    series : mapping of str to array
        Equal-length series: ``pv``, and ``sp``, ``op`` and the ``secondaries`` where given.
    pv, sp, op : str
        Names of the primary, the set point and the controller output in ``series``.
    secondaries : sequence of str
        Candidate secondaries, screened like the PV.
    quality, mode : array of bool, optional
        True where a row's quality is good / its mode is auto (:func:`label_mask`).
    op_limits : (float, float), optional
        The controller output's limits (default: the record's extremes).
    config : ScreeningConfig
        Actions and thresholds.
    min_rows : int
        Fewest rows the analysis needs after exclusions.
    row_offset : int
        Data rows of the source before ``series[...][0]`` (for 1-based row numbers).

    Raises
    ------
    QualityError
        A check set to ``refuse`` found something, or the exclusions leave fewer than
        ``min_rows`` consecutive rows; naming the check, the column and the rows.
    DataError
        A quality or mode mask of another length.
    """
    cfg = config or ScreeningConfig()
    arrays = {k: np.asarray(v, dtype=float).ravel().copy() for k, v in series.items()}
    n = arrays[pv].size
    findings: list[Finding] = []
    excluded = np.zeros(n, dtype=bool)

    def found(check: str, column: str, action: str, mask: NDArray[np.bool_], what: str) -> None:
        count = int(mask.sum())
        rows = _ranges(mask, row_offset)
        total = len(runs(mask))
        doing = {
            "warn": "kept (warning)",
            "exclude": "replaced by interpolation" if check == "spike" else "excluded",
            "refuse": "refused",
        }[action]
        text = f"{check}: {column!r}: {what}, {_where(rows, total)} ({count} of {n} rows): {doing}"
        f = Finding(check, column, action, rows, count, count / n if n else 0.0, text)
        if action == "refuse":
            row = rows[0][0] if rows else None
            raise QualityError(f"data quality: {text}", check=check, column=column, row=row)
        findings.append(f)
        if action == "exclude" and check != "spike":
            excluded[mask] = True

    for name in [pv, *secondaries]:
        y = arrays[name]
        z = spike_scores(y)
        spikes = z > cfg.spike_threshold
        if spikes.any():
            found(
                "spike",
                name,
                cfg.spike,
                spikes,
                f"{int(spikes.sum())} samples up to {float(z.max()):.3g} robust units off the "
                f"running median (threshold {cfg.spike_threshold:g})",
            )
            if cfg.spike == "exclude":
                arrays[name] = _repair(y, spikes)
        frozen = _frozen(y, cfg.frozen_run)
        if frozen.any():
            found(
                "frozen",
                name,
                cfg.frozen,
                frozen,
                f"{100 * frozen.mean():.0f} % of the record in runs of {cfg.frozen_run} or more "
                "equal values (dead transmitter, stale tag or historian compression)",
            )
        line = _straight(y, cfg.compressed_run) & ~frozen
        if line.any():
            found(
                "compressed",
                name,
                cfg.compressed,
                line,
                f"{100 * line.mean():.0f} % of the record on straight lines of "
                f"{cfg.compressed_run} or more samples (historian interpolation)",
            )
    for check, mask, action, what in (
        ("quality", quality, cfg.quality, "quality not good"),
        ("mode", mode, cfg.mode, "loop not in auto"),
    ):
        if mask is None:
            continue
        bad = ~np.asarray(mask, dtype=bool).ravel()
        if bad.size != n:
            raise DataError(f"{check} column has {bad.size} rows, {pv!r} has {n}", column=check)
        if bad.any():
            found(check, pv, action, bad, what)
    if sp is not None:
        err = arrays[sp] - arrays[pv]
        spread = float(np.std(arrays[pv]))
        offset = float(np.mean(err))
        if spread > 0 and abs(offset) > cfg.offset_ratio * spread:
            found(
                "offset",
                pv,
                cfg.offset,
                np.ones(n, dtype=bool),
                f"the PV does not track {sp!r}: mean SP - PV = {offset:.4g}, "
                f"{abs(offset) / spread:.3g} times std(PV) = {spread:.3g} (limit "
                f"{cfg.offset_ratio:g}; manual, saturated or mis-ranged?)",
            )
    if op is not None:
        u = arrays[op]
        lo, hi = op_limits if op_limits is not None else (float(u.min()), float(u.max()))
        tol = 1e-6 * max(hi - lo, 1e-12)
        at = (u <= lo + tol) | (u >= hi - tol)
        share = float(at.mean())
        if share > cfg.saturation_fraction and (op_limits is not None or hi > lo):
            found(
                "saturation",
                op,
                cfg.saturation,
                at,
                f"the controller output is at a limit ({lo:.4g} or {hi:.4g}) in "
                f"{100 * share:.0f} % of the rows (limit {100 * cfg.saturation_fraction:g} %)",
            )
    start, stop = 0, n
    if excluded.any():
        clean = runs(~excluded)
        if not clean:
            checks = sorted({f.check for f in findings if f.action == "exclude"})
            raise QualityError(
                "data quality: every row is excluded by " + ", ".join(checks),
                check=checks[0],
                column=pv,
            )
        start, stop = max(clean, key=lambda ab: ab[1] - ab[0])
        if stop - start < min_rows:
            checks = sorted({f.check for f in findings if f.action == "exclude"})
            raise QualityError(
                f"data quality: after excluding the rows flagged {', '.join(checks)}, the longest "
                f"clean stretch is rows {row_offset + start + 1}-{row_offset + stop} "
                f"({stop - start} rows); the analysis needs {min_rows} consecutive rows "
                f"(or set the check to warn)",
                check=checks[0],
                column=pv,
                row=row_offset + start + 1,
            )
    return Screening(
        findings=tuple(findings),
        start=start,
        stop=stop,
        row_offset=row_offset,
        series={k: v[start:stop] for k, v in arrays.items()},
    )
