"""The commands that read or act on a run: ``wncs report``, ``wncs export``, ``wncs inject``,
``wncs dashboard`` and ``wncs assess``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from agents.wncsca.timeline import format_timeline
from cli.bus import add_plots, table
from cli.table import Command
from core.errors import ConfigError
from dashboard import command as dashboard_command
from kernel.security import client_settings, read_credential
from runtime.artefacts import RUN_FILE
from runtime.assess import add_assess_arguments, run_from_args
from runtime.export import export_run
from runtime.inject import build_request, send
from runtime.report import load_run, write_plots, write_summary
from runtime.security import INJECT, login_of

__all__ = ["REPORT", "INJECT_COMMAND", "DASHBOARD", "ASSESS", "EXPORT"]


def _add_report(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dir", metavar="DIR", help="run directory written by wncs run")
    add_plots(parser)


def _report(args: argparse.Namespace) -> int:
    out = Path(args.dir)
    scenario, rec = load_run(out)
    old = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    rec.wall_s = old.get("wall_s", 0.0)
    rec.phases = old.get("phases_s", {})
    if (out / "history.sqlite").exists() and "messages" in old:
        rec.dropped_invalid = old["messages"].get("dropped_invalid", {})
    summary = write_summary(rec, out)
    paths = write_plots(rec, out, scenario=scenario, plots=args.plots, summary=summary)
    print(table(summary))
    if "wncsca" in summary:
        print(format_timeline(summary))
    print("plots: " + ", ".join(str(p) for p in paths))
    return 0


REPORT = Command(
    "report",
    "redraw a run's plots and print its figures",
    _add_report,
    _report,
    examples=("wncs report runs/bench",),
)


def _add_inject(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "words",
        nargs="+",
        metavar="WORD",
        help="DIR EVENT [KEY=VALUE ...], or EVENT [KEY=VALUE ...] with --listen",
    )
    parser.add_argument("--network", default=None, help="gateway node (default: the only one)")
    parser.add_argument(
        "--listen", default=None, metavar="ENDPOINT", help="router endpoint, instead of DIR"
    )
    parser.add_argument("--run-id", default=None, help="run id, with --listen")
    parser.add_argument(
        "--credentials",
        default=None,
        metavar="FILE",
        help="the inject identity's credential file of a secure run (default with DIR: "
        "DIR/security/inject.json)",
    )


def _inject(args: argparse.Namespace) -> int:
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
    creds = None
    if args.credentials:
        creds = client_settings(read_credential(Path(args.credentials)))
    elif run_dir is not None:
        creds = login_of(run_dir, INJECT)
    send(endpoint, run_id, request, settings=creds)
    what = request.event or (
        f"mode {request.mode}" if request.mode is not None else f"set point {request.setpoint}"
    )
    print(f"injected {what} into run {run_id}")
    return 0


INJECT_COMMAND = Command(
    "inject",
    "inject a network reconfiguration, a mode or a set point into a running run",
    _add_inject,
    _inject,
    examples=(
        "wncs inject runs/wsn node_down node=r1",
        "wncs inject runs/wncs mode steady_state",
        "wncs inject runs/wncs setpoint level=0.72",
    ),
    description=(
        "Send an event to a running run's clock, which stamps it into its next round. The run\n"
        "is named by its directory (its run.json), or by --listen ENDPOINT --run-id ID.\n"
        "\n"
        "events:\n"
        "  node_down node=N, node_up node=N, link_degraded a=N b=M prr=P,\n"
        "  delay_model_changed delay=JSON [link=JSON], relay_added node=N links=JSON,\n"
        "  node_moved node=N links=JSON  (to the gateway, --network when there are several)\n"
        "  mode MODE                     (to the coordination agent)\n"
        "  setpoint LOOP=VALUE\n"
        "\n"
        "An unknown event, field, node, mode or loop is refused (exit 2) before anything is sent."
    ),
)

DASHBOARD = Command(
    "dashboard",
    "watch a live run in the browser, act on it, replay it",
    dashboard_command.add_arguments,
    dashboard_command.run,
    examples=(
        "wncs dashboard runs/wncs",
        "wncs dashboard runs/wncs --port 8800",
        "wncs run scenarios/jcstr_wncs.yaml --out runs/live --realtime 0.5 --dashboard",
    ),
    description=(
        "Serve a web page on 127.0.0.1 that shows a run as it goes on (its history, read as "
        "the historian commits it): the WSN topology with batteries, link quality and the "
        "routes in force; each loop's output against its set point with the delivered samples "
        "and the moves; each path's delay and losses; the sampling periods with the open "
        "intervals shaded; the coordination agent's decisions with their reasons; invalid "
        "messages dropped; simulated against wall time; the TSCH schedule. Its buttons send "
        "what wncs inject sends. A finished run is replayed with a time slider."
    ),
)

ASSESS = Command(
    "assess",
    "Harris index and cascade opportunities of a loop from routine data (seed 004)",
    add_assess_arguments,
    run_from_args,
    examples=(
        "wncs assess loop.csv --primary PV --setpoint SP --secondary T2,T3 --delays 5,2,6,1",
        "wncs assess runs/cr --primary temperature --secondary reactor.y2,reactor.y3"
        " --delays 3,1,3,1",
    ),
    description=(
        "Assess a simple-feedback loop from routine data: its Harris index with its "
        "uncertainty and, per candidate secondary, the variance components 1a/1b/2a/2b and the "
        "predicted variance under cascade control. DATA is a CSV file (columns as exported by a "
        "historian) or a run directory (columns LOOP, LOOP.sp, PLANT.STATE). Exit codes: 0 "
        "assessed, 2 bad input, 3 a part unidentifiable."
    ),
)


def _add_export(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dir", metavar="RUN_DIR", help="run directory written by wncs run")
    fmt = parser.add_mutually_exclusive_group(required=True)
    fmt.add_argument("--csv", action="store_true", help="write CSV files")
    fmt.add_argument("--parquet", action="store_true", help="write Parquet files (pyarrow)")
    parser.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="output directory (default RUN_DIR/csv or RUN_DIR/parquet)",
    )


def _export(args: argparse.Namespace) -> int:
    fmt = "parquet" if args.parquet else "csv"
    written = export_run(args.dir, args.out, fmt=fmt)
    where = written[0].parent if written else Path(args.out or Path(args.dir) / fmt)
    print(
        f"wrote {len(written)} {fmt.upper()} files to {where}: "
        + ", ".join(p.name for p in written)
    )
    return 0


EXPORT = Command(
    "export",
    "write every artefact of a run as CSV or Parquet files",
    _add_export,
    _export,
    examples=(
        "wncs export runs/bench --csv",
        "wncs export runs/wncs --csv --out runs/wncs_csv",
        "wncs export runs/bench --parquet",
    ),
    description=(
        "Write every artefact of a run as CSV (or Parquet) files: per loop its trace "
        "(loop_LOOP.csv: t, t_sampled, y, setpoint, u), per plant its states (plant_PLANT.csv), "
        "the network's path statistics (network_paths.csv) and, with a WSN, its nodes' energy "
        "(network_nodes.csv), and with a coordination agent its decisions and assignments "
        "(wncsca_decisions.csv, wncsca_assignments.csv). Times in the scenario's time units; "
        "a missing value is an empty cell (CSV) or a null (Parquet)."
    ),
)
