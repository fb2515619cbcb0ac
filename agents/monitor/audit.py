"""Plant-wide audit: many loops' routine data assessed at once and ranked, worst first.

``wncs assess DIR_OR_GLOB --config loops.yaml`` (:mod:`runtime.assess`). The files are the
CSV files of a directory (``*.csv``, not recursive) or those a glob matches; ``loops.yaml`` says
which columns of which file make a loop::

    defaults:                          # every field of a loop; used for files no loop names
      pv: PV
      sp: SP
      op: OP
      delay: 3
      sep: ";"
    analysis: {max_order: 30}          # MonitorConfig, for every loop (screening: ... included)
    poor: 0.3                          # Harris index below which a loop is "poor"
    good: 0.7                          # ... from which it needs nothing
    loops:
      - {name: FC101, file: FC101.csv, pv: FIC101.PV, sp: FIC101.SP, op: FIC101.OP, delay: 2}
      - name: TC7
        file: unit2/TC7.csv
        pv: TI7
        delay: 6
        secondaries: [{name: TI7B, d1: 4, d2: 2}]
        quality: Q7                    # and good: [Good], mode: M7, auto: [AUTO, CAS], time: ts

A listed loop's ``file`` is relative to the directory (or to the glob's fixed leading part),
matched also by name. Files no loop names are assessed with ``defaults`` (named by their stem)
when these give ``pv`` and ``delay``. Every loop runs in a worker process
(``concurrent.futures.ProcessPoolExecutor``, ``min(os.cpu_count(), loops, jobs)`` workers
started with the ``spawn`` method and one BLAS thread each, all started before any loop is
dispatched; a script calling :func:`run_audit` needs the ``if __name__ == "__main__":``
guard); a file that cannot be read or assessed is listed with its reason, never stops the audit.

Each loop's outcome has a status: ``assessed`` (a Harris index), ``refused`` (read, but the
index refused: non-stationary, or a data-quality check set to refuse) or ``broken`` (the file or
its columns are unusable). The ranking puts assessed loops first by increasing index (the
worst first), then refused ones, then broken ones; :func:`recommend` gives the action.
"""

from __future__ import annotations

import glob as globmod
import logging
import multiprocessing
import os
import threading
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from agents.monitor.assess import DEFAULT_AUTO, DEFAULT_GOOD, assess_csv
from agents.monitor.config import MonitorConfig, SecondarySpec
from agents.monitor.errors import DataError, MonitorError, QualityError
from agents.monitor.oscillation import acf

__all__ = [
    "LoopSpec",
    "AuditConfig",
    "load_audit_config",
    "collect_loops",
    "assess_loop",
    "run_audit",
    "rank",
    "recommend",
]

log = logging.getLogger(__name__)

_PLOT_SAMPLES = 400
_PLOT_LAGS = 60
_START_TIMEOUT_S = 60.0
_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


class LoopSpec(BaseModel):
    """One loop of the audit: its file and columns (names as in the file's header)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str | None = Field(default=None, description="loop tag (default: the file's stem)")
    file: str | None = Field(default=None, description="CSV file, relative to DIR")
    pv: str = Field(min_length=1, description="primary controlled variable column")
    sp: str | None = Field(default=None, description="set-point column: analyse SP - PV")
    op: str | None = Field(default=None, description="controller-output column")
    op_limits: tuple[float, float] | None = None
    delay: int = Field(ge=1, description="dead time move -> PV, samples")
    secondaries: tuple[SecondarySpec, ...] = ()
    quality: str | None = None
    good: tuple[str, ...] = DEFAULT_GOOD
    mode: str | None = None
    auto: tuple[str, ...] = DEFAULT_AUTO
    time: str | None = None
    start: str | None = None
    until: str | None = None
    window: int | None = Field(default=None, ge=1)
    sep: str = Field(default=";", min_length=1, max_length=1)
    decimal: str = "."
    skip_rows: int | None = Field(default=None, ge=0)

    @model_validator(mode="after")
    def _delays(self) -> LoopSpec:
        for i, s in enumerate(self.secondaries):
            if s.d1 + s.d2 != self.delay:
                raise ValueError(
                    f"secondaries[{i}]: d1 + d2 = {s.d1 + s.d2} must equal delay = {self.delay}"
                )
        return self


class AuditConfig(BaseModel):
    """``loops.yaml`` (module docstring)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    defaults: dict[str, Any] = Field(default_factory=dict)
    analysis: MonitorConfig = Field(default_factory=MonitorConfig)
    poor: float = Field(default=0.3, gt=0, lt=1, description="index below which a loop is poor")
    good: float = Field(default=0.7, gt=0, le=1, description="index from which it needs nothing")
    loops: tuple[dict[str, Any], ...] = ()

    @model_validator(mode="after")
    def _order(self) -> AuditConfig:
        if self.poor >= self.good:
            raise ValueError(f"poor ({self.poor}) must be below good ({self.good})")
        return self


