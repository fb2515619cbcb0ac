"""Assess a simple-feedback loop: Harris index and cascade opportunities (seed 004).

One call answers, from routine closed-loop data and the process delays alone, seed 004's
question "would cascade control pay off, and with which secondary measurement?":

1. the loop's Harris index with its uncertainty (:func:`agents.monitor.harris.harris_index`,
   delay ``d`` from ``u`` to the primary);
2. for every candidate secondary ``y2`` (with its delays ``d1`` secondary -> primary and ``d2``
   ``u`` -> secondary, ``d1 + d2 = d``), the variance decomposition 1a/1b/2a/2b of eq. (11)-(15)
   and the predicted variance under cascade control (band ``[1a + 2a/2, 1a + 2a]`` by default,
   minimum 1a; :mod:`agents.monitor.decomposition`), or the reason it cannot be identified;
3. the ranking of the identified candidates by predicted cascade variance;
4. before all this, the data-quality screening (:mod:`agents.monitor.screening`: frozen,
   compressed, spikes, quality and mode columns, PV not tracking SP, saturated OP), and with the
   index the oscillation diagnosis (:mod:`agents.monitor.oscillation`, Thornhill et al. 2003) of
   the analysed series.

:func:`assess` works on arrays (a node would call it on a window of samples); :func:`assess_csv`
reads a historian export first (:func:`agents.monitor.routine_data.load_routine_csv`), for the
``wncs assess`` command. The result's :meth:`AssessmentResult.to_dict` is JSON-ready (``NaN`` and
infinities become ``null``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.monitor.config import MonitorConfig, SecondarySpec, rows_needed
from agents.monitor.decomposition import Decomposition, decompose, rank_secondaries
from agents.monitor.errors import DataError, IdentificationError
from agents.monitor.harris import HarrisResult, harris_index
from agents.monitor.oscillation import OscillationResult, detect_oscillation
from agents.monitor.routine_data import RoutineData, load_routine_csv
from agents.monitor.screening import Screening, label_mask, screen

__all__ = [
    "SecondarySpec",
    "MonitorConfig",
    "CandidateResult",
    "AssessmentResult",
    "rows_needed",
    "assess",
    "assess_csv",
    "parse_time",
    "DEFAULT_GOOD",
    "DEFAULT_AUTO",
]


def _clean(x: Any) -> Any:
    """JSON-ready copy: numpy scalars to float, NaN/inf to None."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if isinstance(x, float | np.floating):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


@dataclass(frozen=True)
class CandidateResult:
    """Outcome for one candidate secondary.

    ``status`` is ``"ok"`` (``decomposition`` set) or ``"unidentifiable"`` (``reason``, ``detail``
    set, no numbers).
    """

    name: str
    d1: int
    d2: int
    status: Literal["ok", "unidentifiable"]
    decomposition: Decomposition | None = None
    reason: str | None = None
    detail: str | None = None

    def to_dict(self, removed_2a: tuple[float, float] = (0.0, 0.5)) -> dict:
        d: dict[str, Any] = {
            "name": self.name,
            "d1": self.d1,
            "d2": self.d2,
            "status": self.status,
        }
        if self.decomposition is not None:
            d.update(self.decomposition.to_dict(removed_2a))
        else:
            d.update({"reason": self.reason, "detail": self.detail})
        return d


