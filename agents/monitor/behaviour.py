"""The performance monitor node: assesses one loop live on the bus (seed 004).

A scenario node of ``kind: monitor`` (:class:`agents.monitor.config.MonitorNodeConfig`). It reads
the loop's delivered samples (``loop/<l>/meas``), its set point (``ops/setpoint/<l>``, or
``loop/<l>/sp`` under a coordination agent) and the plant states or other loops its candidate
secondaries name (``plant/<p>/state``, ``loop/<l2>/meas``) into a sliding window
(:class:`agents.monitor.run_data.RunSeries`), and publishes ``monitor/assessment/<loop>``
(:class:`bus_schemas.MonitorAssessment`: Harris index with its uncertainty, per secondary the
components 1a/1b/2a/2b and the predicted cascade band, the ranking and the recommendation) every
``period`` and at the end of the run. An assessment at time ``T`` covers the samples delivered
before ``T``; ``wncs assess RUN_DIR --until T --window N ...`` reproduces it from the history.

Data the analysis refuses (too few samples yet, a constant or missing column) give an assessment
of status ``insufficient_data`` or ``refused`` with the reason; the node never stops on them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from agents.monitor.config import MonitorNodeConfig, rows_needed
from agents.monitor.errors import DataError
from agents.monitor.run_data import RunSeries, assess_series
from bus_schemas import MonitorAssessment, MonitorCandidate, MonitorHarris, keys
from bus_schemas.envelope import RawEnvelope
from core.behaviour import Behaviour
from core.time import to_ticks

__all__ = ["MonitorBehaviour", "MonitorSpec", "assessment_body", "run_assessment"]


def _num(v: Any) -> float | None:
    return float(v) if isinstance(v, int | float) and math.isfinite(v) else None


def assessment_body(report: dict[str, Any], *, final: bool) -> MonitorAssessment:
    """The bus body of an assessment report: :meth:`AssessmentResult.to_dict` with the
    ``window`` of :meth:`agents.monitor.run_data.WindowInfo.to_dict` (what ``wncs assess``
    writes as JSON for a run directory)."""
    w = report["window"]
    h = report["harris"]
    if h["status"] == "ok":
        harris = MonitorHarris(
            status="ok",
            index=_num(h["index"]),
            std=_num(h["std"]),
            ci=tuple(h["ci"]) if None not in h["ci"] else None,
            confidence=_num(h["confidence"]),
            sigma2_mv=_num(h["sigma2_mv"]),
            order=h["order"],
        )
    else:
        harris = MonitorHarris(status="unidentifiable", reason=h["reason"], detail=h["detail"])
    cands = []
    for c in report["candidates"]:
        if c["status"] == "ok":
            pr = c["prediction"]
            band = pr["band"]
            cands.append(
                MonitorCandidate(
                    name=c["name"],
                    d1=c["d1"],
                    d2=c["d2"],
                    status="ok",
                    components={k: v for k, v in c["components"].items() if v is not None},
                    band=tuple(band) if None not in band else None,
                    point=_num(pr["point"]),
                    minimum=_num(pr["minimum"]),
                    reduction=_num(pr["reduction"]),
                    order=c["order"],
                )
            )
        else:
            cands.append(
                MonitorCandidate(
                    name=c["name"],
                    d1=c["d1"],
                    d2=c["d2"],
                    status="unidentifiable",
                    reason=c["reason"],
                    detail=c["detail"],
                )
            )
    rec = report["recommendation"]
    return MonitorAssessment(
        loop=w["loop"],
        status="ok",
        final=final,
        until=to_ticks(w["until"]),
        n_samples=w["samples"],
        t_first=to_ticks(w["first_sampled"]),
        t_last=to_ticks(w["last_sampled"]),
        delay=report["delay"],
        variance=_num(report["variance"]),
        harris=harris,
        candidates=tuple(cands),
        ranking=tuple(report["ranking"]),
        cascade=rec["cascade"],
        secondary=rec["secondary"],
        text=rec["text"],
    )


def run_assessment(
    series: Any, cfg: Any, *, until: int, time_unit: str, source: str | None = None
) -> dict[str, Any]:
    """Assess ``series`` as monitor ``cfg`` does: the JSON-ready report (``window`` included).

    Raises
    ------
    DataError
        The window's data are refused (:meth:`agents.monitor.run_data.RunSeries.table`).
    """
    result, info = assess_series(
        series,
        cfg.d,
        cfg.secondaries,
        setpoint=cfg.setpoint,
        config=cfg.analysis,
        source=source,
    )
    return {**result.to_dict(), "window": info.to_dict(until, time_unit)}


@dataclass(frozen=True)
class MonitorSpec:
    """What a monitor node needs of its scenario, computed once
    (:func:`scenario.views.monitor_spec`).

    Attributes
    ----------
    config : MonitorNodeConfig
        The node's configuration (checked against the scenario).
    series : RunSeries
        The window of the loop's columns it assesses (built from the scenario).
    end : int
        End of the run, ticks.
    time_unit : str
        The scenario's time unit, for the report's window.
    """

    config: MonitorNodeConfig
    series: RunSeries
    end: int
    time_unit: str


class MonitorBehaviour(Behaviour):
    def __init__(self, name: str, spec: MonitorSpec) -> None:
        super().__init__(name)
        self.spec = spec
        cfg = spec.config
        self.cfg = cfg
        self.end = spec.end
        self.series = spec.series
        for key, body_type in self.series.subscriptions():
            self.subscribe(key, body_type, self._on_message)
        if cfg.period is not None:
            period = to_ticks(cfg.period)
            self.every(period, self._periodic, start=period)
        self.at(self.end, self._final)

    def _on_message(self, env: RawEnvelope, body: Any) -> None:
        self.series.feed(self.current_key, env.round, env.t, body)

    def _periodic(self) -> None:
        if self.now < self.end:  # the end has its own, final assessment
            self._assess(final=False)

    def _final(self) -> None:
        self._assess(final=True)

    def _assess(self, *, final: bool) -> None:
        cfg = self.cfg
        info = self.series.info()
        need = rows_needed(cfg.analysis, 2 if cfg.secondaries else 1)
        common = {
            "loop": cfg.loop,
            "final": final,
            "until": self.now,
            "n_samples": info.n,
            "t_first": info.t_first,
            "t_last": info.t_last,
            "delay": cfg.d,
        }
        if info.n < need:
            body = MonitorAssessment(
                status="insufficient_data",
                text=f"{info.n} samples in the window; the analysis needs {need}",
                **common,
            )
        else:
            try:
                report = run_assessment(
                    self.series, cfg, until=self.now, time_unit=self.spec.time_unit
                )
            except DataError as err:
                body = MonitorAssessment(status="refused", text=str(err), **common)
            else:
                body = assessment_body(report, final=final)
        self.log.info("assessment of loop %s (%s): %s", cfg.loop, body.status, body.text)
        self.publish(keys.monitor_assessment(cfg.loop), body)
