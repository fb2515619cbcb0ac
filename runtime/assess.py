"""``wncs assess``: the performance monitor on a CSV export or a recorded run (seed 004).

::

    wncs assess DATA --primary COL [--secondary COL[,COL...]] --delays d1,d2[,d1,d2...]
                [--setpoint COL] [--op COL] [--op-limits LO,HI]
                [--window N] [--start T] [--until T]          (run directories, and CSV files:
                [--time COL] [--skip-rows N]                   rows, or times of --time COL)
                [--sep ';'] [--decimal '.'] [--quality COL [--good V,...]] [--mode COL
                [--auto V,...]] [--screen CHECK=ACTION|SETTING=VALUE ...]     (CSV files)
                [--max-order P] [--order P] [--criterion aic|bic] [--method ls|yule_walker]
                [--out FILE]
    wncs assess DIR_OR_GLOB --config loops.yaml [--jobs N] [--plots N] [--out DIR]  (audit)

``DATA`` is a CSV file of routine data as historians export it (a header line, then one row per
sample; columns such as ``time;SP;PV;OP;T2``), or a run directory (``history.sqlite`` of a bus
run, or ``record.json`` of a direct run), whose columns are named as in
:mod:`agents.monitor.columns`: ``LOOP`` (the samples delivered to the loop's controller),
``LOOP.sp`` (its set point), ``PLANT.STATE`` (a plant state on its monitoring grid).

``--delays`` gives, per secondary in order, ``d1`` (samples from the secondary to the primary)
and ``d2`` (from the move to the secondary); every pair must add up to the same ``d``, the dead
time from the move to the primary. Without a secondary it is ``d`` alone (Harris index only).

Every assessment screens the data first (:mod:`agents.monitor.screening`; ``--screen
frozen=refuse`` sets a check's action, ``--screen spike_threshold=12`` a threshold) and reports
the oscillation diagnosis (:mod:`agents.monitor.oscillation`).

Exit codes (:func:`run`): 0 assessed; 2 bad input (the data refused, naming column and row; bad
arguments); 3 a part is unidentifiable (the Harris index or a candidate: printed with its reason,
the rest of the report is still written).

With ``--config`` (:mod:`agents.monitor.audit`) every loop of ``loops.yaml`` is assessed in
parallel processes and ranked, worst first, into ``DIR/audit/`` (or ``--out DIR``):
``audit.csv``, ``audit.json``, ``audit.html`` (:mod:`agents.monitor.audit_report`). Exit codes:
0 the table was written (bad files are listed in it with their reason); 2 a bad configuration or
nothing to assess; 1 the outputs cannot be written.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, TextIO

from pydantic import ValidationError

from agents.monitor.assess import DEFAULT_AUTO, DEFAULT_GOOD, assess_csv
from agents.monitor.audit import collect_loops, load_audit_config, rank, run_audit
from agents.monitor.audit_report import format_table, write_audit
from agents.monitor.columns import SP_SUFFIX
from agents.monitor.config import MonitorConfig, ScreeningConfig, SecondarySpec
from agents.monitor.errors import DataError
from agents.monitor.report import format_report
from agents.monitor.run_data import RunSeries, assess_series
from core.errors import ConfigError
from core.time import to_ticks
from runtime.history import read_meta
from runtime.run_files import feed_history, feed_record
from scenario import load_scenario
from scenario.views import run_shape

__all__ = [
    "add_assess_arguments",
    "parse_delays",
    "assess_path",
    "default_out",
    "run",
    "run_audit_command",
    "run_from_args",
]


def add_assess_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments of ``wncs assess`` (module docstring), added to its sub-parser."""
    parser.add_argument(
        "data",
        help="CSV file of routine data, or a run directory; with --config, a directory of CSV "
        "files or a glob (an audit of many loops)",
    )
    parser.add_argument("--primary", default=None, help="primary controlled variable (PV)")
    parser.add_argument(
        "--secondary",
        default="",
        help="candidate secondary measurements, COL[,COL...] (none: Harris index only)",
    )
    parser.add_argument(
        "--delays",
        default=None,
        help="d1,d2 per secondary in order (samples: secondary -> primary, move -> secondary; "
        "every pair adds up to the delay move -> primary), or d alone without a secondary",
    )
    parser.add_argument(
        "--setpoint", default=None, help="set-point column: analyse the control error SP - PV"
    )
    parser.add_argument(
        "--op", default=None, help="CSV: controller-output column (saturation, manual)"
    )
    parser.add_argument(
        "--op-limits", default=None, help="CSV: LO,HI of the controller output (default its range)"
    )
    parser.add_argument("--sep", default=";", help="CSV field separator (default ';')")
    parser.add_argument("--decimal", default=".", help="CSV decimal mark, '.' or ','")
    parser.add_argument(
        "--skip-rows",
        type=int,
        default=None,
        help="CSV: lines before the header (default: the first line naming every column)",
    )
    parser.add_argument(
        "--time",
        default=None,
        help="CSV: time column (numbers or ISO date-times); --start/--until are then times",
    )
    parser.add_argument(
        "--quality", default=None, help="CSV: quality column; rows not --good are screened"
    )
    parser.add_argument(
        "--good",
        default=",".join(DEFAULT_GOOD),
        help=f"values of --quality meaning good (default {','.join(DEFAULT_GOOD)})",
    )
    parser.add_argument(
        "--mode", default=None, help="CSV: mode column; rows not --auto are screened"
    )
    parser.add_argument(
        "--auto",
        default=",".join(DEFAULT_AUTO),
        help=f"values of --mode meaning automatic (default {','.join(DEFAULT_AUTO)})",
    )
    parser.add_argument(
        "--screen",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="data-quality screening: CHECK=warn|exclude|refuse (checks frozen, compressed, "
        "spike, quality, mode, offset, saturation) or a threshold (frozen_run, compressed_run, "
        "spike_threshold, offset_ratio, saturation_fraction); repeatable",
    )
    parser.add_argument(
        "--window",
        type=int,
        default=None,
        help="the last N samples delivered (run) or rows (CSV) (default all)",
    )
    parser.add_argument(
        "--start",
        default=None,
        help="run: ignore samples taken before this time; CSV: first data row (1-based), or "
        "first time with --time",
    )
    parser.add_argument(
        "--until",
        default=None,
        help="run: samples delivered before this time (default the run's end time); CSV: rows "
        "before this row, or before this time with --time",
    )
    parser.add_argument("--max-order", type=int, default=30, help="largest AR/VAR order tried")
    parser.add_argument("--order", type=int, default=None, help="fixed AR/VAR order")
    parser.add_argument(
        "--criterion",
        choices=("aic", "bic"),
        default="aic",
        help="information criterion that picks the AR/VAR order (default aic)",
    )
    parser.add_argument(
        "--method",
        choices=("ls", "yule_walker"),
        default="ls",
        help="AR/VAR estimator: least squares or Yule-Walker (default ls)",
    )
    parser.add_argument(
        "--config",
        default=None,
        help="loops.yaml: audit every loop it lists (and the files its defaults fit)",
    )
    parser.add_argument(
        "--jobs", type=int, default=None, help="audit: worker processes (default: the cores)"
    )
    parser.add_argument(
        "--plots", type=int, default=20, help="audit: loops plotted in audit.html (worst first)"
    )
    parser.add_argument(
        "--out",
        default=None,
        help="JSON report (default next to the data: "
        "NAME.assessment.json, or RUN_DIR/assessment_PRIMARY.json); audit: output directory "
        "(default DIR/audit)",
    )