@dataclass(frozen=True)
class AssessmentResult:
    """Harris index, per-candidate decompositions and ranking for one loop."""

    primary: str
    delay: int
    n_samples: int
    variance: float
    harris: HarrisResult | None
    harris_error: IdentificationError | None
    candidates: tuple[CandidateResult, ...]
    ranking: tuple[str, ...]
    config: MonitorConfig
    source: str | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    oscillation: OscillationResult | None = None
    screening: Screening | None = None
    hints: tuple[str, ...] = field(default_factory=tuple)
    analysed: NDArray[np.float64] | None = field(default=None, repr=False, compare=False)

    @property
    def best(self) -> CandidateResult | None:
        """The top-ranked identified candidate (None if none)."""
        if not self.ranking:
            return None
        return next(c for c in self.candidates if c.name == self.ranking[0])

    def recommendation(self) -> dict[str, Any]:
        """Whether cascade control is predicted to pay off, and with which secondary."""
        best = self.best
        if best is None or best.decomposition is None:
            return {
                "cascade": False,
                "secondary": None,
                "text": "no candidate secondary could be analysed",
            }
        pr = best.decomposition.prediction(self.config.removed_2a)
        pays = pr.reduction >= self.config.min_reduction
        text = (
            f"cascade with {best.name!r} as secondary: predicted variance of {self.primary!r} "
            f"{pr.point:.4g} (band {pr.low:.4g}-{pr.high:.4g}, at best {pr.minimum:.4g}) against "
            f"{self.variance:.4g} now ({100 * pr.reduction:.0f} % less)"
        )
        if not pays:
            text += f"; below the {100 * self.config.min_reduction:.0f} % threshold: not worth it"
        return {
            "cascade": bool(pays),
            "secondary": best.name,
            "predicted_reduction": pr.reduction,
            "text": text,
        }

    def to_dict(self) -> dict:
        """JSON-ready dictionary of everything above."""
        ra = self.config.removed_2a
        harris: dict[str, Any]
        if self.harris is not None:
            harris = {"status": "ok", **self.harris.to_dict()}
        else:
            err = self.harris_error
            harris = {
                "status": "unidentifiable",
                "reason": err.reason if err else None,
                "detail": err.detail if err else None,
                "kind": err.kind if err else None,
            }
        return _clean(
            {
                "primary": self.primary,
                "delay": self.delay,
                "n_samples": self.n_samples,
                "variance": self.variance,
                "source": self.source,
                "harris": harris,
                "candidates": [c.to_dict(ra) for c in self.candidates],
                "ranking": list(self.ranking),
                "recommendation": self.recommendation(),
                "band_rule": f"[1a + {1 - ra[1]:g}*2a, 1a + {1 - ra[0]:g}*2a]",
                "config": self.config.model_dump(),
                "notes": list(self.notes),
                "oscillation": self.oscillation.to_dict() if self.oscillation else None,
                "screening": self.screening.to_dict() if self.screening else None,
                "hints": list(self.hints),
            }
        )


def _as_specs(
    secondaries: Sequence[SecondarySpec | Mapping[str, Any] | tuple[str, int, int]],
) -> list[SecondarySpec]:
    out = []
    for i, s in enumerate(secondaries):
        if isinstance(s, SecondarySpec):
            out.append(s)
        elif isinstance(s, Mapping):
            out.append(SecondarySpec.model_validate(dict(s)))
        else:
            try:
                name, d1, d2 = s
            except (TypeError, ValueError):
                raise ValueError(
                    f"secondaries[{i}]: expected SecondarySpec, mapping or (name, d1, d2), "
                    f"got {s!r}"
                ) from None
            out.append(SecondarySpec(name=name, d1=d1, d2=d2))
    return out


