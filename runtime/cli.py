"""The ``wncs`` command line.

``wncs run SCENARIO --out DIR``        run a scenario (engines: processes, threads, direct)
``wncs node SCENARIO NAME --connect EP --run-id ID``   run one node of the graph (or ``clock``)
``wncs router --scenario S --listen EP --out DIR``  a standalone router of a multi-host run
``wncs report DIR``                    redraw a run's plots and print its figures
``wncs analyze SCENARIO --out DIR``    the coordination agent's analysis alone, without the bus
``wncs inject DIR EVENT [KEY=VALUE ...]``  a reconfiguration, mode or set point into a live run
``wncs dashboard DIR``                 watch a live run in the browser, act on it, replay it
``wncs assess DATA --primary COL ...``  Harris index and cascade opportunities of a loop (seed 004)
``wncs validate SCENARIO ...``         check scenario files without running them
``wncs schema [--out FILE]``           the scenario files' JSON Schema, for editors
``wncs sweep SCENARIO --grid P=a:b:n --out DIR``  a grid of overrides on the direct engine
``wncs export RUN_DIR --csv|--parquet``  every artefact of a run as CSV or Parquet files
``wncs scale N --out FILE``            write a scenario of N loops over WSN paths

``run``, ``node``, ``validate`` and ``sweep`` take ``--set dotted.path=VALUE`` (repeatable,
:mod:`runtime.overrides`): the value, parsed as YAML, replaces the field in the file's mapping
before validation. The help texts are plain text (no markup) and end with examples; the
examples name only shipped scenarios (``tests/unit/test_cli_conveniences.py`` parses them).

Exit codes: 0 success, 2 bad input (scenario, arguments), 3 the run was stopped by a fault,
1 any other failure.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import subprocess
import sys
import textwrap
from collections.abc import Callable
from importlib.metadata import version
from pathlib import Path
from typing import Any

from agents.monitor.command import add_assess_arguments, run_from_args
from agents.wncsca.timeline import format_timeline
from core.errors import ConfigError, SchemaError, WncsError, exit_code
from dashboard import command as dashboard_command
from kernel.bus import CONFIG_ENV, init_zenoh_log
from kernel.security import client_settings, read_credential
from runtime.affinity import parse_affinity
from runtime.analysis import analyze, parse_delays
from runtime.artefacts import REFUSED_LOG, RUN_FILE
from runtime.export import export_run
from runtime.forkserver import run_node
from runtime.inject import build_request, send
from runtime.launcher import INTERRUPTED, launch
from runtime.report import load_run, write_plots, write_summary
from runtime.router import serve_router
from runtime.scale import PLANTS, write_scale
from runtime.scenario import Scenario, load_scenario
from runtime.security import INJECT, login_of, use_node_credentials
from runtime.sweep import SWEEP_CSV, SWEEP_PARQUET, SWEEP_PNG, parse_axis, sweep

__all__ = ["main", "build_parser", "EXAMPLES"]

log = logging.getLogger("wncs")

PACKAGE = "wncs"  # the distribution name in pyproject.toml

DESCRIPTION = (
    "WNCS: wireless networked control systems on Zenoh, in deterministic virtual time. "
    "Run a scenario (plants, controllers, a WSN gateway emulator, the coordination agent), "
    "inspect its artefacts, inject events into a live run, assess a loop from routine data. "
    "Exit codes: 0 success, 2 bad input, 3 the run was stopped by a fault, 1 other failures."
)

EXAMPLES: dict[str, tuple[str, ...]] = {
    "wncs": (
        "wncs run scenarios/jcstr_wncs.yaml --out runs/wncs --engine threads",
        "wncs validate scenarios/jcstr_wncs.yaml",
        "wncs report runs/wncs",
    ),
    "run": (
        "wncs run scenarios/jcstr_benchmark.yaml --out runs/bench --engine threads",
        "wncs run scenarios/tank_sim.yaml --out runs/tank --set loops.level.tau_s=0.2",
        "wncs run scenarios/jcstr_wsn.yaml --out runs/wsn"
        " --set nodes.network.topology.retry_limit=5",
    ),
    "node": (
        "wncs node scenarios/tank_sim.yaml clock --connect tcp/127.0.0.1:7447 --run-id r1",
        "wncs node scenarios/tank_sim.yaml level_controller --connect tcp/127.0.0.1:7447"
        " --run-id r1",
    ),
    "router": (
        "wncs router --scenario scenarios/tank_sim.yaml --listen tcp/127.0.0.1:7447 --out runs/mh",
        "wncs router --scenario scenarios/tank_sim.yaml --listen tcp/127.0.0.1:7448"
        " --connect tcp/127.0.0.1:7447 --out runs/mh",
        "wncs router --scenario scenarios/tank_sim.yaml --listen tls/0.0.0.0:7447 --tls"
        " --tls-name a.example.org --out runs/mh_tls",
    ),
    "report": ("wncs report runs/bench",),
    "analyze": (
        "wncs analyze scenarios/jcstr_wncs.yaml --out runs/analysis",
        "wncs analyze scenarios/jcstr_wncs.yaml --delays level=0.17,temperature=0.1 --out runs/an",
    ),
    "inject": (
        "wncs inject runs/wsn node_down node=r1",
        "wncs inject runs/wncs mode steady_state",
        "wncs inject runs/wncs setpoint level=0.72",
    ),
    "dashboard": (
        "wncs dashboard runs/wncs",
        "wncs dashboard runs/wncs --port 8800",
        "wncs run scenarios/jcstr_wncs.yaml --out runs/live --realtime 0.5 --dashboard",
    ),
    "assess": (
        "wncs assess loop.csv --primary PV --setpoint SP --secondary T2,T3 --delays 5,2,6,1",
        "wncs assess runs/cr --primary temperature --secondary reactor.y2,reactor.y3"
        " --delays 3,1,3,1",
    ),
    "validate": (
        "wncs validate scenarios/jcstr_benchmark.yaml scenarios/jcstr_wsn.yaml",
        "wncs validate scenarios/tank_sim.yaml --set loops.level.tau_s=0.2",
    ),
    "schema": (
        "wncs schema --out scenario.schema.json",
        "wncs schema > scenario.schema.json",
    ),
    "export": (
        "wncs export runs/bench --csv",
        "wncs export runs/wncs --csv --out runs/wncs_csv",
        "wncs export runs/bench --parquet",
    ),
    "sweep": (
        "wncs sweep scenarios/jcstr_benchmark.yaml --grid loops.level.tau_s=0.1:0.4:7"
        " --out runs/sweep",
        "wncs sweep scenarios/jcstr_wsn.yaml --grid loops.level.tau_s=0.1:0.3:3"
        " --grid nodes.network.topology.retry_limit=2,3 --out runs/sweep_wsn --jobs 2",
        "wncs sweep scenarios/tank_sim.yaml --grid loops.level.tau_s=0.05,0.1,0.2"
        " --set loops.level.settling_band=0.02 --out runs/sweep_tank",
    ),
    "scale": (
        "wncs scale 50 --out runs/scale50.yaml",
        "wncs scale 20 --plant jcstr --per-gateway 4 --out runs/jcstr20.yaml",
    ),
}
"""Per subcommand (and ``wncs`` itself), the commands its help ends with: shipped scenarios only,
and a test parses each."""

_WIDTH = 79  # descriptions are filled to this; the examples are kept as written


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def _fill(text: str) -> str:
    """A description filled to the help's width, unless it is laid out already (has lines)."""
    return text if "\n" in text else textwrap.fill(text, _WIDTH)