def parse_delays(text: str, secondaries: list[str]) -> tuple[int, list[SecondarySpec]]:
    """``d`` and the candidate specs from ``--delays`` (module docstring).

    Raises
    ------
    ValueError
        Naming what is wrong.
    """
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"--delays: expected integers separated by ',', got {text!r}") from None
    if not secondaries:
        if len(values) != 1:
            raise ValueError(
                f"--delays: without --secondary give d alone (samples from the move to the "
                f"primary), got {len(values)} numbers"
            )
        if values[0] < 1:
            raise ValueError(f"--delays: d must be >= 1 sample, got {values[0]}")
        return values[0], []
    if len(values) != 2 * len(secondaries):
        raise ValueError(
            f"--delays: give d1,d2 for each of the {len(secondaries)} secondaries "
            f"({', '.join(secondaries)}), i.e. {2 * len(secondaries)} numbers; got {len(values)}"
        )
    specs = []
    for i, name in enumerate(secondaries):
        d1, d2 = values[2 * i], values[2 * i + 1]
        if d1 < 0 or d2 < 1:
            raise ValueError(
                f"--delays: secondary {name!r}: d1 must be >= 0 and d2 >= 1, got {d1},{d2}"
            )
        if specs and d1 + d2 != specs[0].d1 + specs[0].d2:
            raise ValueError(
                f"--delays: secondary {name!r}: d1 + d2 = {d1 + d2}, but {specs[0].name!r} gives "
                f"{specs[0].d1 + specs[0].d2}: every pair must add up to the delay from the move "
                "to the primary"
            )
        specs.append(SecondarySpec(name=name, d1=d1, d2=d2))
    return specs[0].d1 + specs[0].d2, specs