def _field_error(path: Path, where: str, err: ValidationError) -> DataError:
    e = err.errors()[0]
    loc = ".".join(str(x) for x in e["loc"])
    return DataError(f"{path}: {where}{'.' if where and loc else ''}{loc}: {e['msg']}")


def load_audit_config(path: str | Path) -> tuple[AuditConfig, list[LoopSpec]]:
    """Read ``loops.yaml``: the settings and its listed loops (defaults applied).

    Raises
    ------
    DataError
        Unreadable file, or a field refused, naming the file and the dotted field
        (``loops.yaml: loops[3].delay: Input should be greater than or equal to 1``).
    """
    path = Path(path)
    try:
        raw = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as err:
        raise DataError(f"{path}: cannot read the audit configuration: {err}") from None
    if not isinstance(raw, dict):
        raise DataError(f"{path}: expected a mapping with loops:, defaults:, analysis:")
    try:
        cfg = AuditConfig.model_validate(raw)
    except ValidationError as err:
        raise _field_error(path, "", err) from None
    specs = []
    for i, entry in enumerate(cfg.loops):
        try:
            specs.append(LoopSpec.model_validate({**cfg.defaults, **entry}))
        except ValidationError as err:
            raise _field_error(path, f"loops[{i}]", err) from None
        if specs[-1].file is None:
            raise DataError(f"{path}: loops[{i}].file: needed (the loop's CSV file)")
    names = [s.name or Path(s.file or "").stem for s in specs]
    for i, name in enumerate(names):
        if names.index(name) != i:
            raise DataError(f"{path}: loops[{i}].name: {name!r} is listed twice")
    return cfg, specs


def _base(target: str) -> tuple[Path, list[Path]]:
    """The base directory and the files of ``target`` (a directory or a glob)."""
    p = Path(target)
    if p.is_dir():
        return p, sorted(f for f in p.glob("*.csv") if f.is_file())
    if p.is_file():
        return p.parent, [p]
    parts = p.parts
    magic = next((i for i, q in enumerate(parts) if globmod.has_magic(q)), len(parts))
    base = Path(*parts[:magic]) if magic else Path(".")
    return base, sorted(Path(f) for f in globmod.glob(target, recursive=True) if Path(f).is_file())


def collect_loops(
    target: str, cfg: AuditConfig, specs: Sequence[LoopSpec]
) -> tuple[list[tuple[str, Path | None, LoopSpec | None, str | None]], list[Path]]:
    """The loops to assess: ``(name, file, spec, problem)``, and the files left unconfigured.

    A listed loop whose file is not among ``target``'s files has ``problem`` set.
    """
    base, files = _base(target)
    by_rel = {
        (f.relative_to(base).as_posix() if f.is_relative_to(base) else f.name): f for f in files
    }
    by_name: dict[str, list[Path]] = {}
    for f in files:
        by_name.setdefault(f.name, []).append(f)
    used: set[Path] = set()
    out: list[tuple[str, Path | None, LoopSpec | None, str | None]] = []
    for s in specs:
        file = str(s.file)
        name = s.name or Path(file).stem
        hit = by_rel.get(Path(file).as_posix())
        if hit is None and len(by_name.get(Path(file).name, [])) == 1:
            hit = by_name[Path(file).name][0]
        if hit is None:
            out.append((name, base / file, s, f"file {file!r} not found in {target!r}"))
            continue
        used.add(hit)
        out.append((name, hit, s, None))
    rest = [f for f in files if f not in used]
    unconfigured: list[Path] = []
    taken = {o[0] for o in out}
    for f in rest:
        if "pv" in cfg.defaults and "delay" in cfg.defaults:
            name = f.stem if f.stem not in taken else f.relative_to(base).as_posix()
            try:
                spec = LoopSpec.model_validate({**cfg.defaults, "file": str(f), "name": name})
            except ValidationError as err:
                e = err.errors()[0]
                out.append((name, f, None, f"defaults.{'.'.join(map(str, e['loc']))}: {e['msg']}"))
                continue
            out.append((name, f, spec, None))
        else:
            unconfigured.append(f)
    return out, unconfigured