def assess(
    data: Mapping[str, ArrayLike] | RoutineData,
    primary: str,
    delay: int,
    secondaries: Sequence[SecondarySpec | Mapping[str, Any] | tuple[str, int, int]] = (),
    *,
    setpoint: str | None = None,
    config: MonitorConfig | None = None,
    source: str | None = None,
    op: str | None = None,
    op_limits: tuple[float, float] | None = None,
    quality: ArrayLike | None = None,
    mode: ArrayLike | None = None,
    row_offset: int = 0,
) -> AssessmentResult:
    """Harris index and seed 004 cascade assessment of one simple-feedback loop.

    Parameters
    ----------
    data : mapping or RoutineData
        Routine closed-loop series by name (equal lengths).
    primary : str
        Name of the primary controlled variable (PV).
    delay : int
        Dead time from the manipulated variable to the primary, samples.
    secondaries : sequence
        Candidate secondaries as :class:`SecondarySpec`, mappings or ``(name, d1, d2)``;
        each must satisfy ``d1 + d2 = delay``.
    setpoint : str, optional
        Set-point series; the analysis then uses the control error ``SP - PV`` for the primary.
    config : MonitorConfig, optional
        Analysis settings.
    source : str, optional
        Where the data came from (recorded in the result).
    op : str, optional
        Controller-output series: screened for saturation; tells a loop in manual.
    op_limits : (float, float), optional
        The output's limits (default: the record's extremes).
    quality, mode : array of bool, optional
        Rows of good quality / in auto (:func:`agents.monitor.screening.label_mask`).
    row_offset : int
        Data rows of the source before the first sample (row numbers in the findings).

    Returns
    -------
    AssessmentResult
        Unidentifiable parts carry a status and reason instead of numbers.

    Raises
    ------
    DataError
        A named series is missing, of another length, or the data are too short; a screening
        check set to ``refuse`` found something, or exclusions leave too few rows.
    ValueError
        Inconsistent delays (naming the candidate and field).
    """
    cfg = config or MonitorConfig()
    specs = _as_specs(secondaries)
    if int(delay) != delay or delay < 1:
        raise ValueError(f"delay must be an integer >= 1, got {delay!r}")
    delay = int(delay)
    for i, s in enumerate(specs):
        if s.d1 + s.d2 != delay:
            raise ValueError(
                f"secondaries[{i}] ({s.name!r}): d1 + d2 = {s.d1} + {s.d2} = {s.d1 + s.d2} must "
                f"equal delay = {delay} (dead time from u to {primary!r})"
            )
    names = (
        [primary]
        + ([setpoint] if setpoint else [])
        + [s.name for s in specs]
        + ([op] if op and op not in (primary, setpoint) else [])
    )
    arrays: dict[str, np.ndarray] = {}
    for nm in names:
        if nm not in data:
            raise DataError(f"series {nm!r} not in the data", column=nm)
        arrays[nm] = np.asarray(data[nm], dtype=float).ravel()
    n = arrays[primary].size
    for nm, a in arrays.items():
        if a.size != n:
            raise DataError(f"series {nm!r} has {a.size} samples, {primary!r} has {n}", column=nm)
    need = rows_needed(cfg, 2 if specs else 1)
    if n < need:
        raise DataError(f"{n} samples; the model needs at least {need}", row=n)
    scr = screen(
        arrays,
        pv=primary,
        sp=setpoint,
        op=op,
        secondaries=[s.name for s in specs],
        quality=quality,
        mode=mode,
        op_limits=op_limits,
        config=cfg.screening,
        min_rows=need,
        row_offset=row_offset,
    )
    n_screened, arrays = n, scr.series
    n = arrays[primary].size
    y1 = arrays[primary] if setpoint is None else arrays[setpoint] - arrays[primary]
    rng = np.random.default_rng(cfg.seed)
    notes: list[str] = [f.text for f in scr.findings]
    if n < n_screened:
        notes.append(
            f"analysed rows {scr.first_row}-{scr.last_row} ({n} of {n_screened}: the longest "
            "stretch without excluded rows)"
        )
    osc = detect_oscillation(y1, cfg.oscillation)
    harris: HarrisResult | None = None
    herr: IdentificationError | None = None
    try:
        harris = harris_index(
            y1,
            delay,
            order=cfg.order,
            max_order=cfg.max_order,
            criterion=cfg.criterion,
            uncertainty=cfg.harris_uncertainty,
            n_boot=cfg.n_boot,
            rng=rng,
            confidence=cfg.confidence,
            name=primary,
            op=arrays[op] if op else None,
        )
    except IdentificationError as exc:
        herr = exc
    notes.extend(_harris_notes(harris, osc))
    cands: list[CandidateResult] = []
    decs: dict[str, Decomposition | IdentificationError] = {}
    for s in specs:
        try:
            dec = decompose(
                y1,
                arrays[s.name],
                s.d1,
                s.d2,
                order=cfg.order,
                max_order=cfg.max_order,
                criterion=cfg.criterion,
                method=cfg.method,
                max_innovation_correlation=cfg.max_innovation_correlation,
                n_boot=cfg.decomposition_boot,
                rng=rng,
                names=(primary, s.name),
            )
        except IdentificationError as exc:
            decs[s.name] = exc
            cands.append(
                CandidateResult(
                    s.name, s.d1, s.d2, "unidentifiable", reason=exc.reason, detail=exc.detail
                )
            )
            continue
        decs[s.name] = dec
        if abs(dec.closure - 1.0) > 0.05:
            notes.append(
                f"{s.name!r}: the components add up to {100 * dec.closure:.1f} % of the variance "
                "of the primary (model fit doubtful)"
            )
        cands.append(CandidateResult(s.name, s.d1, s.d2, "ok", decomposition=dec))
    ranking = tuple(rank_secondaries(decs, cfg.removed_2a))
    hints: list[str] = []
    if herr is not None and herr.kind in ("drift", "integrating") and setpoint is None:
        hints.append(
            f"{primary!r} is refused on the PV alone: if the set point moved over the record, "
            "analyse the control error SP - PV (pass --setpoint COL)"
        )
    if herr is not None and herr.kind == "integrating" and op is None:
        hints.append("pass the controller output (--op COL) to tell a loop in manual")
    return AssessmentResult(
        primary=primary,
        delay=delay,
        n_samples=n,
        variance=float(np.var(y1)),
        harris=harris,
        harris_error=herr,
        candidates=tuple(cands),
        ranking=ranking,
        config=cfg,
        source=source,
        notes=tuple(notes),
        oscillation=osc,
        screening=scr,
        hints=tuple(hints),
        analysed=y1,
    )