def _epilog(name: str) -> str:
    return "examples:\n" + "\n".join(f"  {line}" for line in EXAMPLES[name])


def _command(
    sub: argparse._SubParsersAction[argparse.ArgumentParser],
    name: str,
    help: str,
    description: str | None = None,
) -> argparse.ArgumentParser:
    """A subcommand whose help ends with its examples (kept as written: one command a line)."""
    return sub.add_parser(
        name,
        help=help,
        description=_fill(description or help[0].upper() + help[1:] + "."),
        epilog=_epilog(name),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def _add_set(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="PATH=VALUE",
        help="override a field of the scenario before it is validated, e.g. "
        "loops.level.tau_s=0.2 or setpoints.0.value=0.8 (the value is YAML; repeatable)",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="wncs",
        description=_fill(DESCRIPTION),
        epilog=_epilog("wncs")
        + "\n\n'wncs COMMAND --help' shows a command's options and examples.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--version", action="version", version=f"wncs {version(PACKAGE)}", help="print the version"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run = _command(
        sub,
        "run",
        "run a scenario and write its artefacts to DIR",
        "Run a scenario and write its artefacts (run.json, scenario.yaml, history.sqlite or "
        "record.json, summary.json, one PNG per loop, logs/) to DIR. On a terminal it shows "
        "simulated time against the end time, then each loop's overshoot, settling time and IAE.",
    )
    run.add_argument("scenario", help="scenario YAML file")
    run.add_argument("--out", required=True, metavar="DIR", help="output directory")
    run.add_argument(
        "--engine",
        choices=("processes", "threads", "direct"),
        default="processes",
        help="processes: one OS process per node (default); threads: the same nodes in this "
        "process; direct: no bus, fast",
    )
    run.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    run.add_argument(
        "--listen",
        default=None,
        metavar="ENDPOINT",
        help="endpoint of the embedded router (default tcp/127.0.0.1:0)",
    )
    run.add_argument(
        "--realtime",
        type=_positive_float,
        default=None,
        metavar="SECONDS_PER_UNIT",
        help="pace virtual time against the wall clock",
    )
    run.add_argument(
        "--dashboard",
        nargs="?",
        type=dashboard_command.port_number,
        const=dashboard_command.DEFAULT_PORT,
        default=None,
        metavar="PORT",
        help=f"serve the live dashboard on 127.0.0.1:PORT (default "
        f"{dashboard_command.DEFAULT_PORT}) while the run goes on, and the finished run after "
        "it, until Ctrl-C; best with --realtime",
    )
    run.add_argument(
        "--insecure",
        action="store_true",
        help="no credentials and no access control on the router (prints a warning); by "
        "default each node authenticates and may publish only its own keys",
    )
    run.add_argument(
        "--tls",
        action="store_true",
        help="every session over mutual TLS: a CA of the run, a certificate per node under "
        "DIR/security (listen defaults to tls/127.0.0.1:0; refused with --insecure)",
    )
    run.add_argument(
        "--zenoh-config",
        default=None,
        metavar="FILE",
        help="zenoh configuration file the router starts from (default: $ZENOH_CONFIG)",
    )
    run.add_argument(
        "--affinity",
        action="append",
        default=[],
        metavar="NAME=CPUS",
        help="pin a process of the run to CPUs (repeatable): NAME a node, clock, historian, "
        "router, or '*' for the others; CPUS as taskset -c takes them; the threads engine "
        "takes '*' and router only, and runs on one CPU unless '*' says otherwise. E.g. "
        "--affinity '*=0' --affinity historian=1",
    )
    run.add_argument("--quiet", action="store_true", help="print only errors")
    run.add_argument(
        "--force",
        action="store_true",
        help="replace the run already in --out (refused without it)",
    )
    _add_set(run)

    node = _command(
        sub,
        "node",
        "run one node of a scenario's graph",
        "Run one node of a scenario's graph (or the clock, or the historian) against a router: "
        "the command the launcher starts for each node of the processes engine.",
    )
    node.add_argument("scenario", help="scenario YAML file")
    node.add_argument("name", help="node name, or 'clock' / 'historian'")
    node.add_argument("--connect", required=True, help="router endpoint, e.g. tcp/127.0.0.1:7447")
    node.add_argument("--run-id", required=True, help="the run's id (key prefix on the bus)")
    node.add_argument(
        "--credentials",
        default=None,
        metavar="FILE",
        help="the node's credential file (default: NAME.json in $WNCS_SECURITY, the run's "
        "security directory, if set)",
    )
    node.add_argument(
        "--zenoh-config",
        default=None,
        metavar="FILE",
        help="zenoh configuration file the session starts from (default: $ZENOH_CONFIG)",
    )
    node.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    node.add_argument("--out", default=".", help="historian: directory of history.sqlite")
    node.add_argument("--engine", default="processes", help="historian: engine recorded in meta")
    node.add_argument(
        "--realtime",
        type=_positive_float,
        default=None,
        metavar="SECONDS_PER_UNIT",
        help="clock: real-time pacing",
    )
    _add_set(node)

    router = _command(
        sub,
        "router",
        "a standalone router of a run whose nodes live on several hosts",
        "Serve a run's zenoh router with the run's security (credentials and access control "
        "under DIR/security, made by the first router of the run; copy them to the other "
        "hosts). A router with --connect joins another router of the run. Nodes join with "
        "wncs node SCENARIO NAME --connect ENDPOINT --run-id ID and WNCS_SECURITY=DIR/security "
        "(or --credentials DIR/security/NAME.json). Serves until Ctrl-C.",
    )
    router.add_argument("--scenario", required=True, help="scenario YAML file")
    router.add_argument("--listen", required=True, metavar="ENDPOINT", help="e.g. tcp/0.0.0.0:7447")
    router.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="another router of the run to join (repeatable)",
    )
    router.add_argument(
        "--out", required=True, metavar="DIR", help="the run's directory (run.json, security/)"
    )
    router.add_argument("--insecure", action="store_true", help="no credentials, no access control")
    router.add_argument(
        "--tls",
        action="store_true",
        help="the first router: make the run a TLS run (mutual TLS, a CA of the run and a "
        "certificate per node under DIR/security; --listen tls/...); refused with --insecure",
    )
    router.add_argument(
        "--tls-name",
        action="append",
        default=[],
        metavar="HOST",
        help="a DNS name or IP address nodes reach this router by, for its certificate "
        "(repeatable; the loopback and the --listen host are always in it)",
    )
    router.add_argument("--zenoh-config", default=None, metavar="FILE", help="zenoh config file")
    router.add_argument(
        "--run-id",
        default=None,
        metavar="ID",
        help="the first router: the run's id (default: a random one; compose.yaml fixes it)",
    )
    _add_set(router)

    report = _command(sub, "report", "redraw a run's plots and print its figures")
    report.add_argument("dir", metavar="DIR", help="run directory written by wncs run")

    analyze = _command(
        sub,
        "analyze",
        "the coordination agent's decision and periods, without the bus",
        "The coordination agent's analysis alone, without the bus: the largest tolerable delay "
        "of each loop, its decision on the scenario's (or the given) delays and the sampling "
        "periods it would assign.",
    )
    analyze.add_argument("scenario", help="scenario YAML file with a coordination agent")
    analyze.add_argument(
        "--delays",
        default=None,
        help="control-path delays, loop=value,... (default: from the scenario's networks)",
    )
    analyze.add_argument(
        "--method",
        choices=("paper", "fast", "chance"),
        default=None,
        help="paper: seed 000's successive approximation; fast: the same question on the "
        "linearised loops; chance: P(overshoot <= limit) >= confidence over the delay "
        "distributions (default: the method in the scenario's agent)",
    )
    analyze.add_argument("--out", required=True, metavar="DIR", help="output directory")

    inject = _command(
        sub,
        "inject",
        "inject a network reconfiguration, a mode or a set point into a running run",
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
        "An unknown event, field, node, mode or loop is refused (exit 2) before anything is sent.",
    )
    inject.add_argument(
        "words",
        nargs="+",
        metavar="WORD",
        help="DIR EVENT [KEY=VALUE ...], or EVENT [KEY=VALUE ...] with --listen",
    )
    inject.add_argument("--network", default=None, help="gateway node (default: the only one)")
    inject.add_argument(
        "--listen", default=None, metavar="ENDPOINT", help="router endpoint, instead of DIR"
    )
    inject.add_argument("--run-id", default=None, help="run id, with --listen")
    inject.add_argument(
        "--credentials",
        default=None,
        metavar="FILE",
        help="the inject identity's credential file of a secure run (default with DIR: "
        "DIR/security/inject.json)",
    )

    dashboard = _command(
        sub,
        "dashboard",
        "watch a live run in the browser, act on it, replay it",
        "Serve a web page on 127.0.0.1 that shows a run as it goes on (its history, read as "
        "the historian commits it): the WSN topology with batteries, link quality and the "
        "routes in force; each loop's output against its set point with the delivered samples "
        "and the moves; each path's delay and losses; the sampling periods with the open "
        "intervals shaded; the coordination agent's decisions with their reasons; invalid "
        "messages dropped; simulated against wall time; the TSCH schedule. Its buttons send "
        "what wncs inject sends. A finished run is replayed with a time slider.",
    )
    dashboard_command.add_arguments(dashboard)

    assess = _command(
        sub,
        "assess",
        "Harris index and cascade opportunities of a loop from routine data (seed 004)",
        "Assess a simple-feedback loop from routine data: its Harris index with its "
        "uncertainty and, per candidate secondary, the variance components 1a/1b/2a/2b and the "
        "predicted variance under cascade control. DATA is a CSV file (columns as exported by a "
        "historian) or a run directory (columns LOOP, LOOP.sp, PLANT.STATE). Exit codes: 0 "
        "assessed, 2 bad input, 3 a part unidentifiable.",
    )
    add_assess_arguments(assess)

    validate = _command(
        sub,
        "validate",
        "check scenario files without running them",
        "Check scenario files without running anything: a YAML syntax error names the line and "
        "column, a bad field its dotted name and line. Prints 'ok: FILE' for each valid file. "
        "Exit codes: 0 every file is valid, 2 one is not.",
    )
    validate.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="scenario YAML files")
    _add_set(validate)

    schema = _command(
        sub,
        "schema",
        "print the JSON Schema of scenario files (for editors)",
        "Print the JSON Schema of scenario files, from the same models that validate them, for "
        "editors: VS Code's YAML extension completes and checks a scenario with the line "
        "'# yaml-language-server: $schema=scenario.schema.json' at its top.",
    )
    schema.add_argument(
        "--out", default=None, metavar="FILE", help="write the schema to FILE (default stdout)"
    )
    sweep_ = _command(
        sub,
        "sweep",
        "run a scenario over a grid of overrides on the direct engine",
        "Run a scenario on the direct engine at every point of a grid of overrides, in parallel "
        "processes, and write DIR/sweep.csv (one row per point: the grid values, then each "
        "loop's overshoot_pct, settling_time and iae and, with a coordination agent, its "
        "control period from the last assignment), the same table as DIR/sweep.parquet, and "
        "DIR/sweep.png (each loop's overshoot "
        "against the first axis, one line per value of the other axes). Each point is the "
        "scenario with the --set overrides and then the point's values applied as 'wncs run "
        "--set' applies them; a point that does not validate is refused (exit 2) before "
        "anything runs. Progress ('sweep: k/N') goes to stderr.",
    )
    sweep_.add_argument("scenario", help="scenario YAML file")
    sweep_.add_argument(
        "--grid",
        action="append",
        required=True,
        metavar="PATH=VALUES",
        help="a grid axis: PATH=a:b:n (n evenly spaced values from a to b inclusive) or "
        "PATH=x,y,z (each value YAML, as --set); repeatable, the grid is the Cartesian product",
    )
    _add_set(sweep_)
    sweep_.add_argument("--out", required=True, metavar="DIR", help="output directory")
    sweep_.add_argument(
        "--jobs",
        type=int,
        default=None,
        metavar="N",
        help="worker processes (default: the number of CPUs; 1 runs in this process)",
    )
    export = _command(
        sub,
        "export",
        "write every artefact of a run as CSV or Parquet files",
        "Write every artefact of a run as CSV (or Parquet) files: per loop its trace "
        "(loop_LOOP.csv: t, t_sampled, y, setpoint, u), per plant its states (plant_PLANT.csv), "
        "the network's path statistics (network_paths.csv) and, with a WSN, its nodes' energy "
        "(network_nodes.csv), and with a coordination agent its decisions and assignments "
        "(wncsca_decisions.csv, wncsca_assignments.csv). Times in the scenario's time units; "
        "a missing value is an empty cell (CSV) or a null (Parquet).",
    )
    export.add_argument("dir", metavar="RUN_DIR", help="run directory written by wncs run")
    fmt = export.add_mutually_exclusive_group(required=True)
    fmt.add_argument("--csv", action="store_true", help="write CSV files")
    fmt.add_argument("--parquet", action="store_true", help="write Parquet files (pyarrow)")
    export.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="output directory (default RUN_DIR/csv or RUN_DIR/parquet)",
    )
    scale = _command(
        sub,
        "scale",
        "write a scenario of N loops over WSN paths",
        "Write a scenario file of N loops, each its own controller, every sensor two hops from a "
        "gateway over a lossy WSN, with set-point steps staggered across the loops (tank: N "
        "independent tanks of seed 002 with its non-linear PI, steps of 20 mm, 60 s; jcstr: N/2 "
        "reactors of seed 000's benchmark, 6 pu; tank_train: one plant of N such tanks in series, "
        "half of each outflow feeding the next, N coupled loops). Loops are grouped into areas "
        "of --per-gateway loops, each with its own gateway node. The file is validated before "
        "it is written; run it with wncs run.",
    )
    scale.add_argument("n", type=int, metavar="N", help="number of loops (jcstr: even)")
    scale.add_argument("--out", required=True, metavar="FILE", help="scenario file to write")
    scale.add_argument("--plant", choices=PLANTS, default="tank", help="plant of every loop")
    scale.add_argument(
        "--per-gateway", type=int, default=10, metavar="K", help="loops per gateway (default 10)"
    )
    scale.add_argument(
        "--end-time", type=_positive_float, default=None, metavar="T", help="end of the run"
    )
    scale.add_argument("--seed", type=int, default=0, help="the scenario's seed (default 0)")
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
    if args.dashboard is None:
        return _run(args, None)
    if args.engine == "direct":
        raise ConfigError(
            "--dashboard: the direct engine has no history to watch; use --engine threads or "
            "processes"
        )
    children: list[subprocess.Popen[bytes]] = []
    code = INTERRUPTED
    try:
        code = _run(args, lambda out: children.append(dashboard_command.spawn(out, args.dashboard)))
        if children and children[0].poll() is None:
            print("wncs run: the dashboard shows the finished run; Ctrl-C to stop", flush=True)
            children[0].wait()
        return code
    except KeyboardInterrupt:
        return code
    finally:
        for child in children:
            child.terminate()
            child.wait(timeout=10)


