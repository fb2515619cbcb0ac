"""Routine-data CSV as historians export it: reading, refusals naming column and row, assess."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.monitor.assess import MonitorConfig, assess, assess_csv, rows_needed
from agents.monitor.errors import DataError
from agents.monitor.routine_data import load_routine_csv
from controllers.cascade.model import SFBPI
from controllers.cascade.tuning import EXAMPLE_SFB
from plants.cascade.examples import EXAMPLE_1
from plants.cascade.routine import simulate

HEADER = "time;SP;PV;OP;T2"


def _write(tmp_path: Path, lines: list[str], name: str = "loop.csv") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return p


def _rows(n: int, *, decimal: str = ".") -> list[str]:
    rng = np.random.default_rng(0)
    out = []
    for k in range(n):
        pv, op, t2 = 50 + rng.normal(), 30 + rng.normal(), 120 + rng.normal()
        cells = [f"{pv:.4f}", f"{op:.4f}", f"{t2:.4f}"]
        if decimal == ",":
            cells = [c.replace(".", ",") for c in cells]
        out.append(f"2024-03-01 00:{k // 60:02d}:{k % 60:02d};50.0;" + ";".join(cells))
    return out


def test_reads_semicolon_export_with_text_time_and_decimal_comma(tmp_path):
    lines = [HEADER] + [r.replace("50.0", "50,0") for r in _rows(300, decimal=",")] + [""]
    p = _write(tmp_path, lines)
    data = load_routine_csv(p, ["SP", "PV", "T2"], ";", decimal=",", constant_ok=["SP"])
    assert data.n_rows == 300
    assert data["SP"][0] == 50.0
    assert 45 < data["PV"].mean() < 55
    assert data.header == ("time", "SP", "PV", "OP", "T2")


def test_comma_separated_and_bom(tmp_path):
    lines = ["\ufefftime,PV,T2"] + [f"{k},{np.sin(k)},{np.cos(k)}" for k in range(50)]
    p = _write(tmp_path, lines)
    data = load_routine_csv(p, ["PV", "T2"], ",")
    assert data["PV"][3] == pytest.approx(np.sin(3))


@pytest.mark.parametrize(
    "cell, message",
    [
        ("", "missing value"),
        ("NA", "missing value"),
        ("#N/A", "missing value"),
        ("NaN", "missing value"),
        ("abc", "non-numeric value 'abc'"),
        ("49..2", "non-numeric value '49..2'"),
        ("inf", "non-finite value 'inf'"),
    ],
)
def test_bad_cell_names_column_and_row(tmp_path, cell, message):
    rows = _rows(300)
    fields = rows[6].split(";")
    fields[2] = cell  # PV of data row 7 (file line 8)
    rows[6] = ";".join(fields)
    p = _write(tmp_path, [HEADER] + rows)
    with pytest.raises(DataError) as exc:
        load_routine_csv(p, ["SP", "PV", "T2"], ";", constant_ok=["SP"])
    assert exc.value.column == "PV" and exc.value.row == 7
    text = str(exc.value)
    assert "column 'PV', row 7 (line 8)" in text and message in text


def test_short_row_is_a_missing_value(tmp_path):
    rows = _rows(300)
    rows[41] = ";".join(rows[41].split(";")[:3])  # row 42 lacks OP and T2
    p = _write(tmp_path, [HEADER] + rows)
    with pytest.raises(DataError, match=r"column 'T2', row 42 .*missing value .*3 of 5 fields"):
        load_routine_csv(p, ["PV", "T2"], ";")


def test_decimal_comma_without_the_option_is_explained(tmp_path):
    p = _write(tmp_path, [HEADER] + _rows(300, decimal=","))
    with pytest.raises(DataError, match=r"column 'PV', row 1 .*non-numeric.*decimal=','"):
        load_routine_csv(p, ["PV"], ";")


def test_constant_column_is_refused_unless_allowed(tmp_path):
    p = _write(tmp_path, [HEADER] + _rows(300))
    with pytest.raises(DataError) as exc:
        load_routine_csv(p, ["SP", "PV"], ";")
    assert exc.value.column == "SP"
    assert "column 'SP' is constant (50 in all 300 rows" in str(exc.value)
    load_routine_csv(p, ["SP", "PV"], ";", constant_ok=["SP"])


def test_too_few_rows_for_the_model(tmp_path):
    p = _write(tmp_path, [HEADER] + _rows(120))
    need = rows_needed(MonitorConfig())
    with pytest.raises(DataError, match=rf"has 120 data rows; the model needs at least {need}"):
        load_routine_csv(p, ["PV", "T2"], ";", min_rows=need)
    with pytest.raises(DataError, match="120 data rows"):
        assess_csv(p, "PV", 6, [("T2", 5, 1)])


def test_missing_column_and_wrong_separator(tmp_path):
    p = _write(tmp_path, [HEADER] + _rows(10))
    with pytest.raises(DataError) as exc:
        load_routine_csv(p, ["PV", "TT101"], ";")
    assert exc.value.column == "TT101"
    assert "column 'TT101' not found" in str(exc.value) and "'T2'" in str(exc.value)
    with pytest.raises(DataError, match=r"is the separator ','\?"):
        load_routine_csv(p, ["PV"], ",")


def test_empty_and_unreadable_files(tmp_path):
    with pytest.raises(DataError, match="empty"):
        load_routine_csv(_write(tmp_path, ["", ""]), ["PV"], ";")
    with pytest.raises(DataError, match="cannot read"):
        load_routine_csv(tmp_path / "nope.csv", ["PV"], ";")


def test_assess_csv_end_to_end_matches_arrays(tmp_path):
    run = simulate(EXAMPLE_1, SFBPI(EXAMPLE_SFB["example_1"]), 3000, np.random.default_rng(2))
    sp = 80.0
    lines = [HEADER]
    for k in range(run.t.size):
        pv = sp + run.measured["y1"][k]
        t2 = 150.0 + run.measured["y2"][k]
        lines.append(f"{k};{sp:.1f};{pv:.10f};{run.u[k]:.10f};{t2:.10f}")
    p = _write(tmp_path, lines)
    res = assess_csv(p, "PV", 6, [("T2", 5, 1)], setpoint="SP", sep=";")
    ref = assess({"PV": -run.measured["y1"], "T2": run.measured["y2"]}, "PV", 6, [("T2", 5, 1)])
    c, r = res.candidates[0].decomposition, ref.candidates[0].decomposition
    assert c.components.c1a == pytest.approx(r.components.c1a, rel=1e-6)
    assert res.harris.index == pytest.approx(ref.harris.index, rel=1e-6)
    d = res.to_dict()
    assert d["source"] == str(p) and d["ranking"] == ["T2"]
    assert d["recommendation"]["secondary"] == "T2"
    json.dumps(d, allow_nan=False)


def test_binary_file_is_refused(tmp_path):
    p = tmp_path / "dump.csv"
    p.write_bytes(b"PV;T2\n\xff\xfe\x00\x01;2\n")
    with pytest.raises(DataError, match="not a readable"):
        load_routine_csv(p, ["PV"], ";")