def _harris_notes(h: HarrisResult | None, osc: OscillationResult) -> list[str]:
    """Caveats of the index: oscillating data, an index above 1."""
    out = []
    if h is not None and (h.oscillating_model or osc.oscillating):
        out.append(
            "oscillating loop: the Harris index is that of the data (the cycle counts as "
            "variance a minimum-variance controller would remove); if the cycle comes from the "
            "valve (stiction), retuning alone will not remove it"
        )
    if h is not None and h.above_one:
        if h.ci[0] > 1.0:
            out.append(
                f"Harris index {h.index:.3f} with its whole interval above 1: the delay d = "
                f"{h.delay} is probably larger than the loop's"
            )
        else:
            out.append(
                f"Harris index {h.index:.3f} above 1: estimation noise; the loop is at minimum "
                "variance within its uncertainty"
            )
    return out


_SP_NAME = re.compile(
    r"(^|[^a-z0-9])(sp|sv|setpoint|set_point|set-point|set point)([^a-z0-9]|$)", re.I
)

DEFAULT_GOOD = ("good", "ok", "192")
"""Quality-column values read as good by default (text compared case-insensitively; 192 is the
OPC DA "good" quality)."""

DEFAULT_AUTO = ("auto", "aut", "cas", "cascade")
"""Mode-column values read as "in automatic" by default."""


