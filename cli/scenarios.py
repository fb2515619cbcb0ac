"""The commands about scenarios, without the bus: ``wncs analyze`` (the coordination agent's
analysis alone), ``wncs validate``, ``wncs schema``, ``wncs sweep`` (a grid of overrides on the
direct engine) and ``wncs scale`` (a scenario of N loops)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from agents.wncsca.timeline import format_timeline
from cli.table import Command, add_set, positive_float
from core.errors import ConfigError
from runtime.analysis import analyze, parse_delays
from runtime.scale import PLANTS, write_scale
from runtime.sweep import SWEEP_CSV, SWEEP_PARQUET, SWEEP_PNG, parse_axis, sweep
from scenario import Scenario, load_scenario

__all__ = ["ANALYZE", "VALIDATE", "SCHEMA", "SWEEP", "SCALE"]


def _add_analyze(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario YAML file with a coordination agent")
    parser.add_argument(
        "--delays",
        default=None,
        help="control-path delays, loop=value,... (default: from the scenario's networks)",
    )
    parser.add_argument(
        "--method",
        choices=("paper", "fast", "chance"),
        default=None,
        help="paper: seed 000's successive approximation; fast: the same question on the "
        "linearised loops; chance: P(overshoot <= limit) >= confidence over the delay "
        "distributions (default: the method in the scenario's agent)",
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="output directory")


def _analyze(args: argparse.Namespace) -> int:
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


ANALYZE = Command(
    "analyze",
    "the coordination agent's decision and periods, without the bus",
    _add_analyze,
    _analyze,
    examples=(
        "wncs analyze scenarios/jcstr_wncs.yaml --out runs/analysis",
        "wncs analyze scenarios/jcstr_wncs.yaml --delays level=0.17,temperature=0.1 --out runs/an",
    ),
    description=(
        "The coordination agent's analysis alone, without the bus: the largest tolerable delay "
        "of each loop, its decision on the scenario's (or the given) delays and the sampling "
        "periods it would assign."
    ),
)


def _add_validate(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="scenario YAML files")
    add_set(parser)


def _validate(args: argparse.Namespace) -> int:
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


VALIDATE = Command(
    "validate",
    "check scenario files without running them",
    _add_validate,
    _validate,
    examples=(
        "wncs validate scenarios/jcstr_benchmark.yaml scenarios/jcstr_wsn.yaml",
        "wncs validate scenarios/tank_sim.yaml --set loops.level.tau_s=0.2",
    ),
    description=(
        "Check scenario files without running anything: a YAML syntax error names the line and "
        "column, a bad field its dotted name and line. Prints 'ok: FILE' for each valid file. "
        "Exit codes: 0 every file is valid, 2 one is not."
    ),
)


def _add_schema(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--out", default=None, metavar="FILE", help="write the schema to FILE (default stdout)"
    )


def _schema(args: argparse.Namespace) -> int:
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


SCHEMA = Command(
    "schema",
    "print the JSON Schema of scenario files (for editors)",
    _add_schema,
    _schema,
    examples=(
        "wncs schema --out scenario.schema.json",
        "wncs schema > scenario.schema.json",
    ),
    description=(
        "Print the JSON Schema of scenario files, from the same models that validate them, for "
        "editors: VS Code's YAML extension completes and checks a scenario with the line "
        "'# yaml-language-server: $schema=scenario.schema.json' at its top."
    ),
)


def _add_sweep(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario YAML file")
    parser.add_argument(
        "--grid",
        action="append",
        required=True,
        metavar="PATH=VALUES",
        help="a grid axis: PATH=a:b:n (n evenly spaced values from a to b inclusive) or "
        "PATH=x,y,z (each value YAML, as --set); repeatable, the grid is the Cartesian product",
    )
    add_set(parser)
    parser.add_argument("--out", required=True, metavar="DIR", help="output directory")
    parser.add_argument(
        "--jobs",
        type=int,
        default=None,
        metavar="N",
        help="worker processes (default: the number of CPUs; 1 runs in this process)",
    )


def _sweep(args: argparse.Namespace) -> int:
    axes = [parse_axis(text) for text in args.grid]
    rows = sweep(
        args.scenario, axes, args.out, overrides=args.set, jobs=args.jobs, progress=sys.stderr
    )
    out = Path(args.out)
    print(f"{len(rows)} points: {out / SWEEP_CSV}, {out / SWEEP_PARQUET}, {out / SWEEP_PNG}")
    return 0


SWEEP = Command(
    "sweep",
    "run a scenario over a grid of overrides on the direct engine",
    _add_sweep,
    _sweep,
    examples=(
        "wncs sweep scenarios/jcstr_benchmark.yaml --grid loops.level.tau_s=0.1:0.4:7"
        " --out runs/sweep",
        "wncs sweep scenarios/jcstr_wsn.yaml --grid loops.level.tau_s=0.1:0.3:3"
        " --grid nodes.network.topology.retry_limit=2,3 --out runs/sweep_wsn --jobs 2",
        "wncs sweep scenarios/tank_sim.yaml --grid loops.level.tau_s=0.05,0.1,0.2"
        " --set loops.level.settling_band=0.02 --out runs/sweep_tank",
    ),
    description=(
        "Run a scenario on the direct engine at every point of a grid of overrides, in parallel "
        "processes, and write DIR/sweep.csv (one row per point: the grid values, then each "
        "loop's overshoot_pct, settling_time and iae and, with a coordination agent, its "
        "control period from the last assignment), the same table as DIR/sweep.parquet, and "
        "DIR/sweep.png (each loop's overshoot "
        "against the first axis, one line per value of the other axes). Each point is the "
        "scenario with the --set overrides and then the point's values applied as 'wncs run "
        "--set' applies them; a point that does not validate is refused (exit 2) before "
        "anything runs. Progress ('sweep: k/N') goes to stderr."
    ),
)


def _add_scale(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("n", type=int, metavar="N", help="number of loops (jcstr: even)")
    parser.add_argument("--out", required=True, metavar="FILE", help="scenario file to write")
    parser.add_argument("--plant", choices=PLANTS, default="tank", help="plant of every loop")
    parser.add_argument(
        "--per-gateway", type=int, default=10, metavar="K", help="loops per gateway (default 10)"
    )
    parser.add_argument(
        "--end-time", type=positive_float, default=None, metavar="T", help="end of the run"
    )
    parser.add_argument("--seed", type=int, default=0, help="the scenario's seed (default 0)")


def _scale(args: argparse.Namespace) -> int:
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


SCALE = Command(
    "scale",
    "write a scenario of N loops over WSN paths",
    _add_scale,
    _scale,
    examples=(
        "wncs scale 50 --out runs/scale50.yaml",
        "wncs scale 20 --plant jcstr --per-gateway 4 --out runs/jcstr20.yaml",
    ),
    description=(
        "Write a scenario file of N loops, each its own controller, every sensor two hops from a "
        "gateway over a lossy WSN, with set-point steps staggered across the loops (tank: N "
        "independent tanks of seed 002 with its non-linear PI, steps of 20 mm, 60 s; jcstr: N/2 "
        "reactors of seed 000's benchmark, 6 pu; tank_train: one plant of N such tanks in series, "
        "half of each outflow feeding the next, N coupled loops). Loops are grouped into areas "
        "of --per-gateway loops, each with its own gateway node. The file is validated before "
        "it is written; run it with wncs run."
    ),
)