def default_out(data: Path, primary: str) -> Path:
    """Where the JSON report goes by default: next to the data."""
    if data.is_dir():
        return data / f"assessment_{primary}.json"
    return data.with_name(data.stem + ".assessment.json")


def assess_path(
    data: str | Path,
    primary: str,
    delay: int,
    secondaries: list[SecondarySpec],
    *,
    setpoint: str | None = None,
    sep: str = ";",
    decimal: str = ".",
    window: int | None = None,
    start: str | float | None = None,
    until: str | float | None = None,
    config: MonitorConfig | None = None,
    **csv_options: Any,
) -> dict[str, Any]:
    """The JSON report of one assessment of ``data`` (a CSV file or a run directory).

    ``csv_options`` go to :func:`agents.monitor.assess.assess_csv` (``op``, ``op_limits``,
    ``quality``, ``good``, ``mode``, ``auto``, ``time``, ``skip_rows``); they do not apply to a
    run directory.

    Raises
    ------
    DataError
        Data refused (naming the column and row), unknown columns, not a run directory.
    ValueError
        Options that do not apply to this kind of data.
    """
    cfg = config or MonitorConfig()
    path = Path(data)
    if not path.exists():
        raise DataError(f"{str(path)!r} does not exist (a CSV file or a run directory)")
    if not path.is_dir():
        result = assess_csv(
            path,
            primary,
            delay,
            secondaries,
            setpoint=setpoint,
            sep=sep,
            decimal=decimal,
            config=cfg,
            start=start,
            until=until,
            window=window,
            **csv_options,
        )
        return {
            **result.to_dict(),
            "setpoint": setpoint,
            "data": {"kind": "csv", "path": str(path), "rows": result.n_samples},
        }
    for key, value in csv_options.items():
        if value not in (None, "", DEFAULT_GOOD, DEFAULT_AUTO):
            raise ValueError(f"--{key.replace('_', '-')} applies to CSV files, not to a run")
    times = []
    for flag, value in (("--start", start), ("--until", until)):
        try:
            times.append(None if value is None else float(value))
        except ValueError:
            raise ValueError(f"{flag}: a run's time is a number, got {value!r}") from None
    return _assess_run(path, primary, delay, secondaries, setpoint, window, *times, cfg)


