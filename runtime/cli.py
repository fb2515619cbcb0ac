"""The ``wncs`` command line.

``wncs run SCENARIO --out DIR``        run a scenario (engines: processes, threads, direct)
``wncs node SCENARIO NAME --connect EP --run-id ID``   run one node of the graph (or ``clock``)
``wncs report DIR``                    redraw a run's plots and print its figures
``wncs analyze SCENARIO --out DIR``    the coordination agent's analysis alone, without the bus
``wncs assess DATA --primary COL ...``  Harris index and cascade opportunities of a loop (seed 004)

Exit codes: 0 success, 2 bad input (scenario, arguments), 3 the run was stopped by a fault,
1 any other failure.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
from pathlib import Path
from typing import Any

from agents.monitor.command import add_assess_arguments, run_from_args
from agents.wncsca.timeline import format_timeline
from core.errors import ConfigError, SchemaError, WncsError
from kernel.bus import open_client
from runtime.analysis import analyze, parse_delays
from runtime.artefacts import RUN_FILE, SCENARIO_FILE
from runtime.history import load_record
from runtime.inject import build_request, send
from runtime.launcher import launch
from runtime.nodes import bus_node, check_node, clock_runner
from runtime.report import load_saved_record, write_plots, write_summary
from runtime.scenario import load_scenario

__all__ = ["main", "build_parser"]

log = logging.getLogger("wncs")


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="wncs", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="run a scenario and write its artefacts to DIR")
    run.add_argument("scenario", help="scenario YAML file")
    run.add_argument("--out", required=True, help="output directory")
    run.add_argument("--engine", choices=("processes", "threads", "direct"), default="processes")
    run.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    run.add_argument(
        "--listen", default=None, help="endpoint of the embedded router (default tcp/127.0.0.1:0)"
    )
    run.add_argument(
        "--realtime",
        type=_positive_float,
        default=None,
        metavar="SECONDS_PER_UNIT",
        help="pace virtual time against the wall clock",
    )
    run.add_argument("--quiet", action="store_true", help="print only errors")

    node = sub.add_parser("node", help="run one node of a scenario's graph")
    node.add_argument("scenario")
    node.add_argument("name", help="node name, or 'clock' / 'historian'")
    node.add_argument("--connect", required=True, help="router endpoint, e.g. tcp/127.0.0.1:7447")
    node.add_argument("--run-id", required=True)
    node.add_argument("--seed", type=int, default=None)
    node.add_argument("--out", default=".", help="historian: directory of history.sqlite")
    node.add_argument("--engine", default="processes", help="historian: engine recorded in meta")
    node.add_argument(
        "--realtime",
        type=_positive_float,
        default=None,
        metavar="SECONDS_PER_UNIT",
        help="clock: real-time pacing",
    )

    report = sub.add_parser("report", help="redraw a run's plots and print its figures")
    report.add_argument("dir")

    analyze = sub.add_parser(
        "analyze", help="the coordination agent's decision and periods, without the bus"
    )
    analyze.add_argument("scenario")
    analyze.add_argument(
        "--delays",
        default=None,
        help="control-path delays, loop=value,... (default: from the scenario's networks)",
    )
    analyze.add_argument("--method", choices=("paper", "fast"), default=None)
    analyze.add_argument("--out", required=True, help="output directory")

    inject = sub.add_parser(
        "inject",
        help="inject a network reconfiguration, a mode or a set point into a running run",
        description="wncs inject DIR EVENT [KEY=VALUE ...]  (or --listen EP --run-id ID EVENT ...)."
        " Events: node_down node=N | node_up node=N | link_degraded a=N b=M prr=P |"
        " delay_model_changed delay=JSON [link=JSON] | relay_added node=N links=JSON |"
        " node_moved node=N links=JSON | mode MODE (to the coordination agent) |"
        " setpoint LOOP=VALUE",
    )
    inject.add_argument("words", nargs="+", help="DIR EVENT [KEY=VALUE ...]")
    inject.add_argument("--network", default=None, help="gateway node (default: the only one)")
    inject.add_argument("--listen", default=None, help="router endpoint, instead of DIR")
    inject.add_argument("--run-id", default=None, help="run id, with --listen")

    assess = sub.add_parser(
        "assess",
        help="Harris index and cascade opportunities of a loop from routine data (seed 004)",
        description="Assess a simple-feedback loop from routine data: its Harris index with its "
        "uncertainty and, per candidate secondary, the variance components 1a/1b/2a/2b and the "
        "predicted variance under cascade control. DATA is a CSV file (columns as exported by a "
        "historian) or a run directory (columns LOOP, LOOP.sp, PLANT.STATE). Exit codes: 0 "
        "assessed, 2 bad input, 3 a part unidentifiable.",
    )
    add_assess_arguments(assess)
    return parser


def _table(summary: dict[str, Any]) -> str:
    unit = summary.get("time_unit", "")
    rows = [f"{'loop':<14}{'overshoot %':>12}{'settling ' + unit:>14}{'IAE':>12}"]
    for name, lp in summary["loops"].items():
        os_ = lp["overshoot_pct"]
        st = lp["settling_time"]
        rows.append(
            f"{name:<14}{'-' if os_ is None else f'{os_:.2f}':>12}"
            f"{'not settled' if st is None else f'{st:.3f}':>14}"
            f"{'-' if lp['iae'] is None else format(lp['iae'], '.4g'):>12}"
        )
    return "\n".join(rows)


def _cmd_run(args: argparse.Namespace) -> int:
    def _terminate(signum: int, frame: object) -> None:
        raise KeyboardInterrupt  # unwinds the launcher, which stops its children

    signal.signal(signal.SIGTERM, _terminate)
    stream = sys.stdout if (sys.stdout.isatty() and not args.quiet) else None
    result = launch(
        args.scenario,
        args.out,
        engine=args.engine,
        seed=args.seed,
        listen=args.listen,
        realtime=args.realtime,
        progress=stream,
    )
    if result.code != 0:
        print(f"wncs run: {result.error}", file=sys.stderr)
        return result.code
    if not args.quiet:
        s = result.summary
        print(
            f"{s['scenario']} ({s['engine']} engine, seed {s['seed']}): "
            f"{s['end_time']:g} {s['time_unit']} in {s['wall_s']:.2f} s wall time"
        )
        print(_table(s))
        if "wncsca" in s:
            print("\ncoordination agent (WNCSCA) timeline:")
            print(format_timeline(s))
        pngs = sorted(p.name for p in Path(args.out).glob("*.png"))
        print(f"\nartefacts in {Path(args.out).resolve()}: summary.json, " + ", ".join(pngs))
    return 0


def _cmd_node(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario)
    if args.seed is not None:
        scenario = scenario.model_copy(update={"seed": args.seed})
    if args.name != "clock":
        try:
            check_node(scenario, args.name)
        except KeyError as err:
            raise ConfigError(str(err.args[0])) from err
    session = open_client(args.connect)
    try:
        if args.name == "clock":
            return clock_runner(scenario, session, args.run_id, realtime=args.realtime).run()
        options = {"out": args.out, "engine": args.engine}
        return bus_node(scenario, args.name, args.run_id, session, options).run()
    finally:
        session.close()


def _cmd_report(args: argparse.Namespace) -> int:
    out = Path(args.dir)
    try:
        info = json.loads((out / RUN_FILE).read_text())
    except (OSError, ValueError) as err:
        raise ConfigError(f"{out / RUN_FILE}: not a run directory ({err})") from err
    scenario = load_scenario(out / SCENARIO_FILE)
    if (out / "history.sqlite").exists():
        rec = load_record(out / "history.sqlite", scenario, engine=info["engine"])
    else:
        rec = load_saved_record(out)
    old = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    rec.wall_s = old.get("wall_s", 0.0)
    rec.phases = old.get("phases_s", {})
    if (out / "history.sqlite").exists() and "messages" in old:
        rec.dropped_invalid = old["messages"].get("dropped_invalid", {})
    summary = write_summary(rec, out)
    paths = write_plots(rec, out, scenario=scenario)
    print(_table(summary))
    if "wncsca" in summary:
        print(format_timeline(summary))
    print("plots: " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_analyze(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario)
    try:
        delays = None if args.delays is None else parse_delays(args.delays, scenario.loops)
    except ValueError as err:
        raise ConfigError(str(err)) from err
    out = Path(args.out)
    summary = analyze(scenario, delays=delays, method=args.method, out=out)
    w = summary["wncsca"]
    for name, b in w["bounds"].items():
        print(f"{name}: largest tolerable delay at the benchmark periods {b['tau_d_max']:.4g}")
    print(format_timeline(summary))
    print(f"artefacts in {out}: summary.json" + (", search.png" if w["assignments"] else ""))
    return 0


def _cmd_inject(args: argparse.Namespace) -> int:
    words = list(args.words)
    run_dir = None
    if args.listen is not None:
        if not args.run_id:
            raise ConfigError("--listen needs --run-id")
        endpoint, run_id = args.listen, args.run_id
    else:
        if len(words) < 2:
            raise ConfigError("usage: wncs inject DIR EVENT [KEY=VALUE ...]")
        run_dir = Path(words.pop(0))
        try:
            info = json.loads((run_dir / RUN_FILE).read_text())
        except (OSError, ValueError) as err:
            raise ConfigError(f"{run_dir / RUN_FILE}: not a running run ({err})") from err
        endpoint, run_id = info.get("endpoint"), info["run_id"]
        if not endpoint:
            raise ConfigError(f"{run_dir / RUN_FILE}: the run has no bus (direct engine)")
    request = build_request(words[0], words[1:], run_dir=run_dir, network=args.network)
    send(endpoint, run_id, request)
    what = request.event or (
        f"mode {request.mode}" if request.mode is not None else f"set point {request.setpoint}"
    )
    print(f"injected {what} into run {run_id}")
    return 0


def _cmd_assess(args: argparse.Namespace) -> int:
    return run_from_args(args)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.INFO if args.command == "node" else logging.WARNING
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        commands = {
            "run": _cmd_run,
            "node": _cmd_node,
            "report": _cmd_report,
            "inject": _cmd_inject,
            "analyze": _cmd_analyze,
            "assess": _cmd_assess,
        }
        return commands[args.command](args)
    except ConfigError as err:
        print(f"wncs {args.command}: {err}", file=sys.stderr)
        return 2
    except (WncsError, SchemaError) as err:
        print(f"wncs {args.command}: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
