"""The performance monitor on the bus (threads engine, real router): every assessment it
publishes equals ``wncs assess RUN_DIR`` on the same data (same window), and the command gives
the same numbers on a direct-engine record of the same scenario."""

from __future__ import annotations

import json

import pytest

from agents.monitor.behaviour import assessment_body
from bus_schemas import MonitorAssessment, codec, keys
from cli.main import main
from core.time import to_ticks
from runtime.history import connect
from runtime.launcher import launch
from tests.conftest import SCENARIOS, write_variant

CASCADE = SCENARIOS / "cascade_routine.yaml"
END, START, WINDOW, PERIOD, MAX_ORDER = 1060.0, 50.0, 800, 150.0, 10


def shortened(data: dict) -> None:
    """The shipped scenario, shorter: 1060 min, an 800-sample window, an assessment every 150 min
    (the first one has too few samples), AR/VAR orders up to 10."""
    data["end_time"] = END
    data["nodes"]["monitor"].update(
        window=WINDOW, start=START, period=PERIOD, analysis={"max_order": MAX_ORDER}
    )


def cli_args(run_dir, until: float | None = None) -> list[str]:
    args = [
        "assess",
        str(run_dir),
        "--primary", "temperature",
        "--setpoint", "temperature.sp",
        "--secondary", "reactor.y2,reactor.y3",
        "--delays", "3,1,3,1",
        "--window", str(WINDOW),
        "--start", str(START),
        "--max-order", str(MAX_ORDER),
    ]  # fmt: skip
    return args + (["--until", str(until)] if until is not None else [])


def published(run_dir) -> list[MonitorAssessment]:
    with connect(run_dir / "history.sqlite") as conn:
        rows = conn.execute(
            "SELECT body FROM messages WHERE key = ? ORDER BY id",
            (keys.monitor_assessment("temperature"),),
        ).fetchall()
    return [MonitorAssessment.model_validate(codec.unpack_mapping(r[0])) for r in rows]


@pytest.fixture(scope="module")
def bus_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("monitor")
    scenario = write_variant(tmp, CASCADE, "cascade_short.yaml", shortened)
    result = launch(scenario, tmp / "threads", engine="threads")
    assert result.code == 0, result.error
    return scenario, tmp / "threads"


def test_node_assessments_equal_the_command_on_the_same_data(bus_run, capsys):
    _, run_dir = bus_run
    bodies = published(run_dir)
    times = [150.0 * k for k in range(1, 8)] + [END]
    assert [b.until for b in bodies] == [to_ticks(t) for t in times]
    assert [b.final for b in bodies] == [False] * 7 + [True]
    first = bodies[0]
    assert first.status == "insufficient_data" and first.n_samples == 100
    assert first.text == "100 samples in the window; the analysis needs 200"
    code = main(cli_args(run_dir, until=150.0))
    assert code == 2 and "100 samples in the window; the model needs at least 200" in (
        capsys.readouterr().err
    )
    for body in bodies[1:]:
        assert body.status == "ok"
        until = body.until / 1_000_000
        out = run_dir / f"cli_{until:g}.json"
        code = main([*cli_args(run_dir, until=None if body.final else until), "--out", str(out)])
        # short windows may leave a slow candidate unidentifiable (exit 3), as in the node
        parts = [body.harris, *body.candidates]
        assert code == (0 if all(p.status == "ok" for p in parts) else 3)
        report = json.loads(out.read_text())
        assert assessment_body(report, final=body.final) == body  # exactly, every figure
    final = bodies[-1]
    assert all(c.status == "ok" for c in final.candidates)
    assert final.n_samples == WINDOW and final.t_last == to_ticks(END - 1.0)
    assert final.t_first == to_ticks(END - WINDOW)
    assert final.ranking == ("reactor.y2", "reactor.y3") and final.secondary == "reactor.y2"
    assert final.cascade is True and 0.0 < final.harris.index < 0.5
    y2 = final.candidates[0]
    assert y2.reduction > 0.5 and y2.band[0] < y2.band[1]
    capsys.readouterr()


def test_direct_engine_record_gives_the_same_assessment(bus_run, tmp_path, capsys):
    """Engines agree on the traces, so the command reads the same series from record.json."""
    scenario, run_dir = bus_run
    direct = launch(scenario, tmp_path / "direct", engine="direct")
    assert direct.code == 0, direct.error
    reports = {}
    for name, d in (("bus", run_dir), ("direct", tmp_path / "direct")):
        out = tmp_path / f"{name}.json"
        assert main([*cli_args(d), "--out", str(out)]) == 0
        reports[name] = json.loads(out.read_text())
    capsys.readouterr()
    a, b = reports["bus"], reports["direct"]
    assert a["data"]["engine"] == "threads" and b["data"]["engine"] == "direct"
    for key in ("harris", "candidates", "ranking", "variance", "recommendation"):
        assert a[key] == b[key]
    assert a["window"] == b["window"]


def test_run_directory_refusals(bus_run, capsys):
    _, run_dir = bus_run
    args = ["assess", str(run_dir), "--delays", "3,1"]
    assert main([*args, "--primary", "temperature", "--secondary", "reactor.T_j"]) == 2
    assert "'reactor.T_j' is not a column of this run" in capsys.readouterr().err
    assert main([*args, "--primary", "level", "--secondary", "reactor.y2"]) == 2
    assert "'level' is not a loop of this run" in capsys.readouterr().err
    assert (
        main([*args, "--primary", "temperature", "--secondary", "reactor.y2", "--setpoint", "SP"])
        == 2
    )
    assert "--setpoint: in a run directory" in capsys.readouterr().err
