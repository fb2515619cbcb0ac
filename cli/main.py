"""The ``wncs`` command line: the top layer (it may know every other part, the dashboard too).

``wncs run SCENARIO --out DIR``        run a scenario (engines: processes, threads, direct)
``wncs node SCENARIO NAME --connect EP --run-id ID``   run one node of the graph (or ``clock``)
``wncs router --scenario S --listen EP --out DIR``  a standalone router of a multi-host run
``wncs report DIR``                    redraw a run's plots and print its figures
``wncs analyze SCENARIO --out DIR``    the coordination agent's analysis alone, without the bus
``wncs inject DIR EVENT [KEY=VALUE ...]``  a reconfiguration, mode, set point or drift, live
``wncs dashboard DIR``                 watch a live run in the browser, act on it, replay it
``wncs assess DATA --primary COL ...``  Harris index and cascade opportunities of a loop (seed 004)
``wncs validate SCENARIO ...``         check scenario files without running them
``wncs schema [--out FILE]``           the scenario files' JSON Schema, for editors
``wncs sweep SCENARIO --grid P=a:b:n --out DIR``  a grid of overrides on the direct engine
``wncs export RUN_DIR --csv|--parquet``  every artefact of a run as CSV or Parquet files
``wncs scale N --out FILE``            write a scenario of N loops over WSN paths

``run``, ``node``, ``validate`` and ``sweep`` take ``--set dotted.path=VALUE`` (repeatable,
:mod:`scenario.overrides`): the value, parsed as YAML, replaces the field in the file's mapping
before validation. The help texts are plain text (no markup) and end with examples; the
examples name only shipped scenarios (``tests/unit/test_cli_conveniences.py`` parses them).

Exit codes: 0 success, 2 bad input (scenario, arguments), 3 the run was stopped by a fault,
1 any other failure.

The commands are a table (:data:`COMMANDS`): each row a :class:`cli.table.Command` with its help,
examples and the ``add``/``run`` pair that makes it, kept side by side in its module
(:mod:`cli.bus`: run, node, router; :mod:`cli.runs`: report, inject, dashboard, assess, export;
:mod:`cli.scenarios`: analyze, validate, schema, sweep, scale).
"""

from __future__ import annotations

import argparse
import logging
import sys
from importlib.metadata import version

from cli import bus, runs, scenarios
from cli.table import Command, epilog, fill
from core.errors import SchemaError, WncsError, exit_code
from kernel.bus import init_zenoh_log

__all__ = ["COMMANDS", "EXAMPLES", "build_parser", "main"]

PACKAGE = "wncs"  # the distribution name in pyproject.toml

DESCRIPTION = (
    "WNCS: wireless networked control systems on Zenoh, in deterministic virtual time. "
    "Run a scenario (plants, controllers, a WSN gateway emulator, the coordination agent), "
    "inspect its artefacts, inject events into a live run, assess a loop from routine data. "
    "Exit codes: 0 success, 2 bad input, 3 the run was stopped by a fault, 1 other failures."
)

COMMANDS: tuple[Command, ...] = (
    bus.RUN,
    bus.NODE,
    bus.ROUTER,
    runs.REPORT,
    scenarios.ANALYZE,
    runs.INJECT_COMMAND,
    runs.DASHBOARD,
    runs.ASSESS,
    scenarios.VALIDATE,
    scenarios.SCHEMA,
    scenarios.SWEEP,
    runs.EXPORT,
    scenarios.SCALE,
)
"""Every sub-command, in the order ``wncs --help`` lists them."""

EXAMPLES: dict[str, tuple[str, ...]] = {
    "wncs": (
        "wncs run scenarios/jcstr_wncs.yaml --out runs/wncs --engine threads",
        "wncs validate scenarios/jcstr_wncs.yaml",
        "wncs report runs/wncs",
    ),
    **{c.name: c.examples for c in COMMANDS},
}
"""Per subcommand (and ``wncs`` itself), the commands its help ends with: shipped scenarios only,
and a test parses each."""

_QUIET_ZENOH = ("run", "inject")
"""The commands whose process's stdout is the terminal: zenoh's own log off
(:func:`kernel.bus.init_zenoh_log`)."""


def build_parser() -> argparse.ArgumentParser:
    """The ``wncs`` parser: one sub-parser per row of :data:`COMMANDS`."""
    parser = argparse.ArgumentParser(
        prog="wncs",
        description=fill(DESCRIPTION),
        epilog=epilog(EXAMPLES["wncs"])
        + "\n\n'wncs COMMAND --help' shows a command's options and examples.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--version", action="version", version=f"wncs {version(PACKAGE)}", help="print the version"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.declare(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.INFO if args.command == "node" else logging.WARNING
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    if args.command in _QUIET_ZENOH:
        init_zenoh_log("off")
    run = {c.name: c.run for c in COMMANDS}[args.command]
    try:
        return run(args)
    except (WncsError, SchemaError) as err:
        print(f"wncs {args.command}: {err}", file=sys.stderr)
        return exit_code(err)
    except KeyboardInterrupt as err:
        return exit_code(err)


if __name__ == "__main__":
    sys.exit(main())