def assess_csv(
    path: str | Path,
    primary: str,
    delay: int,
    secondaries: Sequence[SecondarySpec | Mapping[str, Any] | tuple[str, int, int]] = (),
    *,
    setpoint: str | None = None,
    sep: str = ";",
    decimal: str = ".",
    config: MonitorConfig | None = None,
    op: str | None = None,
    op_limits: tuple[float, float] | None = None,
    quality: str | None = None,
    good: Sequence[str] = DEFAULT_GOOD,
    mode: str | None = None,
    auto: Sequence[str] = DEFAULT_AUTO,
    time: str | None = None,
    start: str | float | None = None,
    until: str | float | None = None,
    window: int | None = None,
    skip_rows: int | None = None,
) -> AssessmentResult:
    """:func:`assess` on the columns of a routine-data CSV file (refusals as :class:`DataError`).

    Parameters
    ----------
    op, op_limits, setpoint, config
        As :func:`assess` (columns by name).
    quality, mode : str, optional
        Quality / mode columns (text); rows whose value is not in ``good`` / ``auto`` are
        screened (:func:`agents.monitor.screening.label_mask`).
    time : str, optional
        Time column (numbers, or ISO 8601 date-times such as ``2024-03-01 00:10:00``): then
        ``start`` and ``until`` are times; without it they are 1-based data rows.
    start, until, window
        Rows at or after ``start`` and before ``until``; of them the last ``window``.
    skip_rows : int, optional
        Lines before the header (default: found, :func:`load_routine_csv`).
    """
    cfg = config or MonitorConfig()
    specs = _as_specs(secondaries)
    cols = [primary] + ([setpoint] if setpoint else []) + [s.name for s in specs]
    if op and op not in cols:
        cols.append(op)
    labels = [c for c in (quality, mode, time) if c]
    data = load_routine_csv(
        path,
        cols,
        sep,
        decimal=decimal,
        min_rows=rows_needed(cfg, 2 if specs else 1),
        constant_ok=[c for c in (setpoint, op) if c],
        labels=labels,
        skip_rows=skip_rows,
    )
    a, b = _rows(data, time, start, until, window)
    arrays = {k: v[a:b] for k, v in data.columns.items()}
    result = assess(
        arrays,
        primary,
        delay,
        specs,
        setpoint=setpoint,
        config=cfg,
        source=str(path),
        op=op,
        op_limits=op_limits,
        quality=label_mask(data.labels[quality][a:b], good) if quality else None,
        mode=label_mask(data.labels[mode][a:b], auto) if mode else None,
        row_offset=a,
    )
    sp_like = [c for c in data.header if _SP_NAME.search(c) and c not in (primary, setpoint)]
    if setpoint is None and sp_like and result.hints:
        hint = (
            f"the file has a set-point column {sp_like[0]!r}: pass --setpoint {sp_like[0]} to "
            "analyse the control error"
        )
        return replace(result, hints=(hint, *result.hints[1:]))
    return result


def parse_time(text: str) -> float:
    """A time cell as a number: itself if numeric, else an ISO 8601 date-time in seconds
    (naive times counted from 1970-01-01 as written, no time zone applied).

    Raises
    ------
    ValueError
        Neither a number nor an ISO date-time.
    """
    t = text.strip().strip('"').strip()
    try:
        return float(t)
    except ValueError:
        pass
    try:
        dt = datetime.fromisoformat(t)
    except ValueError:
        raise ValueError(f"{text!r} is neither a number nor an ISO 8601 date-time") from None
    if dt.tzinfo is not None:
        return dt.timestamp()
    return (dt - datetime(1970, 1, 1)).total_seconds()


def _rows(
    data: RoutineData,
    time: str | None,
    start: str | float | None,
    until: str | float | None,
    window: int | None,
) -> tuple[int, int]:
    """0-based ``[a, b)`` of the rows selected by ``start``, ``until`` and ``window``."""
    n = data.n_rows
    if window is not None and window < 1:
        raise DataError(f"--window: must be >= 1 rows, got {window}")
    if time is None:
        a, b = 0, n
        for flag, value in (("--start", start), ("--until", until)):
            if value is None:
                continue
            try:
                row = int(str(value))
            except ValueError:
                raise DataError(
                    f"{flag}: {value!r} is not a data row number (pass --time COL to cut by time)"
                ) from None
            if row < 1:
                raise DataError(f"{flag}: data rows count from 1, got {row}")
            if flag == "--start":
                a = min(row - 1, n)
            else:
                b = min(row - 1, n)
    else:
        times = np.empty(n)
        for k, cell in enumerate(data.labels[time]):
            try:
                times[k] = parse_time(cell)
            except ValueError as err:
                raise DataError(
                    f"column {time!r}, row {k + 1}: {err}", column=time, row=k + 1
                ) from None
        back = np.flatnonzero(np.diff(times) <= 0)
        if back.size:
            k = int(back[0]) + 2
            raise DataError(
                f"column {time!r}, row {k}: time {data.labels[time][k - 1]!r} does not increase",
                column=time,
                row=k,
            )
        a, b = 0, n
        try:
            if start is not None:
                a = int(np.searchsorted(times, parse_time(str(start)), side="left"))
            if until is not None:
                b = int(np.searchsorted(times, parse_time(str(until)), side="left"))
        except ValueError as err:
            raise DataError(f"--start/--until: {err}") from None
    if b <= a:
        raise DataError(f"--start/--until select no rows (rows {a + 1} to {b} of {n})")
    if window is not None:
        a = max(a, b - window)
    return a, b