def assess_loop(name: str, file: str, spec: LoopSpec, analysis: MonitorConfig) -> dict[str, Any]:
    """One loop's outcome (module docstring); run in a worker process. Never raises for bad
    data: the outcome is then ``broken`` or ``refused`` with the reason."""
    outcome: dict[str, Any] = {"loop": name, "file": file, "pid": os.getpid()}
    try:
        result = assess_csv(
            file,
            spec.pv,
            spec.delay,
            spec.secondaries,
            setpoint=spec.sp,
            sep=spec.sep,
            decimal=spec.decimal,
            config=analysis,
            op=spec.op,
            op_limits=spec.op_limits,
            quality=spec.quality,
            good=spec.good,
            mode=spec.mode,
            auto=spec.auto,
            time=spec.time,
            start=spec.start,
            until=spec.until,
            window=spec.window,
            skip_rows=spec.skip_rows,
        )
    except QualityError as err:
        return {**outcome, "status": "refused", "reason": str(err), "flags": [err.check]}
    except (MonitorError, ValueError, OSError) as err:
        return {**outcome, "status": "broken", "reason": str(err), "flags": []}
    report = result.to_dict()
    h = report["harris"]
    osc = report["oscillation"] or {}
    scr = report["screening"] or {}
    y = np.asarray(result.analysed if result.analysed is not None else [], dtype=float)
    return {
        **outcome,
        "status": "assessed" if h["status"] == "ok" else "refused",
        "harris": h.get("index"),
        "ci": h.get("ci"),
        "std": h.get("std"),
        "above_one": h.get("above_one", False),
        "nonstationary": h.get("kind"),
        "reason": None if h["status"] == "ok" else f"{h['reason']}: {h['detail']}",
        "oscillating": bool(osc.get("oscillating")),
        "period": osc.get("period") if osc.get("oscillating") else None,
        "regularity": osc.get("regularity"),
        "amplitude": osc.get("amplitude") if osc.get("oscillating") else None,
        "flags": list(scr.get("flags", [])) + (["oscillation"] if osc.get("oscillating") else []),
        "cascade": report["recommendation"] if report["candidates"] else None,
        "rows": scr.get("rows"),
        "report": report,
        "plot": {
            "y": y[:_PLOT_SAMPLES].tolist(),
            "acf": acf(y, min(_PLOT_LAGS, y.size - 1)).tolist() if y.size > 2 else [],
        },
    }


@contextmanager
def _single_threaded_children() -> Iterator[None]:
    """Workers spawned inside start with one BLAS/OpenMP thread each, unless the user set the
    variables: forked or spawned workers with multithreaded OpenBLAS each spin their threads,
    and two such workers on two cores ran 4-9 times slower than one process (measured,
    bench/monitor_audit.py). The parent's environment is restored on exit."""
    saved = {k: os.environ.get(k) for k in _THREAD_VARS}
    for k in _THREAD_VARS:
        os.environ.setdefault(k, "1")
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _start_worker(barrier: Any) -> None:
    """Wait until every worker process has started, so that the loops spread over all."""
    try:
        barrier.wait(_START_TIMEOUT_S)
    except threading.BrokenBarrierError:
        log.warning("audit: not every worker started within %g s; going on", _START_TIMEOUT_S)


