"""Every bad input is refused with exit code 2, naming the file, field or argument, without a
traceback and without half-written artefacts (issue 19, item 5: the cases found by probing)."""

from __future__ import annotations

import json
import shutil
import sqlite3

import pytest

from bus_schemas import codec
from cli.main import main
from core.errors import ProtocolError
from core.rounds import RoundPlanner
from tests.conftest import SCENARIOS

BENCH = SCENARIOS / "jcstr_benchmark.yaml"


def _refused(capsys, argv, *expected):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    for text in expected:
        assert text in err, err
    return err


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("loops.level.setpoint=.nan", "line 53: loops.level.setpoint: nan is not a finite number"),
        ("nodes.reactor.x0.H=.inf", "nodes.reactor.x0.H: inf is not a finite number"),
        ("nodes.level_controller.law.Kp=.nan", "nodes.level_controller.law.Kp: nan is not"),
        ("setpoints.0.value=-.inf", "setpoints.0.value: -inf is not a finite number"),
        ("end_time=1e300", "end_time: Input should be less than or equal to 1000000000"),
        ("setpoints.0.value=1e308", "setpoints.0.value: Input should be less than or equal"),
        (
            "loops.temperature.actuator=F_out",
            "loops.temperature.actuator: input 'F_out' of plant 'reactor' is already moved by "
            "loop 'level'",
        ),
    ],
)
def test_a_bad_value_is_refused_before_anything_is_written(override, message, tmp_path, capsys):
    out = tmp_path / "run"
    _refused(capsys, ["run", BENCH, "--engine", "direct", "--out", out, "--set", override], message)
    assert not out.exists()


def test_unlimited_actuator_limits_stay_allowed(capsys):
    assert main(["validate", str(BENCH), "--set", "nodes.level_controller.law.u_min=-.inf"]) == 0


def test_a_binary_or_deeply_nested_file_is_refused(tmp_path, capsys):
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"\xff\xfe\x00\x01garbage")
    _refused(capsys, ["validate", binary], str(binary), "not a text scenario: byte 0xff")
    nul = tmp_path / "nul.yaml"
    nul.write_text("name: x\x00\n")
    _refused(capsys, ["validate", nul], "NUL byte at offset 7")
    deep = tmp_path / "deep.yaml"
    deep.write_text("a: " + "[" * 100_000 + "]" * 100_000 + "\n")
    _refused(capsys, ["validate", deep], str(deep), "nested too deeply")


def test_an_unwritable_or_occupied_out_is_refused(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    _refused(
        capsys,
        ["run", BENCH, "--engine", "direct", "--out", blocker / "run"],
        f"--out {blocker / 'run'}: cannot write there",
    )
    out = tmp_path / "run"
    assert main(["run", str(BENCH), "--engine", "direct", "--out", str(out), "--quiet"]) == 0
    before = (out / "summary.json").read_text()
    _refused(
        capsys,
        ["run", BENCH, "--engine", "direct", "--out", out, "--quiet", "--set", "end_time=3"],
        "holds a run already (run.json)",
        "--force",
    )
    assert (out / "summary.json").read_text() == before  # untouched
    argv = ["run", BENCH, "--engine", "direct", "--out", out, "--quiet", "--force"]
    assert main([*map(str, argv), "--set", "end_time=3"]) == 0
    assert json.loads((out / "summary.json").read_text())["end_time"] == 3


def test_a_corrupt_history_and_a_dead_run_are_refused(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(BENCH, run / "scenario.yaml")
    (run / "run.json").write_text(
        json.dumps({"run_id": "r1", "endpoint": "tcp/127.0.0.1:1", "engine": "threads"})
    )
    (run / "history.sqlite").write_text("not a database")
    _refused(capsys, ["report", run], "history.sqlite: not a readable history")
    _refused(capsys, ["export", run, "--csv"], "not a readable history")
    _refused(capsys, ["inject", run, "setpoint", "level=0.72"], "no router answers at tcp/")
    _refused(capsys, ["inject", run, "setpoint", "level=1e308"], "beyond a physical value")


def test_a_run_stops_at_its_largest_number_of_rounds():
    planner = RoundPlanner(["a"], end=10**9, max_microsteps=10, max_rounds=5)
    with pytest.raises(ProtocolError, match="clock.max_rounds"):
        for t in range(1, 10):
            planner.advance_with({}, {"a": t})
    assert planner.round == 4


def test_a_history_row_that_fails_its_schema_is_listed_never_read(tmp_path, capsys):
    """A forged body the nodes refused but the historian kept (here: a delivered sample whose
    value is text, and a body that is not msgpack) is listed in the summary and left out of
    the traces, which equal the clean run's."""
    out = tmp_path / "run"
    argv = ["run", str(BENCH), "--engine", "threads", "--out", str(out), "--quiet"]
    assert main([*argv, "--set", "end_time=3"]) == 0
    clean = json.loads((out / "summary.json").read_text())
    with sqlite3.connect(out / "history.sqlite") as db:
        db.execute(
            "INSERT INTO messages (round, t, key, src, seq, body) VALUES (?, ?, ?, ?, ?, ?)",
            (5, 100_000, "loop/level/meas", "network", 999, codec.pack_mapping({"value": "abc"})),
        )
        db.execute(
            "INSERT INTO messages (round, t, key, src, seq, body) VALUES (?, ?, ?, ?, ?, ?)",
            (6, 100_000, "loop/level/u", "level_controller", 999, b"\xc1garbage"),
        )
    assert main(["report", str(out)]) == 0
    again = json.loads((out / "summary.json").read_text())
    listed = again["messages"]["invalid_in_history"]
    assert [(r["key"], r["seq"]) for r in listed] == [
        ("loop/level/meas", 999),
        ("loop/level/u", 999),
    ]
    assert again["loops"] == clean["loops"]