def _run(args: argparse.Namespace, on_start: Callable[[Path], None] | None) -> int:
    stream = sys.stdout if (sys.stdout.isatty() and not args.quiet) else None
    result = launch(
        args.scenario,
        args.out,
        engine=args.engine,
        seed=args.seed,
        listen=args.listen,
        realtime=args.realtime,
        progress=stream,
        overrides=args.set,
        force=args.force,
        on_start=on_start,
        insecure=args.insecure,
        zenoh_config=args.zenoh_config,
        tls=args.tls,
        affinity=parse_affinity(args.affinity),
    )
    if result.code == INTERRUPTED:
        where = f"; partial results in {args.out}" if result.summary else ""
        print(f"wncs run: {result.error}{where}", file=sys.stderr)
        return result.code
    if result.code != 0:
        print(f"wncs run: {result.error}", file=sys.stderr)
        return result.code
    refused = (result.summary.get("router") or {}).get("refused")
    if refused:
        log = Path(args.out) / REFUSED_LOG
        print(
            f"wncs run: the router refused {refused} attempts on the bus (see {log})",
            file=sys.stderr,
        )
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
    scenario = load_scenario(args.scenario, overrides=args.set)
    if args.seed is not None:
        scenario = scenario.model_copy(update={"seed": args.seed})
    return run_node(
        scenario,
        args.name,
        args.connect,
        args.run_id,
        out=args.out,
        engine=args.engine,
        realtime=args.realtime,
    )