def _assess_run(
    run_dir: Path,
    primary: str,
    delay: int,
    secondaries: list[SecondarySpec],
    setpoint: str | None,
    window: int | None,
    start: float | None,
    until: float | None,
    cfg: MonitorConfig,
) -> dict[str, Any]:
    scen_file = run_dir / "scenario.yaml"
    if not scen_file.exists():
        raise DataError(f"{str(run_dir)!r} is not a run directory (no scenario.yaml)")
    scenario = load_scenario(scen_file)
    if setpoint is not None and setpoint != primary + SP_SUFFIX:
        raise ValueError(
            f"--setpoint: in a run directory the set point of loop {primary!r} is "
            f"{primary + SP_SUFFIX!r}, got {setpoint!r}"
        )
    if window is not None and window < 1:
        raise ValueError(f"--window: must be >= 1 samples, got {window}")
    t_until = to_ticks(scenario.end_time if until is None else until)
    columns = ([setpoint] if setpoint else []) + [s.name for s in secondaries]
    series = RunSeries(
        run_shape(scenario), primary, columns, start=to_ticks(start or 0.0), window=window
    )
    engine = "direct"
    if (run_dir / "history.sqlite").exists():
        engine = read_meta(run_dir / "history.sqlite").get("engine", "?")
        feed_history(run_dir / "history.sqlite", series, until=t_until)
    elif (run_dir / "record.json").exists():
        feed_record(run_dir / "record.json", series, until=t_until)
    else:
        raise DataError(f"{str(run_dir)!r} has neither history.sqlite nor record.json")
    result, info = assess_series(
        series,
        delay,
        secondaries,
        setpoint=setpoint is not None,
        config=cfg,
        source=str(run_dir),
    )
    return {
        **result.to_dict(),
        "setpoint": setpoint,
        "data": {"kind": "run", "path": str(run_dir), "engine": engine},
        "window": info.to_dict(t_until, scenario.time_unit),
    }


def unidentified(report: dict[str, Any]) -> list[str]:
    """The parts of a report that could not be identified, each with its reason."""
    out = []
    h = report["harris"]
    if h["status"] != "ok":
        out.append(f"Harris index of {report['primary']!r}: {h['reason']} ({h['detail']})")
    for c in report["candidates"]:
        if c["status"] != "ok":
            out.append(f"secondary {c['name']!r}: {c['reason']} ({c['detail']})")
    return out


def run(
    data: str,
    *,
    primary: str,
    secondaries: list[str],
    delays: str,
    out: str | None = None,
    stdout: TextIO | None = None,
    stderr: TextIO | None = None,
    **options: Any,
) -> int:
    """``wncs assess``: assess, print, write the JSON report; return the exit code."""
    stdout = stdout or sys.stdout
    stderr = stderr or sys.stderr
    try:
        delay, specs = parse_delays(delays, secondaries)
        report = assess_path(data, primary, delay, specs, **options)
    except (DataError, ConfigError, ValueError) as err:
        print(f"wncs assess: {err}", file=stderr)
        return 2
    path = Path(out) if out else default_out(Path(data), primary)
    try:
        path.write_text(json.dumps(report, indent=1, allow_nan=False) + "\n")
    except OSError as err:
        print(f"wncs assess: cannot write the report {str(path)!r}: {err}", file=stderr)
        return 1
    print(format_report(report), file=stdout)
    print(f"report written to {path}", file=stdout)
    bad = unidentified(report)
    for line in bad:
        print(f"wncs assess: unidentifiable: {line}", file=stderr)
    return 3 if bad else 0


