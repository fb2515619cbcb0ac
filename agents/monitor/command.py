"""``wncs assess``: the performance monitor on a CSV export or a recorded run (seed 004).

::

    wncs assess DATA --primary COL [--secondary COL[,COL...]] --delays d1,d2[,d1,d2...]
                [--setpoint COL] [--sep ';'] [--decimal '.']                 (CSV files)
                [--window N] [--start T] [--until T]                        (run directories)
                [--max-order P] [--order P] [--criterion aic|bic] [--method ls|yule_walker]
                [--out FILE]

``DATA`` is a CSV file of routine data as historians export it (a header line, then one row per
sample; columns such as ``time;SP;PV;OP;T2``), or a run directory (``history.sqlite`` of a bus
run, or ``record.json`` of a direct run), whose columns are named as in
:mod:`agents.monitor.run_data`: ``LOOP`` (the samples delivered to the loop's controller),
``LOOP.sp`` (its set point), ``PLANT.STATE`` (a plant state on its monitoring grid).

``--delays`` gives, per secondary in order, ``d1`` (samples from the secondary to the primary)
and ``d2`` (from the move to the secondary); every pair must add up to the same ``d``, the dead
time from the move to the primary. Without a secondary it is ``d`` alone (Harris index only).

Exit codes (:func:`run`): 0 assessed; 2 bad input (the data refused, naming column and row; bad
arguments); 3 a part is unidentifiable (the Harris index or a candidate: printed with its reason,
the rest of the report is still written).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, TextIO

from pydantic import ValidationError

from agents.monitor.config import MonitorConfig, SecondarySpec

__all__ = [
    "add_assess_arguments",
    "parse_delays",
    "assess_path",
    "default_out",
    "run",
    "run_from_args",
]


def add_assess_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments of ``wncs assess`` (module docstring), added to its sub-parser."""
    parser.add_argument("data", help="CSV file of routine data, or a run directory")
    parser.add_argument("--primary", required=True, help="primary controlled variable (PV)")
    parser.add_argument(
        "--secondary",
        default="",
        help="candidate secondary measurements, COL[,COL...] (none: Harris index only)",
    )
    parser.add_argument(
        "--delays",
        required=True,
        help="d1,d2 per secondary in order (samples: secondary -> primary, move -> secondary; "
        "every pair adds up to the delay move -> primary), or d alone without a secondary",
    )
    parser.add_argument(
        "--setpoint", default=None, help="set-point column: analyse the control error SP - PV"
    )
    parser.add_argument("--sep", default=";", help="CSV field separator (default ';')")
    parser.add_argument("--decimal", default=".", help="CSV decimal mark, '.' or ','")
    parser.add_argument(
        "--window", type=int, default=None, help="run: the last N samples delivered (default all)"
    )
    parser.add_argument(
        "--start", type=float, default=None, help="run: ignore samples taken before this time"
    )
    parser.add_argument(
        "--until",
        type=float,
        default=None,
        help="run: samples delivered before this time (default the run's end time)",
    )
    parser.add_argument("--max-order", type=int, default=30, help="largest AR/VAR order tried")
    parser.add_argument("--order", type=int, default=None, help="fixed AR/VAR order")
    parser.add_argument("--criterion", choices=("aic", "bic"), default="aic")
    parser.add_argument("--method", choices=("ls", "yule_walker"), default="ls")
    parser.add_argument(
        "--out",
        default=None,
        help="JSON report (default next to the data: "
        "NAME.assessment.json, or RUN_DIR/assessment_PRIMARY.json)",
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
    start: float | None = None,
    until: float | None = None,
    config: MonitorConfig | None = None,
) -> dict[str, Any]:
    """The JSON report of one assessment of ``data`` (a CSV file or a run directory).

    Raises
    ------
    DataError
        Data refused (naming the column and row), unknown columns, not a run directory.
    ValueError
        Options that do not apply to this kind of data.
    """
    from agents.monitor.errors import DataError

    cfg = config or MonitorConfig()
    path = Path(data)
    if not path.exists():
        raise DataError(f"{str(path)!r} does not exist (a CSV file or a run directory)")
    if not path.is_dir():
        from agents.monitor.assess import assess_csv

        for flag, value in (("--window", window), ("--start", start), ("--until", until)):
            if value is not None:
                raise ValueError(f"{flag} applies to run directories, not to a CSV file")
        result = assess_csv(
            path,
            primary,
            delay,
            secondaries,
            setpoint=setpoint,
            sep=sep,
            decimal=decimal,
            config=cfg,
        )
        return {
            **result.to_dict(),
            "setpoint": setpoint,
            "data": {"kind": "csv", "path": str(path), "rows": result.n_samples},
        }
    return _assess_run(path, primary, delay, secondaries, setpoint, window, start, until, cfg)


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
    from agents.monitor.errors import DataError
    from agents.monitor.run_data import (
        SP_SUFFIX,
        RunSeries,
        assess_series,
        feed_history,
        feed_record,
    )
    from runtime.scenario import load_scenario
    from runtime.time import to_ticks

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
    series = RunSeries(scenario, primary, columns, start=to_ticks(start or 0.0), window=window)
    engine = "direct"
    if (run_dir / "history.sqlite").exists():
        from runtime.history import read_meta

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
    from agents.monitor.errors import DataError
    from agents.monitor.report import format_report
    from runtime.errors import ConfigError

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


def run_from_args(args: argparse.Namespace, **streams: TextIO) -> int:
    """``wncs assess`` from the parsed arguments of :func:`add_assess_arguments`."""
    stderr = streams.get("stderr") or sys.stderr
    try:
        config = MonitorConfig(
            max_order=args.max_order,
            order=args.order,
            criterion=args.criterion,
            method=args.method,
        )
    except ValidationError as err:
        e = err.errors()[0]
        print(f"wncs assess: --{str(e['loc'][0]).replace('_', '-')}: {e['msg']}", file=stderr)
        return 2
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
        **streams,
    )
