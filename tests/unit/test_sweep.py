"""``wncs sweep`` (issue 17, item 4): the grid's parsing, a bad point refused naming the --grid
argument before anything runs, and a 3 x 3 grid whose rows equal 9 separate direct runs of the
same overrides made through ``wncs run``'s own API (:func:`runtime.launcher.launch`)."""

from __future__ import annotations

import csv
import itertools
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from cli.main import main
from core.errors import ConfigError
from runtime.launcher import launch
from runtime.sweep import parse_axis, parse_range

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "scenarios" / "jcstr_benchmark.yaml"  # about 0.1 s a run on the direct engine
LEVEL = (0.1, 0.2, 0.3)
TEMPERATURE = (0.05, 0.1, 0.2)


@pytest.mark.parametrize(
    "text, expected",
    [
        ("0.1:0.4:7", (0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4)),
        ("0:1:3", (0.0, 0.5, 1.0)),
        ("2:5:4", (2, 3, 4, 5)),
        ("0.3:0.3:1", (0.3,)),
        ("0.1:0.9:1", (0.1,)),
        ("1:0:3", (1.0, 0.5, 0.0)),
    ],
)
def test_range_is_n_evenly_spaced_values_inclusive(text, expected):
    values = parse_range(text)
    assert values == expected
    assert [type(v) for v in values] == [type(v) for v in expected]


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("0.1:0.4:0", "n must be an integer >= 1, got '0'"),
        ("0.1:0.4:-2", "n must be an integer >= 1"),
        ("0.1:0.4:2.5", "n must be an integer >= 1, got '2.5'"),
        ("0.1:0.4:x", "n must be an integer >= 1"),
        ("0.1:0.4", "is not a:b:n"),
        ("a:0.4:3", "'a' is not a number"),
    ],
)
def test_bad_range_is_refused(text, fragment):
    with pytest.raises(ConfigError, match="^--grid") as err:
        parse_range(text, where="--grid")
    assert fragment in str(err.value)


def test_axis_lists_are_yaml_values():
    axis = parse_axis("nodes.network.topology.retry_limit=2,3, 5")
    assert axis.path == "nodes.network.topology.retry_limit" and axis.values == (2, 3, 5)
    assert parse_axis("loops.level.tau_s=0.1:0.2:2").values == (0.1, 0.2)
    with pytest.raises(ConfigError, match="expected PATH=a:b:n or PATH=x,y,z"):
        parse_axis("loops.level.tau_s")


def _call(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    "grid, value",
    [
        ("loops.level.tau_s=0.1,-0.2", "-0.2"),
        ("loops.level.tau_s=0.1:0.2:0", None),
        ("loops.level.nope=1,2", "1"),
    ],
)
def test_bad_grid_value_is_refused_naming_the_argument(capsys, tmp_path, grid, value):
    out = tmp_path / "sweep"
    code, _, err = _call(
        capsys,
        "sweep",
        BENCH,
        "--grid",
        "loops.temperature.tau_s=0.1",
        "--grid",
        grid,
        "--out",
        out,
    )
    assert code == 2, err
    assert f"wncs sweep: --grid {grid}: " in err
    if value is not None:
        assert f"value {value}: " in err
    assert not out.exists()  # refused before anything ran


def test_a_3x3_grid_equals_9_separate_runs(capsys, tmp_path):
    out = tmp_path / "sweep"
    code, _, err = _call(
        capsys,
        "sweep",
        BENCH,
        "--grid",
        "loops.level.tau_s=0.1:0.3:3",
        "--grid",
        "loops.temperature.tau_s=" + ",".join(map(str, TEMPERATURE)),
        "--set",
        "end_time=4.0",
        "--out",
        out,
        "--jobs",
        "2",
    )
    assert code == 0, err
    assert "sweep: 9/9" in err
    assert (out / "sweep.png").stat().st_size > 0
    with (out / "sweep.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 9
    table = pq.read_table(out / "sweep.parquet").to_pylist()  # the same table, types kept
    assert [list(r) for r in table] == [list(r) for r in rows]
    for got, row in zip(table, rows, strict=True):
        assert {k: "" if v is None else v for k, v in got.items()} == {
            k: "" if c == "" else float(c) for k, c in row.items()
        }
    for row, (level, temperature) in zip(rows, itertools.product(LEVEL, TEMPERATURE), strict=True):
        assert float(row["loops.level.tau_s"]) == level
        assert float(row["loops.temperature.tau_s"]) == temperature
        run = launch(
            BENCH,
            tmp_path / f"run_{level}_{temperature}",
            engine="direct",
            overrides=[
                "end_time=4.0",
                f"loops.level.tau_s={level}",
                f"loops.temperature.tau_s={temperature}",
            ],
        )
        assert run.code == 0
        for loop, figures in run.summary["loops"].items():
            for name in ("overshoot_pct", "settling_time", "iae"):
                expected = figures[name]
                cell = row[f"{loop}.{name}"]
                assert cell == "" if expected is None else float(cell) == expected, (
                    loop,
                    name,
                    cell,
                    expected,
                )
