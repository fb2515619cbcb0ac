"""The processes engine's fork server: imports once, loads the scenario once, forks every node.

A node process used to start as ``wncs node SCENARIO NAME ...``: a fresh interpreter importing
numpy, scipy, python-control, pydantic and every node kind, then validating the scenario, each
node on its own (about 1.2 s of CPU per node; eight nodes on two cores, 4 s before the first
round, and 100 loops need 200 such interpreters, some 35 GB). The launcher now starts one
``python -m runtime.forkserver``, which imports what a node needs (:mod:`runtime.nodes`, not the
command line's reports, sweeps and assessments), validates the scenario, freezes the imported
objects against the garbage collector (so the forked children share their pages) and then forks
one child per node. Each child is an OS process of its own as before: its own session on the
router, its own process group, its log in ``logs/<node>.log``, SIGTERM when its parent goes;
it runs exactly what ``wncs node`` runs (:func:`run_node`).

Nothing of zenoh runs in the server before it forks (a forked runtime's threads would be lost):
only the children open sessions. The server tells its parent on standard output, one line each,
``started NAME PID`` when a child is forked and ``exit NAME CODE`` when it is reaped (``CODE``
as ``subprocess`` gives it: negative for a signal), and leaves when every child has.

    python -m runtime.forkserver SCENARIO --connect EP --run-id ID --logs DIR --node NAME ...

With ``--connect -`` the server imports and validates first, then reads the endpoint as a line
on its standard input (the launcher starts it beside the router's process, whose endpoint it
learns only once that router listens); an empty input sends it away.
"""

from __future__ import annotations

import argparse
import gc
import logging
import os
import signal
import sys
from collections.abc import Sequence

from core.errors import ConfigError, SchemaError, WncsError, exit_code
from kernel.bus import open_client
from kernel.lifetime import die_with_parent
from runtime.affinity import cpus_of, parse_affinity, pin
from runtime.nodes import bus_node, check_node, clock_runner
from runtime.security import use_node_credentials
from scenario import Scenario, load_scenario

__all__ = ["run_node", "main"]

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def run_node(
    scenario: Scenario,
    name: str,
    connect: str,
    run_id: str,
    *,
    out: str | None = None,
    engine: str | None = None,
    realtime: float | None = None,
) -> int:
    """Run node ``name`` (or ``clock``) of ``scenario`` on the router at ``connect`` until the
    clock stops the run; the exit code of ``wncs node``. The clock cancels the run on SIGTERM
    or SIGINT (the launcher's Ctrl-C arrives so)."""
    if name != "clock":
        try:
            check_node(scenario, name)
        except KeyError as err:
            raise ConfigError(str(err.args[0])) from err
    session = open_client(connect)
    try:
        if name == "clock":
            runner = clock_runner(scenario, session, run_id, realtime=realtime)

            def interrupt(signum: int, frame: object) -> None:
                runner.cancel(f"interrupted ({signal.Signals(signum).name} to the clock)")

            signal.signal(signal.SIGTERM, interrupt)
            signal.signal(signal.SIGINT, interrupt)
            return runner.run()
        options = {"out": out, "engine": engine}
        return bus_node(scenario, name, run_id, session, options).run()
    finally:
        session.close()


def _child(scenario: Scenario, name: str, args: argparse.Namespace, parent: int) -> int:
    """In a forked child: become node ``name``'s process (own group, its log) and run it."""
    os.setsid()
    die_with_parent(parent)
    cpus = cpus_of(parse_affinity(args.affinity), name)
    if cpus is not None:
        pin(os.getpid(), cpus)
    use_node_credentials(name)  # a secure run: this node's, as wncs node finds them
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGCHLD):
        signal.signal(sig, signal.SIG_DFL)
    fd = os.open(os.path.join(args.logs, f"{name}.log"), os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    sys.stdin.close()
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT, force=True)
    if cpus is not None:
        logging.getLogger("wncs").info("%s pinned to CPU(s) %s", name, sorted(cpus))
    try:
        return run_node(
            scenario,
            name,
            args.connect,
            args.run_id,
            out=args.out,
            engine=args.engine,
            realtime=args.realtime,
        )
    except (WncsError, SchemaError) as err:
        print(f"wncs node: {err}", file=sys.stderr)
        return exit_code(err)
    except KeyboardInterrupt as err:
        return exit_code(err)
    except Exception:  # noqa: BLE001 - a child must never return into the server's loop
        logging.getLogger("wncs").exception("node %s failed", name)
        return 1


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m runtime.forkserver", description=__doc__)
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument(
        "--connect", required=True, help="the router's endpoint (-: a line on standard input)"
    )
    p.add_argument("--run-id", required=True, help="the run id")
    p.add_argument("--logs", required=True, help="folder of the nodes' logs")
    p.add_argument("--node", action="append", required=True, help="a node to fork (repeatable)")
    p.add_argument("--out", default=None, help="the run directory (the historian's)")
    p.add_argument("--engine", default="processes", help="engine recorded in the history")
    p.add_argument("--realtime", type=float, default=None, help="the clock's seconds per unit")
    p.add_argument("--seed", type=int, default=None, help="the run's seed")
    p.add_argument("--set", action="append", default=[], help="a --set override (repeatable)")
    p.add_argument(
        "--affinity",
        action="append",
        default=[],
        metavar="NAME=CPUS",
        help="the CPUs of a node's process, '*' for the others (runtime.affinity; repeatable)",
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        scenario = load_scenario(args.scenario, overrides=args.set)
    except ConfigError as err:
        print(f"forkserver: {err}", file=sys.stderr)
        return 2
    if args.seed is not None:
        scenario = scenario.model_copy(update={"seed": args.seed})
    if args.connect == "-":  # started before the router: its endpoint comes on standard input
        args.connect = sys.stdin.readline().strip()
        if not args.connect:
            print("forkserver: no router endpoint (the launcher gave up)", file=sys.stderr)
            return 2
    sys.stdout.flush()
    gc.collect()
    gc.freeze()  # the children share the imported objects' pages instead of copying them
    parent = os.getpid()
    children: dict[int, str] = {}
    for name in args.node:
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                code = _child(scenario, name, args, parent)
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(code)
        children[pid] = name
        print(f"started {name} {pid}", flush=True)
    while children:
        try:
            pid, status = os.wait()
        except ChildProcessError:
            break
        name = children.pop(pid, None)
        if name is not None:
            print(f"exit {name} {os.waitstatus_to_exitcode(status)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
