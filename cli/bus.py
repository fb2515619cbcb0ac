"""The commands that run a scenario's graph: ``wncs run`` (the whole graph, with its router),
``wncs node`` (one node of it, against a router: what the processes engine starts for each node)
and ``wncs router`` (a standalone router of a run whose nodes live on several hosts)."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from agents.wncsca.timeline import format_timeline
from cli.table import Command, add_set, positive_float
from core.errors import ConfigError
from dashboard import command as dashboard_command
from kernel.bus import CONFIG_ENV
from runtime.affinity import parse_affinity
from runtime.artefacts import REFUSED_LOG
from runtime.forkserver import run_node
from runtime.launcher import INTERRUPTED, launch
from runtime.report import AUTO_LOOPS, PLOTS, SUMMARY_FIGURE
from runtime.router import serve_router
from runtime.security import use_node_credentials
from scenario import load_scenario

__all__ = ["RUN", "NODE", "ROUTER", "table"]


def _add_run(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario YAML file")
    parser.add_argument("--out", required=True, metavar="DIR", help="output directory")
    parser.add_argument(
        "--engine",
        choices=("processes", "threads", "direct"),
        default="processes",
        help="processes: one OS process per node (default); threads: the same nodes in this "
        "process; direct: no bus, fast",
    )
    parser.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    parser.add_argument(
        "--listen",
        default=None,
        metavar="ENDPOINT",
        help="endpoint of the embedded router (default tcp/127.0.0.1:0)",
    )
    parser.add_argument(
        "--realtime",
        type=positive_float,
        default=None,
        metavar="SECONDS_PER_UNIT",
        help="pace virtual time against the wall clock",
    )
    parser.add_argument(
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
    parser.add_argument(
        "--insecure",
        action="store_true",
        help="no credentials and no access control on the router (prints a warning); by "
        "default each node authenticates and may publish only its own keys",
    )
    parser.add_argument(
        "--tls",
        action="store_true",
        help="every session over mutual TLS: a CA of the run, a certificate per node under "
        "DIR/security (listen defaults to tls/127.0.0.1:0; refused with --insecure)",
    )
    parser.add_argument(
        "--zenoh-config",
        default=None,
        metavar="FILE",
        help="zenoh configuration file the router starts from (default: $ZENOH_CONFIG)",
    )
    parser.add_argument(
        "--affinity",
        action="append",
        default=[],
        metavar="NAME=CPUS",
        help="pin a process of the run to CPUs (repeatable): NAME a node, clock, historian, "
        "router, or '*' for the others; CPUS as taskset -c takes them; the threads engine "
        "takes '*' and router only, and runs on one CPU unless '*' says otherwise. E.g. "
        "--affinity '*=0' --affinity historian=1",
    )
    parser.add_argument("--quiet", action="store_true", help="print only errors")
    add_plots(parser)
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the run already in --out (refused without it)",
    )
    add_set(parser)


def add_plots(parser: argparse.ArgumentParser) -> None:
    """``--plots``: which figures are drawn (:func:`runtime.report.write_plots`)."""
    parser.add_argument(
        "--plots",
        choices=PLOTS,
        default="auto",
        help=f"figures drawn: all (one per loop, the agent's, the laws'), summary (every loop "
        f"in one figure, {SUMMARY_FIGURE}, and the agent's), none; auto (default): all up to "
        f"{AUTO_LOOPS} loops, summary beyond",
    )


def table(summary: dict[str, Any]) -> str:
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


def _run_command(args: argparse.Namespace) -> int:
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
        plots=args.plots,
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
        print(table(s))
        if "wncsca" in s:
            print("\ncoordination agent (WNCSCA) timeline:")
            print(format_timeline(s))
        pngs = sorted(p.name for p in Path(args.out).glob("*.png"))
        print(f"\nartefacts in {Path(args.out).resolve()}: summary.json, " + ", ".join(pngs))
    return 0


RUN = Command(
    "run",
    "run a scenario and write its artefacts to DIR",
    _add_run,
    _run_command,
    examples=(
        "wncs run scenarios/jcstr_benchmark.yaml --out runs/bench --engine threads",
        "wncs run scenarios/tank_sim.yaml --out runs/tank --set loops.level.tau_s=0.2",
        "wncs run scenarios/jcstr_wsn.yaml --out runs/wsn"
        " --set nodes.network.topology.retry_limit=5",
    ),
    description="Run a scenario and write its artefacts (run.json, scenario.yaml, "
    "history.sqlite or record.json, summary.json, one PNG per loop, logs/) to DIR. On a "
    "terminal it shows simulated time against the end time, then each loop's overshoot, "
    "settling time and IAE.",
)


def _add_node(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario YAML file")
    parser.add_argument("name", help="node name, or 'clock' / 'historian'")
    parser.add_argument("--connect", required=True, help="router endpoint, e.g. tcp/127.0.0.1:7447")
    parser.add_argument("--run-id", required=True, help="the run's id (key prefix on the bus)")
    parser.add_argument(
        "--credentials",
        default=None,
        metavar="FILE",
        help="the node's credential file (default: NAME.json in $WNCS_SECURITY, the run's "
        "security directory, if set)",
    )
    parser.add_argument(
        "--zenoh-config",
        default=None,
        metavar="FILE",
        help="zenoh configuration file the session starts from (default: $ZENOH_CONFIG)",
    )
    parser.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    parser.add_argument("--out", default=".", help="historian: directory of history.sqlite")
    parser.add_argument("--engine", default="processes", help="historian: engine recorded in meta")
    parser.add_argument(
        "--realtime",
        type=positive_float,
        default=None,
        metavar="SECONDS_PER_UNIT",
        help="clock: real-time pacing",
    )
    add_set(parser)


def _node(args: argparse.Namespace) -> int:
    # its session's credentials (--credentials, else NAME.json in $WNCS_SECURITY) and zenoh
    # configuration file (--zenoh-config)
    use_node_credentials(args.name, args.credentials)
    if args.zenoh_config:
        os.environ[CONFIG_ENV] = args.zenoh_config
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


NODE = Command(
    "node",
    "run one node of a scenario's graph",
    _add_node,
    _node,
    examples=(
        "wncs node scenarios/tank_sim.yaml clock --connect tcp/127.0.0.1:7447 --run-id r1",
        "wncs node scenarios/tank_sim.yaml level_controller --connect tcp/127.0.0.1:7447"
        " --run-id r1",
    ),
    description="Run one node of a scenario's graph (or the clock, or the historian) against a "
    "router: the command the launcher starts for each node of the processes engine.",
)


def _add_router(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", required=True, help="scenario YAML file")
    parser.add_argument("--listen", required=True, metavar="ENDPOINT", help="e.g. tcp/0.0.0.0:7447")
    parser.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="another router of the run to join (repeatable)",
    )
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="the run's directory (run.json, security/)"
    )
    parser.add_argument("--insecure", action="store_true", help="no credentials, no access control")
    parser.add_argument(
        "--tls",
        action="store_true",
        help="the first router: make the run a TLS run (mutual TLS, a CA of the run and a "
        "certificate per node under DIR/security; --listen tls/...); refused with --insecure",
    )
    parser.add_argument(
        "--tls-name",
        action="append",
        default=[],
        metavar="HOST",
        help="a DNS name or IP address nodes reach this router by, for its certificate "
        "(repeatable; the loopback and the --listen host are always in it)",
    )
    parser.add_argument("--zenoh-config", default=None, metavar="FILE", help="zenoh config file")
    parser.add_argument(
        "--run-id",
        default=None,
        metavar="ID",
        help="the first router: the run's id (default: a random one; compose.yaml fixes it)",
    )
    add_set(parser)


def _router(args: argparse.Namespace) -> int:
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


ROUTER = Command(
    "router",
    "a standalone router of a run whose nodes live on several hosts",
    _add_router,
    _router,
    examples=(
        "wncs router --scenario scenarios/tank_sim.yaml --listen tcp/127.0.0.1:7447 --out runs/mh",
        "wncs router --scenario scenarios/tank_sim.yaml --listen tcp/127.0.0.1:7448"
        " --connect tcp/127.0.0.1:7447 --out runs/mh",
        "wncs router --scenario scenarios/tank_sim.yaml --listen tls/0.0.0.0:7447 --tls"
        " --tls-name a.example.org --out runs/mh_tls",
    ),
    description="Serve a run's zenoh router with the run's security (credentials and access "
    "control under DIR/security, made by the first router of the run; copy them to the other "
    "hosts). A router with --connect joins another router of the run. Nodes join with "
    "wncs node SCENARIO NAME --connect ENDPOINT --run-id ID and WNCS_SECURITY=DIR/security "
    "(or --credentials DIR/security/NAME.json). Serves until Ctrl-C.",
)
