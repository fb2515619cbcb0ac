"""Assess a simple-feedback loop: Harris index and cascade opportunities (seed 004).

One call answers, from routine closed-loop data and the process delays alone, seed 004's
question "would cascade control pay off, and with which secondary measurement?":

1. the loop's Harris index with its uncertainty (:func:`agents.monitor.harris.harris_index`,
   delay ``d`` from ``u`` to the primary);
2. for every candidate secondary ``y2`` (with its delays ``d1`` secondary -> primary and ``d2``
   ``u`` -> secondary, ``d1 + d2 = d``), the variance decomposition 1a/1b/2a/2b of eq. (11)-(15)
   and the predicted variance under cascade control (band ``[1a + 2a/2, 1a + 2a]`` by default,
   minimum 1a; :mod:`agents.monitor.decomposition`), or the reason it cannot be identified;
3. the ranking of the identified candidates by predicted cascade variance.

:func:`assess` works on arrays (a node would call it on a window of samples); :func:`assess_csv`
reads a historian export first (:func:`agents.monitor.routine_data.load_routine_csv`), for the
``wncs assess`` command. The result's :meth:`AssessmentResult.to_dict` is JSON-ready (``NaN`` and
infinities become ``null``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from agents.monitor.config import MonitorConfig, SecondarySpec, rows_needed
from agents.monitor.decomposition import Decomposition, decompose, rank_secondaries
from agents.monitor.errors import DataError, IdentificationError
from agents.monitor.harris import HarrisResult, harris_index
from agents.monitor.routine_data import RoutineData, load_routine_csv

__all__ = [
    "SecondarySpec",
    "MonitorConfig",
    "CandidateResult",
    "AssessmentResult",
    "rows_needed",
    "assess",
    "assess_csv",
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

    Returns
    -------
    AssessmentResult
        Unidentifiable parts carry a status and reason instead of numbers.

    Raises
    ------
    DataError
        A named series is missing, of another length, or the data are too short.
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
    names = [primary] + ([setpoint] if setpoint else []) + [s.name for s in specs]
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
    y1 = arrays[primary] if setpoint is None else arrays[setpoint] - arrays[primary]
    rng = np.random.default_rng(cfg.seed)
    notes: list[str] = []
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
        )
    except IdentificationError as exc:
        herr = exc
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
    )


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
) -> AssessmentResult:
    """:func:`assess` on the columns of a routine-data CSV file (refusals as :class:`DataError`)."""
    cfg = config or MonitorConfig()
    specs = _as_specs(secondaries)
    cols = [primary] + ([setpoint] if setpoint else []) + [s.name for s in specs]
    data = load_routine_csv(
        path,
        cols,
        sep,
        decimal=decimal,
        min_rows=rows_needed(cfg, 2 if specs else 1),
        constant_ok=[setpoint] if setpoint else [],
    )
    return assess(data, primary, delay, specs, setpoint=setpoint, config=cfg, source=str(path))