def _cmd_router(args: argparse.Namespace) -> int:
    return serve_router(
        args.scenario,
        Path(args.out),
        args.listen,
        connect=tuple(args.connect),
        insecure=args.insecure,
        zenoh_config=args.zenoh_config,
        overrides=tuple(args.set),
        run_id=args.run_id,
        tls=args.tls,
        tls_names=tuple(args.tls_name),
    )


def _cmd_report(args: argparse.Namespace) -> int:
    out = Path(args.dir)
    scenario, rec = load_run(out)
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
    for name, m in sorted((w.get("jitter_margin") or {}).items()):
        print(
            f"{name}: jitter margin {m['margin']:.4g} against a delay variation of "
            f"{m['variation']:.4g} ({'within' if m['ok'] else 'OUTSIDE'}; Kao-Lincoln)"
        )
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


def _cmd_assess(args: argparse.Namespace) -> int:
    return run_from_args(args)


def _cmd_validate(args: argparse.Namespace) -> int:
    code = 0
    for path in args.scenarios:
        try:
            load_scenario(path, overrides=args.set)
        except ConfigError as err:
            print(f"wncs validate: {err}", file=sys.stderr)
            code = 2
        else:
            print(f"ok: {path}")
    return code


def _cmd_schema(args: argparse.Namespace) -> int:
    text = json.dumps(Scenario.model_json_schema(), indent=2) + "\n"
    if args.out is None:
        sys.stdout.write(text)
        return 0
    try:
        Path(args.out).write_text(text, encoding="utf-8")
    except OSError as err:
        raise ConfigError(f"--out {args.out}: cannot write: {err.strerror or err}") from err
    print(f"wrote {args.out}")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    fmt = "parquet" if args.parquet else "csv"
    written = export_run(args.dir, args.out, fmt=fmt)
    where = written[0].parent if written else Path(args.out or Path(args.dir) / fmt)
    print(
        f"wrote {len(written)} {fmt.upper()} files to {where}: "
        + ", ".join(p.name for p in written)
    )
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    axes = [parse_axis(text) for text in args.grid]
    rows = sweep(
        args.scenario, axes, args.out, overrides=args.set, jobs=args.jobs, progress=sys.stderr
    )
    out = Path(args.out)
    print(f"{len(rows)} points: {out / SWEEP_CSV}, {out / SWEEP_PARQUET}, {out / SWEEP_PNG}")
    return 0


