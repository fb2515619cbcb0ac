"""``wncs export RUN_DIR --csv|--parquet`` (issue 17, item 6): a direct run's CSV files hold its
record (``record.json``, read here independently as JSON), and the Parquet files hold the same
tables as the CSV files (read back with pyarrow)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from cli.main import main
from core.time import TICKS_PER_UNIT
from runtime.launcher import launch

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "scenarios" / "jcstr_benchmark.yaml"


def _num(cell: str) -> float | None:
    return None if cell == "" else float(cell)


def _rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open(newline="") as f:
        header, *rows = list(csv.reader(f))
    return header, rows


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "run"
    result = launch(BENCH, out, engine="direct", overrides=["end_time=3.0"])
    assert result.code == 0, result.error
    return out


def test_csv_files_hold_the_runs_record(capsys, run_dir, tmp_path):
    out = tmp_path / "csv"
    assert main(["export", str(run_dir), "--csv", "--out", str(out)]) == 0
    assert "wrote 4 CSV files" in capsys.readouterr().out
    record = json.loads((run_dir / "record.json").read_text())
    for name, loop in record["loops"].items():
        header, rows = _rows(out / f"loop_{name}.csv")
        assert header == ["t", "t_sampled", "y", "setpoint", "u"]
        assert len(rows) == len(loop["t"]) > 0
        steps = loop["setpoints"]
        columns = (loop["t"], loop["t_sampled"], loop["y"], loop["u"])
        for row, t, ts, y, u in zip(rows, *columns, strict=True):
            expected_sp = [v for at, v in steps if at <= t][-1]
            assert [_num(c) for c in row] == [
                t / TICKS_PER_UNIT,
                ts / TICKS_PER_UNIT,
                y,
                expected_sp,
                u,
            ]
    for name, plant in record["plants"].items():
        header, rows = _rows(out / f"plant_{name}.csv")
        assert header == ["t", *plant["state_names"]]
        assert [[float(c) for c in r] for r in rows] == [
            [t / TICKS_PER_UNIT, *x] for t, x in zip(plant["t"], plant["x"], strict=True)
        ]
    summary = json.loads((run_dir / "summary.json").read_text())
    header, rows = _rows(out / "network_paths.csv")
    assert [r[0] for r in rows] == sorted(summary["network"]["paths"])
    for row in rows:
        stats = summary["network"]["paths"][row[0]]
        assert {h: _num(c) for h, c in zip(header[1:], row[1:], strict=True)} == stats


def test_default_out_is_the_run_directorys_csv(capsys, run_dir):
    assert main(["export", str(run_dir), "--csv"]) == 0
    assert (run_dir / "csv" / "loop_level.csv").is_file()


def test_parquet_files_hold_the_csv_tables(capsys, run_dir, tmp_path):
    assert main(["export", str(run_dir), "--csv", "--out", str(tmp_path / "csv")]) == 0
    assert main(["export", str(run_dir), "--parquet", "--out", str(tmp_path / "pq")]) == 0
    assert "wrote 4 PARQUET files" in capsys.readouterr().out
    csv_files = sorted(p.stem for p in (tmp_path / "csv").glob("*.csv"))
    assert sorted(p.stem for p in (tmp_path / "pq").glob("*.parquet")) == csv_files
    for stem in csv_files:
        header, rows = _rows(tmp_path / "csv" / f"{stem}.csv")
        table = pq.read_table(tmp_path / "pq" / f"{stem}.parquet").to_pydict()
        assert list(table) == header
        for k, name in enumerate(header):
            column = table[name]
            cells = [r[k] for r in rows]
            if stem.startswith("network_paths") and name == "loop":
                assert column == cells
            else:
                assert column == [_num(c) for c in cells], (stem, name)


def test_not_a_run_directory_is_refused(capsys, tmp_path):
    assert main(["export", str(tmp_path), "--csv"]) == 2
    assert "not a run directory" in capsys.readouterr().err