def run_audit(
    loops: Sequence[tuple[str, Path | None, LoopSpec | None, str | None]],
    analysis: MonitorConfig,
    *,
    jobs: int | None = None,
) -> list[dict[str, Any]]:
    """Assess every loop, in ``min(os.cpu_count(), loops, jobs)`` worker processes; outcomes in
    the order of ``loops`` (a loop with a problem is ``broken`` without being run)."""
    todo = [(i, lp) for i, lp in enumerate(loops) if lp[3] is None and lp[2] is not None]
    outcomes: dict[int, dict[str, Any]] = {
        i: {"loop": lp[0], "file": str(lp[1]), "status": "broken", "reason": lp[3], "flags": []}
        for i, lp in enumerate(loops)
        if lp[3] is not None or lp[2] is None
    }
    workers = max(1, min(os.cpu_count() or 1, len(todo), jobs or len(todo) or 1))
    if workers == 1 or len(todo) <= 1:
        for i, (name, file, spec, _) in todo:
            assert spec is not None and file is not None
            outcomes[i] = assess_loop(name, str(file), spec, analysis)
    else:
        ctx = multiprocessing.get_context("spawn")
        barrier = ctx.Barrier(workers)
        with (
            _single_threaded_children(),
            ProcessPoolExecutor(
                max_workers=workers, mp_context=ctx, initializer=_start_worker, initargs=(barrier,)
            ) as pool,
        ):
            futures: dict[int, Future[dict[str, Any]]] = {
                i: pool.submit(assess_loop, name, str(file), spec, analysis)
                for i, (name, file, spec, _) in todo
            }
            for i, fut in futures.items():
                try:
                    outcomes[i] = fut.result()
                except Exception as err:  # a worker's own failure: listed, the audit goes on
                    log.exception("audit: loop %s failed", loops[i][0])
                    outcomes[i] = {
                        "loop": loops[i][0],
                        "file": str(loops[i][1]),
                        "status": "broken",
                        "reason": f"internal error: {type(err).__name__}: {err}",
                        "flags": [],
                    }
    return [outcomes[i] for i in range(len(loops))]


def recommend(o: dict[str, Any], *, poor: float = 0.3, good: float = 0.7) -> str:
    """The recommended action for one outcome (what an engineer would do next)."""
    if o["status"] == "broken":
        return "fix the data or the configuration: " + str(o.get("reason"))
    acts: list[str] = []
    flags = set(o.get("flags", []))
    if "frozen" in flags or "compressed" in flags:
        acts.append("check the transmitter and the historian's compression of the tag")
    if "spike" in flags:
        acts.append("check the transmitter (spikes)")
    if "quality" in flags or "mode" in flags:
        acts.append("assess a period in auto with good quality")
    if "offset" in flags:
        acts.append("PV does not track SP: check the mode, the output limits and the ranging")
    if "saturation" in flags:
        acts.append("OP saturated: check the valve sizing and the output limits")
    if o["status"] == "refused":
        kind = o.get("nonstationary")
        acts.append(
            {
                "manual": "put the loop in automatic (in manual over the record)",
                "drift": "drifting record: assess a shorter window, find the slow disturbance",
                "integrating": "not stationary: pass the set point (sp:) if it moved, check the "
                "loop mode",
                "diverging": "unstable loop: detune it now",
            }.get(str(kind), "see the reason")
        )
        return "; ".join(dict.fromkeys(acts))
    idx = o.get("harris")
    if o.get("oscillating"):
        acts.append(
            f"sustained oscillation (period {o['period']:.3g} samples): check the valve for "
            "stiction (valve travel, bump test in manual), then the tuning"
        )
    elif idx is not None and idx < poor:
        acts.append(f"poor (index {idx:.2f} < {poor:g}): retune")
    elif idx is not None and idx >= good:
        acts.append("none: near minimum variance")
    else:
        acts.append("fair: review the tuning when convenient")
    cas = o.get("cascade")
    if cas and cas.get("cascade"):
        acts.append(cas["text"])
    return "; ".join(dict.fromkeys(acts))


def rank(outcomes: Sequence[dict[str, Any]], *, poor: float = 0.3, good: float = 0.7) -> list[dict]:
    """Outcomes ranked worst first (module docstring), each with ``rank`` and ``action``."""
    order = {"assessed": 0, "refused": 1, "broken": 2}

    def key(o: dict[str, Any]) -> tuple:
        idx = o.get("harris")
        return (order[o["status"]], idx if idx is not None else 0.0, o["loop"])

    out = []
    for k, o in enumerate(sorted(outcomes, key=key)):
        out.append({**o, "rank": k + 1, "action": recommend(o, poor=poor, good=good)})
    return out