def _pairs(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise ValueError(f"--screen: expected KEY=VALUE, got {item!r}")
        out[key.strip()] = value.strip()
    return out


def _limits(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--op-limits: expected LO,HI, got {text!r}") from None
    if not lo < hi:
        raise ValueError(f"--op-limits: LO must be below HI, got {text!r}")
    return lo, hi


def _words(text: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in text.split(",") if v.strip())


def run_from_args(args: argparse.Namespace, **streams: TextIO) -> int:
    """``wncs assess`` from the parsed arguments of :func:`add_assess_arguments`."""
    stderr = streams.get("stderr") or sys.stderr
    try:
        pairs = _pairs(args.screen)
        op_limits = _limits(args.op_limits)
    except ValueError as err:
        print(f"wncs assess: {err}", file=stderr)
        return 2
    try:
        screening = ScreeningConfig(**pairs)
    except ValidationError as err:
        e = err.errors()[0]
        print(f"wncs assess: --screen {e['loc'][0]}: {e['msg']}", file=stderr)
        return 2
    try:
        config = MonitorConfig(
            max_order=args.max_order,
            order=args.order,
            criterion=args.criterion,
            method=args.method,
            screening=screening,
        )
    except ValidationError as err:
        e = err.errors()[0]
        print(f"wncs assess: --{str(e['loc'][0]).replace('_', '-')}: {e['msg']}", file=stderr)
        return 2
    if args.config is not None:
        return run_audit_command(
            args.data,
            args.config,
            out=args.out,
            jobs=args.jobs,
            plots=args.plots,
            screening=screening if args.screen else None,
            **streams,
        )
    for flag, value in (("--primary", args.primary), ("--delays", args.delays)):
        if value is None:
            print(
                f"wncs assess: error: the following arguments are required: {flag} (or "
                "--config loops.yaml for an audit)",
                file=stderr,
            )
            raise SystemExit(2)
    secondaries = [s.strip() for s in args.secondary.split(",") if s.strip()]
    return run(
        args.data,
        primary=args.primary,
        secondaries=secondaries,
        delays=args.delays,
        out=args.out,
        setpoint=args.setpoint,
        sep=args.sep,
        decimal=args.decimal,
        window=args.window,
        start=args.start,
        until=args.until,
        config=config,
        op=args.op,
        op_limits=op_limits,
        quality=args.quality,
        good=_words(args.good),
        mode=args.mode,
        auto=_words(args.auto),
        time=args.time,
        skip_rows=args.skip_rows,
        **streams,
    )


def run_audit_command(
    target: str,
    config: str,
    *,
    out: str | None = None,
    jobs: int | None = None,
    plots: int = 20,
    screening: ScreeningConfig | None = None,
    stdout: TextIO | None = None,
    stderr: TextIO | None = None,
) -> int:
    """``wncs assess DIR_OR_GLOB --config loops.yaml``: audit, print the ranking, write the
    outputs; return the exit code (module docstring)."""
    stdout = stdout or sys.stdout
    stderr = stderr or sys.stderr
    try:
        cfg, specs = load_audit_config(config)
    except DataError as err:
        print(f"wncs assess: {err}", file=stderr)
        return 2
    if jobs is not None and jobs < 1:
        print(f"wncs assess: --jobs: must be >= 1, got {jobs}", file=stderr)
        return 2
    analysis = cfg.analysis
    if screening is not None:
        analysis = analysis.model_copy(update={"screening": screening})
    loops, unconfigured = collect_loops(target, cfg, specs)
    if not loops:
        print(
            f"wncs assess: nothing to audit: {target!r} has no CSV file that {config} names "
            "(or whose columns its defaults give)",
            file=stderr,
        )
        return 2
    ranked = rank(run_audit(loops, analysis, jobs=jobs), poor=cfg.poor, good=cfg.good)
    base = Path(target) if Path(target).is_dir() else Path(config).parent
    out_dir = Path(out) if out else base / "audit"
    try:
        paths = write_audit(
            ranked,
            out_dir,
            unconfigured=[str(f) for f in unconfigured],
            poor=cfg.poor,
            good=cfg.good,
            plotted=plots,
            title=f"Loop audit of {target}",
        )
    except OSError as err:
        print(f"wncs assess: cannot write the audit to {str(out_dir)!r}: {err}", file=stderr)
        return 1
    print(format_table(ranked), file=stdout)
    for o in ranked:
        if o["status"] == "broken":
            print(f"wncs assess: {o['loop']} ({o['file']}): {o['reason']}", file=stderr)
    pids = {o["pid"] for o in ranked if "pid" in o}
    print(
        f"{len(ranked)} loops ({sum(o['status'] == 'broken' for o in ranked)} broken) in "
        f"{len(pids)} processes; written {paths['csv']}, {paths['json']}, {paths['html']}",
        file=stdout,
    )
    return 0
