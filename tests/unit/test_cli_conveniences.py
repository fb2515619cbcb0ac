"""The CLI's conveniences (issue 17, items 3, 4 and 6): ``--version``, plain help texts ending in
examples that are real commands, ``wncs schema``, ``wncs validate`` (YAML errors with line and
column, model errors with the dotted field and its line, exit 2; 0 on every shipped scenario),
``--set`` (refused exactly like the same value in the file), and zenoh's own log lines kept off a
run's terminal output."""

from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest
import yaml

from cli.main import EXAMPLES, build_parser, main
from core.errors import ConfigError
from scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "scenarios"
SHIPPED = sorted(SCENARIOS.glob("*.yaml"))
TANK = SCENARIOS / "tank_sim.yaml"
SHORT = [  # the tank scenario cut to 5 s, one set point, no disturbances: a quick run
    "--set",
    "end_time=5",
    "--set",
    "disturbances=[]",
    "--set",
    "setpoints=[{t: 0.0, loop: level, value: 50.0}]",
]


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def _call(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _help(capsys, *argv: str) -> str:
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--help"])
    assert exc.value.code == 0
    return capsys.readouterr().out


@pytest.fixture
def sigterm_restored():
    """``wncs run`` installs a SIGTERM handler; put the test process's back."""
    before = signal.getsignal(signal.SIGTERM)
    yield
    signal.signal(signal.SIGTERM, before)


def _tank_copy(tmp_path: Path, *, tau_s: str | None = None) -> tuple[Path, int]:
    """tank_sim.yaml copied line for line (``tau_s`` of loop level replaced in place, if given);
    returns the path and the 1-based line of that ``tau_s``."""
    lines = TANK.read_text().splitlines()
    start = lines.index("loops:")
    (line,) = [i for i, t in enumerate(lines) if i > start and t.strip().startswith("tau_s:")]
    if tau_s is not None:
        indent = lines[line][: len(lines[line]) - len(lines[line].lstrip())]
        lines[line] = f"{indent}tau_s: {tau_s}"
    path = tmp_path / "tank.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path, line + 1


# -- version and help -----------------------------------------------------------------------------


def test_version_is_the_installed_distributions(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out == f"wncs {version('wncs')}\n"


@pytest.mark.parametrize("command", ["", *_subcommands()])
def test_help_is_plain_text_and_ends_with_examples(capsys, command):
    text = _help(capsys, *([command] if command else []))
    for markup in ("``", ":func:", ":mod:", ":class:", ":meth:"):
        assert markup not in text, (command, markup)
    assert "examples:" in text
    shown = text.split("examples:\n", 1)[1].splitlines()
    examples = EXAMPLES[command or "wncs"]
    assert [line.strip() for line in shown[: len(examples)]] == list(examples)
    if command:  # a subcommand's help ends with them
        assert [line.strip() for line in shown if line.strip()] == list(examples)


@pytest.mark.parametrize("command", ["", *_subcommands()])
def test_every_argument_has_a_help_string(command):
    parser = _subcommands()[command] if command else build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            continue
        assert action.help and action.help != argparse.SUPPRESS, (command, action.dest)


def test_every_command_has_examples():
    assert set(EXAMPLES) == {"wncs", *_subcommands()}
    assert all(1 <= len(lines) <= 3 for lines in EXAMPLES.values())


@pytest.mark.parametrize(
    "line", [line for lines in EXAMPLES.values() for line in lines], ids=lambda s: s[:60]
)
def test_examples_are_real_commands(line):
    """Each example parses; the scenarios it names are shipped, with the nodes and --set paths
    it names."""
    words = shlex.split(line)
    assert words[0] == "wncs"
    argv = words[1 : words.index(">")] if ">" in words else words[1:]
    args = build_parser().parse_args(argv)
    named = [w for w in argv if w.startswith("scenarios/")]
    for path in named:
        assert (ROOT / path).is_file(), path
    if getattr(args, "set", None):
        for path in named:
            load_scenario(ROOT / path, overrides=args.set)
    if args.command == "node":
        scenario = load_scenario(ROOT / args.scenario)
        assert args.name in {"clock", *scenario.participants()}
    if args.command == "analyze":
        assert load_scenario(ROOT / args.scenario).agent_node() is not None


# -- schema ---------------------------------------------------------------------------------------


def test_schema_is_the_scenario_models(capsys, tmp_path):
    code, out, _ = _call(capsys, "schema")
    assert code == 0
    printed = json.loads(out)
    assert printed == Scenario.model_json_schema()
    assert set(printed["properties"]) == set(Scenario.model_fields)
    assert "nodes" in printed["required"] and "loops" in printed["required"]

    target = tmp_path / "scenario.schema.json"
    code, out, _ = _call(capsys, "schema", "--out", str(target))
    assert code == 0 and str(target) in out
    assert json.loads(target.read_text()) == printed


# -- validate -------------------------------------------------------------------------------------


def test_validate_accepts_every_shipped_scenario(capsys):
    assert len(SHIPPED) >= 10
    code, out, err = _call(capsys, "validate", *map(str, SHIPPED))
    assert code == 0, err
    assert out.splitlines() == [f"ok: {p}" for p in SHIPPED]


def test_yaml_syntax_error_names_line_and_column(capsys, tmp_path):
    text = "name: bad\nend_time: 1.0\nnodes:\n  tank: {kind: plant, model: tank]\n"
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    lines = text.splitlines()
    line = next(i for i, t in enumerate(lines) if "]" in t)
    column = lines[line].index("]")
    code, out, err = _call(capsys, "validate", str(path))
    assert code == 2 and out == ""
    assert f"{path}: line {line + 1}, column {column + 1}: not valid YAML" in err, err


def test_bad_field_names_the_dotted_field_and_its_line(capsys, tmp_path):
    path, line = _tank_copy(tmp_path, tau_s="-0.1")
    code, out, err = _call(capsys, "validate", str(path))
    assert code == 2 and out == ""
    assert f"{path}: line {line}: loops.level.tau_s: Input should be greater than 0" in err, err


def test_a_bad_file_among_good_ones_fails_the_lot(capsys, tmp_path):
    bad, _ = _tank_copy(tmp_path, tau_s="-0.1")
    code, out, err = _call(capsys, "validate", str(TANK), str(bad))
    assert code == 2
    assert out.splitlines() == [f"ok: {TANK}"] and str(bad) in err


def test_validate_runs_as_a_command(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nnodes:\n  - [unclosed\n")
    done = subprocess.run(
        [sys.executable, "-m", "cli", "validate", str(TANK), str(bad)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert done.returncode == 2, done.stderr
    assert done.stdout.splitlines() == [f"ok: {TANK}"]
    assert f"{bad}: line 4, column 1: not valid YAML" in done.stderr, done.stderr


# -- --set ----------------------------------------------------------------------------------------


def test_set_bad_value_is_refused_like_the_same_value_in_the_file(capsys, tmp_path):
    path, _ = _tank_copy(tmp_path)
    code_set, out_set, err_set = _call(
        capsys, "validate", str(path), "--set", "loops.level.tau_s=-0.1"
    )
    _tank_copy(tmp_path, tau_s="-0.1")  # the same path, the value now written in the file
    code_file, out_file, err_file = _call(capsys, "validate", str(path))
    assert code_set == code_file == 2 and out_set == out_file == ""
    assert "loops.level.tau_s: Input should be greater than 0" in err_file
    assert err_set == err_file


def test_set_bad_value_starts_nothing(capsys, tmp_path, sigterm_restored):
    out_dir = tmp_path / "run"
    code, _, err = _call(
        capsys, "run", str(TANK), "--out", str(out_dir), "--set", "loops.level.tau_s=-0.1"
    )
    assert code == 2 and "loops.level.tau_s: Input should be greater than 0" in err
    assert not out_dir.exists()


@pytest.mark.parametrize(
    ("override", "field", "expected"),
    [
        ("loops.level.tau_s=0.2", lambda s: s.loops["level"].tau_s, 0.2),
        ("setpoints.1.value=80", lambda s: s.setpoints[1].value, 80.0),
        ("end_time=200", lambda s: s.end_time, 200.0),
        ("clock={may_drop: [operator]}", lambda s: tuple(s.clock.may_drop), ("operator",)),
    ],
)
def test_set_changes_the_validated_scenario(override, field, expected):
    assert field(load_scenario(TANK)) != expected
    assert field(load_scenario(TANK, overrides=[override])) == expected


def test_set_value_is_applied_before_validation_and_typed_as_yaml():
    """A string that validation would refuse where a number is expected; a YAML list for a list."""
    with pytest.raises(ConfigError, match=r"loops\.level\.tau_s: Input should be a valid number"):
        load_scenario(TANK, overrides=["loops.level.tau_s=fast"])
    scenario = load_scenario(TANK, overrides=SHORT[1::2])
    assert len(scenario.disturbances) == 0 and scenario.end_time == 5.0
    assert [(s.t, s.loop, s.value) for s in scenario.setpoints] == [(0.0, "level", 50.0)]


@pytest.mark.parametrize(
    ("override", "fragment"),
    [
        ("loops.levl.tau_s=0.2", "loops has no key 'levl' (keys: level;"),
        ("clock.may_drop=[operator]", "the scenario has no key 'clock' (keys: name, time_unit"),
        ("nodes.tank.params.b.x=1", "nodes.tank.params.b is 2.0, not a mapping or list"),
        ("setpoints.7.value=1", "setpoints has 3 items, no index 7"),
        ("setpoints.first.value=1", "setpoints is a list, 'first' is not an index"),
        ("loops.level.tau_s", "expected PATH=VALUE"),
        ("loops..tau_s=1", "empty segment"),
    ],
)
def test_bad_set_path_is_refused_naming_the_argument(capsys, override, fragment):
    code, out, err = _call(capsys, "validate", str(TANK), "--set", override)
    assert code == 2 and out == ""
    assert f"--set {override}: " in err and fragment in err, err


def test_run_uses_the_override(capsys, tmp_path, sigterm_restored):
    """The direct engine samples every 0.2 s with --set loops.level.tau_s=0.2 (file: 0.05 s),
    and the run directory keeps the scenario as run and the overrides."""
    out_dir = tmp_path / "run"
    argv = ["run", str(TANK), "--out", str(out_dir), "--engine", "direct", "--quiet", *SHORT]
    code, _, err = _call(capsys, *argv, "--set", "loops.level.tau_s=0.2")
    assert code == 0, err
    times = json.loads((out_dir / "summary.json").read_text())["loops"]["level"]["trace"]["t"]
    steps = {round(b - a, 9) for a, b in zip(times, times[1:], strict=False)}
    assert steps == {0.2}
    as_run = yaml.safe_load((out_dir / "scenario.yaml").read_text())
    assert as_run["loops"]["level"]["tau_s"] == 0.2 and as_run["end_time"] == 5.0
    run_info = json.loads((out_dir / "run.json").read_text())
    assert run_info["overrides"][-1] == "loops.level.tau_s=0.2"


# -- zenoh's own log lines ------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["run", "inject"])
def test_terminal_commands_start_zenoh_log_off(capsys, monkeypatch, tmp_path, command):
    """The commands whose process talks on the bus with the terminal as stdout start zenoh's
    logging at "off" (kernel.bus.init_zenoh_log: RUST_LOG still wins) before anything else."""
    levels: list[str] = []
    monkeypatch.setattr("cli.main.init_zenoh_log", levels.append)
    monkeypatch.setattr("cli.bus.signal.signal", lambda *args: None)
    argv = {
        "run": ["run", str(TANK), "--out", str(tmp_path / "o"), "--set", "loops.level.tau_s=-1"],
        "inject": ["inject", str(tmp_path / "nothing"), "node_down", "node=r1"],
    }[command]
    assert main(argv) == 2
    assert levels == ["off"]


@pytest.mark.slow
def test_zenoh_log_lines_stay_off_a_threads_run_unless_rust_log_asks(tmp_path):
    """Zenoh logs to the process's stdout; ``wncs run`` starts it at "off" unless RUST_LOG is
    set, so a normal run prints only its own lines. With RUST_LOG=info the same run shows
    zenoh's lines, so the check can fail."""
    env = {k: v for k, v in os.environ.items() if k != "RUST_LOG"}

    def run(out: str, **extra: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "cli", "run", str(TANK), "--out", str(tmp_path / out)]
            + ["--engine", "threads", *SHORT],
            capture_output=True,
            text=True,
            timeout=300,
            cwd=ROOT,
            env={**env, **extra},
        )

    quiet = run("quiet")
    assert quiet.returncode == 0, quiet.stderr
    assert "zenoh::" not in quiet.stdout + quiet.stderr
    assert quiet.stdout.startswith("tank_sim (threads engine, seed 0)"), quiet.stdout
    loud = run("loud", RUST_LOG="info")
    assert loud.returncode == 0, loud.stderr
    assert "zenoh::" in loud.stdout


@pytest.mark.slow
def test_processes_engine_gives_every_node_the_overrides(tmp_path):
    """Each node process loads the file itself: with the launcher passing --set on, the bus run
    equals the direct run of the same overrides, sample for sample."""
    overrides = [*SHORT, "--set", "loops.level.tau_s=0.2"]
    traces = {}
    for engine in ("processes", "direct"):
        out = tmp_path / engine
        done = subprocess.run(
            [sys.executable, "-m", "cli", "run", str(TANK), "--out", str(out)]
            + ["--engine", engine, "--quiet", *overrides],
            capture_output=True,
            text=True,
            timeout=300,
            cwd=ROOT,
        )
        assert done.returncode == 0, done.stderr
        traces[engine] = json.loads((out / "summary.json").read_text())["loops"]["level"]["trace"]
    assert traces["processes"] == traces["direct"]
    assert traces["direct"]["t"][:3] == [0.0, 0.2, 0.4]