def _cmd_scale(args: argparse.Namespace) -> int:
    try:
        scenario = write_scale(
            args.n,
            args.out,
            plant=args.plant,
            per_gateway=args.per_gateway,
            end_time=args.end_time,
            seed=args.seed,
        )
    except ValueError as err:
        raise ConfigError(str(err)) from err
    except OSError as err:
        raise ConfigError(f"--out {args.out}: cannot write: {err.strerror or err}") from err
    print(
        f"wrote {args.out}: {len(scenario.loops)} loops, {len(scenario.nodes)} nodes, "
        f"{len(scenario.gateways())} gateways, {scenario.end_time:g} {scenario.time_unit}"
    )
    return 0


def _use_node_credentials(args: argparse.Namespace) -> None:
    """``wncs node``: the credentials its session opens with (``--credentials``, else
    ``NAME.json`` in ``$WNCS_SECURITY``: :func:`runtime.security.use_node_credentials`); and its
    zenoh configuration file (``--zenoh-config``)."""
    use_node_credentials(args.name, args.credentials)
    if args.zenoh_config:
        os.environ[CONFIG_ENV] = args.zenoh_config


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.INFO if args.command == "node" else logging.WARNING
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    if args.command in ("run", "inject"):
        init_zenoh_log("off")  # this process's stdout is the terminal: kernel.bus.init_zenoh_log
    if args.command == "node":
        _use_node_credentials(args)
    try:
        commands = {
            "run": _cmd_run,
            "node": _cmd_node,
            "router": _cmd_router,
            "report": _cmd_report,
            "inject": _cmd_inject,
            "analyze": _cmd_analyze,
            "assess": _cmd_assess,
            "validate": _cmd_validate,
            "schema": _cmd_schema,
            "sweep": _cmd_sweep,
            "export": _cmd_export,
            "scale": _cmd_scale,
            "dashboard": dashboard_command.run,
        }
        return commands[args.command](args)
    except (WncsError, SchemaError) as err:
        print(f"wncs {args.command}: {err}", file=sys.stderr)
        return exit_code(err)
    except KeyboardInterrupt as err:
        return exit_code(err)


if __name__ == "__main__":
    sys.exit(main())
