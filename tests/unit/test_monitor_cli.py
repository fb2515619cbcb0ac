"""``wncs assess`` on CSV files: the printed and written report, refusals naming column and row
(exit 2), unidentifiable parts with their reason (exit 3), bad arguments (exit 2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cli.main import main
from controllers.cascade.model import SFBPI
from controllers.cascade.tuning import EXAMPLE_SFB
from plants.cascade.examples import EXAMPLE_1, EXAMPLE_3
from plants.cascade.routine import simulate
from runtime.assess import parse_delays

HEADER = "time;SP;PV;OP;T2;T3"


def _csv(tmp_path: Path, run, *, name: str = "loop.csv", edit=None, rows: int | None = None):
    """A historian-style export: SP constant, PV = SP + y1, T2/T3 around their operating points."""
    n = run.t.size if rows is None else rows
    y3 = run.measured.get("y3", np.zeros(run.t.size))
    lines = [HEADER]
    for k in range(n):
        cells = [
            f"2024-03-01 {k // 3600:02d}:{k // 60 % 60:02d}:{k % 60:02d}",
            "80.0",
            f"{80.0 + run.measured['y1'][k]:.10f}",
            f"{run.u[k]:.10f}",
            f"{150.0 + run.measured['y2'][k]:.10f}",
            f"{120.0 + y3[k]:.10f}",
        ]
        if edit is not None:
            edit(k, cells)
        lines.append(";".join(cells))
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def example_1():
    return simulate(EXAMPLE_1, SFBPI(EXAMPLE_SFB["example_1"]), 3000, np.random.default_rng(2))


@pytest.fixture(scope="module")
def example_3():
    return simulate(EXAMPLE_3, SFBPI(EXAMPLE_SFB["example_3"]), 4000, np.random.default_rng(4))


def _assess(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["assess", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_two_candidates_printed_ranked_and_written_next_to_the_data(tmp_path, capsys, example_3):
    """Example 3 (u -> y3 -> y2 -> y1): T2 = y2 (d1 5, d2 2) ranks before T3 = y3 (d1 6, d2 1)."""
    path = _csv(tmp_path, example_3)
    code, out, err = _assess(
        capsys,
        str(path),
        "--primary", "PV", "--setpoint", "SP", "--secondary", "T3,T2", "--delays", "6,1,5,2",
    )  # fmt: skip
    assert code == 0, err
    report = json.loads((tmp_path / "loop.assessment.json").read_text())
    assert report["ranking"] == ["T2", "T3"]
    assert report["setpoint"] == "SP" and report["data"] == {
        "kind": "csv",
        "path": str(path),
        "rows": 4000,
    }
    assert 0.0 < report["harris"]["index"] < 1.0 and report["harris"]["std"] > 0.0
    by = {c["name"]: c for c in report["candidates"]}
    assert (by["T2"]["d1"], by["T2"]["d2"], by["T3"]["d1"], by["T3"]["d2"]) == (5, 2, 6, 1)
    for c in by.values():
        comp = c["components"]
        assert sum(comp.values()) == pytest.approx(report["variance"], rel=0.02)
        lo, hi = c["prediction"]["band"]
        assert lo == pytest.approx(comp["1a"] + comp["2a"] / 2) and hi == pytest.approx(
            comp["1a"] + comp["2a"]
        )
    h = report["harris"]
    assert f"Harris index {h['index']:.3f} +- {h['std']:.3f}" in out
    assert "control error SP - PV; delay d = 7 samples" in out
    assert "T2 (d1 = 5, d2 = 2)" in out and "1a " in out and "2b " in out
    assert "under cascade" in out and "Ranking: 1. T2  2. T3" in out
    assert "Recommendation: cascade with 'T2'" in out
    assert f"report written to {tmp_path / 'loop.assessment.json'}" in out


def test_harris_only_and_explicit_out(tmp_path, capsys, example_1):
    path = _csv(tmp_path, example_1)
    out_file = tmp_path / "elsewhere" / "r.json"
    out_file.parent.mkdir()
    code, out, _ = _assess(
        capsys, str(path), "--primary", "PV", "--delays", "6", "--out", str(out_file)
    )
    assert code == 0
    report = json.loads(out_file.read_text())
    assert report["candidates"] == [] and report["delay"] == 6
    assert "Candidate" not in out and "Harris index" in out


def _cell(column: str, row: int, value: str):
    index = HEADER.split(";").index(column)

    def edit(k: int, cells: list[str]) -> None:
        if k == row - 1:
            cells[index] = value

    return edit


@pytest.mark.parametrize(
    "edit, column, message",
    [
        (_cell("PV", 1234, ""), "PV", "column 'PV', row 1234 (line 1235): missing value"),
        (_cell("T2", 77, "NaN"), "T2", "column 'T2', row 77 (line 78): missing value"),
        (_cell("T2", 5, "12,5"), "T2", "column 'T2', row 5 (line 6): non-numeric value '12,5'"),
        (_cell("PV", 2999, "err"), "PV", "column 'PV', row 2999 (line 3000): non-numeric"),
        (
            lambda k, cells: cells.__setitem__(4, "150.0"),
            "T2",
            "column 'T2' is constant (150 in all 3000 rows",
        ),
    ],
    ids=["empty", "nan", "decimal-comma", "text", "constant"],
)
def test_bad_data_exit_2_naming_column_and_row(tmp_path, capsys, example_1, edit, column, message):
    path = _csv(tmp_path, example_1, edit=edit)
    code, out, err = _assess(
        capsys, str(path), "--primary", "PV", "--secondary", "T2", "--delays", "5,1"
    )
    assert code == 2 and out == ""
    assert err.startswith("wncs assess: ") and message in err and f"'{column}'" in err
    assert not (tmp_path / "loop.assessment.json").exists()


def test_too_few_rows_exit_2(tmp_path, capsys, example_1):
    path = _csv(tmp_path, example_1, rows=150)
    code, _, err = _assess(
        capsys, str(path), "--primary", "PV", "--secondary", "T2", "--delays", "5,1"
    )
    assert code == 2
    assert "has 150 data rows; the model needs at least 335" in err


def test_scaled_copy_is_unidentifiable_exit_3(tmp_path, capsys, example_1):
    """T3 = -3 PV + 5: reported with its reason, no numbers; T2 still assessed, report written."""

    def copy(k: int, cells: list[str]) -> None:
        cells[5] = f"{-3.0 * float(cells[2]) + 5.0:.10f}"

    path = _csv(tmp_path, example_1, edit=copy)
    code, out, err = _assess(
        capsys, str(path), "--primary", "PV", "--secondary", "T2,T3", "--delays", "5,1,5,1"
    )
    assert code == 3
    assert "wncs assess: unidentifiable: secondary 'T3': collinear" in err
    assert "T3 (d1 = 5, d2 = 1): unidentifiable (collinear)" in out
    report = json.loads((tmp_path / "loop.assessment.json").read_text())
    bad = next(c for c in report["candidates"] if c["name"] == "T3")
    assert bad["status"] == "unidentifiable" and bad["reason"] == "collinear"
    assert "components" not in bad and report["ranking"] == ["T2"]


def test_silent_disturbance_channel_exit_3(tmp_path, capsys):
    """No disturbance enters the secondary (and no measurement noise): T2 is an exact function
    of the past, so its channel cannot be identified."""
    stages = tuple(
        s.model_copy(
            update={"meas_noise_std": 0.0, **({"noise_std": 0.0} if s.name == "y2" else {})}
        )
        for s in EXAMPLE_1.stages
    )
    proc = EXAMPLE_1.model_copy(update={"stages": stages})
    run = simulate(proc, SFBPI(EXAMPLE_SFB["example_1"]), 3000, np.random.default_rng(5))
    path = _csv(tmp_path, run)
    code, out, err = _assess(
        capsys, str(path), "--primary", "PV", "--secondary", "T2", "--delays", "5,1"
    )
    assert code == 3
    assert "secondary 'T2': silent_channel" in err and "secondary channel" in err
    assert json.loads((tmp_path / "loop.assessment.json").read_text())["ranking"] == []


@pytest.mark.parametrize(
    "args, message",
    [
        (["--secondary", "T2", "--delays", "5"], "give d1,d2 for each of the 1 secondaries"),
        (["--secondary", "T2,T3", "--delays", "5,1,5,2"], "every pair must add up"),
        (["--secondary", "T2", "--delays", "5,x"], "expected integers"),
        (["--secondary", "T2", "--delays", "6,0"], "d2 >= 1"),
        (["--secondary", "TT101", "--delays", "5,1"], "column 'TT101' not found"),
        (["--secondary", "T2", "--delays", "5,1", "--window", "0"], "--window: must be >= 1"),
        (["--secondary", "T2", "--delays", "5,1", "--start", "x"], "pass --time COL"),
        (["--delays", "5", "--screen", "frozen=drop"], "--screen frozen: Input should be"),
        (["--delays", "5", "--screen", "frozen"], "--screen: expected KEY=VALUE"),
        (["--delays", "5", "--op-limits", "100,0"], "--op-limits: LO must be below HI"),
        (["--secondary", "T2", "--delays", "5,1", "--max-order", "0"], "--max-order"),
        (["--secondary", "T2", "--delays", "5,1", "--sep", ","], "is the separator ','?"),
    ],
)
def test_bad_arguments_exit_2(tmp_path, capsys, example_1, args, message):
    path = _csv(tmp_path, example_1, rows=400)
    code, _, err = _assess(capsys, str(path), "--primary", "PV", *args)
    assert code == 2 and message in err, err


def test_missing_data_and_argparse_errors(tmp_path, capsys):
    code, _, err = _assess(capsys, str(tmp_path / "none.csv"), "--primary", "PV", "--delays", "3")
    assert code == 2 and "does not exist" in err
    with pytest.raises(SystemExit) as exc:
        main(["assess", str(tmp_path), "--delays", "3"])
    assert exc.value.code == 2
    capsys.readouterr()


def test_parse_delays():
    d, specs = parse_delays("5,2,6,1", ["y2", "y3"])
    assert d == 7 and [(s.name, s.d1, s.d2) for s in specs] == [("y2", 5, 2), ("y3", 6, 1)]
    assert parse_delays("4", []) == (4, [])
    with pytest.raises(ValueError, match="d alone"):
        parse_delays("3,1", [])
