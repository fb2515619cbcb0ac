"""Data-quality screening before the analysis (issue 16, item 2) and practical CSV input (item
3): frozen and compressed segments, spikes, quality and mode columns, PV far from SP, saturated
OP, each named with its rows; multi-line headers, --skip-rows, --start/--until/--window by row
or by time; hints in refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import lfilter  # noqa: TID253 - not a node: imports what it uses at the top

from agents.monitor.assess import assess, assess_csv, parse_time
from agents.monitor.config import MonitorConfig, ScreeningConfig
from agents.monitor.errors import DataError, QualityError
from agents.monitor.screening import label_mask, runs, spike_scores
from cli.main import main

PHI = 0.9
DELAY = 3
# Harris index of an AR(1) output under delay d: (1 + phi^2 + ... + phi^(2(d-1))) (1 - phi^2)
AR1_INDEX = (1 + PHI**2 + PHI**4) * (1 - PHI**2)


def _ar1(n: int, seed: int, *, mean: float = 1.22, scale: float = 0.004) -> np.ndarray:
    e = np.random.default_rng(seed).standard_normal(n + 200)
    return mean + scale * lfilter([1.0], [1.0, -PHI], e)[200:]


def _write(tmp_path: Path, header: str, rows: list[str], name: str = "loop.csv") -> Path:
    p = tmp_path / name
    p.write_text("\n".join([header, *rows]) + "\n")
    return p


def _cfg(**screening) -> MonitorConfig:
    return MonitorConfig(screening=ScreeningConfig(**screening))


def test_runs_and_label_mask():
    assert runs(np.array([0, 1, 1, 0, 1], dtype=bool)) == [(1, 3), (4, 5)]
    assert label_mask(["Good", " good ", "Bad", "1.0", "192", ""], ["good", "1"]).tolist() == [
        True,
        True,
        False,
        True,
        False,
        False,
    ]


def test_ar1_index_is_the_closed_form_without_findings():
    y = _ar1(5000, 1)
    res = assess({"PV": y}, "PV", DELAY)
    assert res.screening.findings == ()
    assert res.harris.index == pytest.approx(AR1_INDEX, abs=0.04)


def test_spike_is_named_and_no_longer_makes_the_loop_look_perfect():
    """One sample of 1000 in a PV of 1.22 +- 0.004: its variance dwarfs the rest, so the index
    of the raw data is ~1 (the spike is an unpredictable innovation); repaired, the AR(1)'s."""
    y = _ar1(751, 2)
    y[400] = 1000.0
    raw = assess({"PV": y}, "PV", DELAY, config=_cfg(spike="warn"))
    assert raw.harris.index > 0.9  # what the issue saw: "a perfect loop"
    res = assess({"PV": y}, "PV", DELAY)
    (f,) = res.screening.findings
    assert f.check == "spike" and f.rows == ((401, 401),) and f.action == "exclude"
    assert "spike: 'PV'" in res.notes[0] and "replaced by interpolation" in res.notes[0]
    assert res.harris.index == pytest.approx(AR1_INDEX, abs=0.12)
    assert res.harris.index < 0.7
    with pytest.raises(QualityError, match=r"spike: 'PV'.*rows 401 .*refused") as exc:
        assess({"PV": y}, "PV", DELAY, config=_cfg(spike="refuse"))
    assert exc.value.check == "spike" and exc.value.row == 401


def test_spike_scores_leave_sharp_genuine_features_alone():
    t = np.arange(5000)
    noise = 0.01 * np.random.default_rng(0).standard_normal(t.size)
    tri = 2 / np.pi * np.arcsin(np.sin(2 * np.pi * t / 15)) + noise
    assert spike_scores(tri).max() < 3.0  # threshold 8
    assert spike_scores(np.random.default_rng(1).standard_normal(5000)).max() < 5.0


def test_frozen_record_is_named_and_refused_when_too_little_is_left():
    """PV frozen over 80 % of the record: the 150 live rows are fewer than the 200 the model
    needs; with frozen=warn the index is computed, with the finding in the report."""
    y = _ar1(751, 3)
    y[150:] = y[150]
    with pytest.raises(QualityError, match=r"frozen.*longest clean stretch is rows 1-150"):
        assess({"PV": y}, "PV", DELAY)
    res = assess({"PV": y}, "PV", DELAY, config=_cfg(frozen="warn"))
    (f,) = res.screening.findings
    assert f.check == "frozen" and f.rows == ((151, 751),) and f.count == 601
    assert f.fraction == pytest.approx(601 / 751)
    assert "80 % of the record" in f.text


def test_frozen_block_excluded_keeps_the_longest_stretch():
    y = _ar1(3000, 4)
    y[1000:1100] = y[1000]
    res = assess({"PV": y}, "PV", DELAY)
    assert res.screening.flags == ("frozen",)
    assert (res.screening.first_row, res.screening.last_row) == (1101, 3000)
    assert res.n_samples == 1900 and "analysed rows 1101-3000" in " ".join(res.notes)


def test_compressed_straight_lines_are_named():
    y = _ar1(2000, 5)
    y[500:560] = np.linspace(y[500], y[559], 60)
    res = assess({"PV": y}, "PV", DELAY)
    (f,) = res.screening.findings
    assert f.check == "compressed" and f.rows == ((501, 560),) and f.action == "warn"


def test_pv_far_from_sp_is_named():
    """PV 0.01 +- 0.004 against SP 2.5: offset 2.49, about 270 times std(PV)."""
    pv = _ar1(1000, 6, mean=0.01)
    sp = np.full(1000, 2.5)
    res = assess({"PV": pv, "SP": sp}, "PV", DELAY, setpoint="SP")
    (f,) = res.screening.findings
    ratio = (2.5 - pv.mean()) / pv.std()
    assert f.check == "offset" and f"{ratio:.3g} times std(PV)" in f.text
    with pytest.raises(QualityError, match="does not track 'SP'"):
        assess({"PV": pv, "SP": sp}, "PV", DELAY, setpoint="SP", config=_cfg(offset="refuse"))


def test_saturated_output_is_named():
    pv = _ar1(1000, 7)
    op = np.clip(60 + 30 * np.random.default_rng(7).standard_normal(1000), 0, 100)
    share = np.mean((op == 0) | (op == 100))
    res = assess({"PV": pv, "OP": op}, "PV", DELAY, op="OP", op_limits=(0.0, 100.0))
    (f,) = res.screening.findings
    assert f.check == "saturation" and f.count == int(share * 1000)
    assert f"{100 * share:.0f} % of the rows" in f.text


def test_offline_quality_rows_are_named_and_excluded(tmp_path):
    """Rows 301-600 flagged Bad with the PV sitting at 0.01: excluded, the longest good
    stretch (601-2000) analysed, the AR(1)'s index found again."""
    pv = _ar1(2000, 8)
    pv[300:600] = 0.01 + 1e-4 * np.random.default_rng(9).standard_normal(300)
    q = ["Good"] * 2000
    q[300:600] = ["Bad"] * 300
    rows = [f"{k};2.5;{pv[k]:.8f};{q[k]}" for k in range(2000)]
    path = _write(tmp_path, "t;SP;PV;Q", rows)
    res = assess_csv(path, "PV", DELAY, quality="Q", good=["good"])
    (f,) = res.screening.findings
    assert f.check == "quality" and f.rows == ((301, 600),)
    assert (res.screening.first_row, res.screening.last_row) == (601, 2000)
    assert res.harris.index == pytest.approx(AR1_INDEX, abs=0.05)
    mode = ["AUTO"] * 2000
    mode[1500:] = ["MAN"] * 500
    rows = [f"{k};{pv[k]:.8f};{mode[k]}" for k in range(2000)]
    path = _write(tmp_path, "t;PV;MODE", rows, name="mode.csv")
    res = assess_csv(path, "PV", DELAY, mode="MODE")
    assert res.screening.findings[0].check == "mode"
    assert res.screening.findings[0].rows == ((1501, 2000),)


def test_multi_line_header_and_skip_rows(tmp_path):
    y = _ar1(600, 10)
    rows = [f"2024-03-01T00:{k // 60:02d}:{k % 60:02d};{v:.8f}" for k, v in enumerate(y)]
    lines = ["Export of unit 2", "tag;FIC101.PV", "description;flow", "time;PV", "s;m3/h"]
    path = _write(tmp_path, lines[0], lines[1:] + rows)
    data = assess_csv(path, "PV", DELAY)
    assert data.n_samples == 600
    assert data.harris.index == pytest.approx(
        assess({"PV": np.round(y, 8)}, "PV", DELAY).harris.index, rel=1e-9
    )
    # with --skip-rows the header is the line after the skipped ones
    with pytest.raises(DataError, match="column 'PV' not found"):
        assess_csv(path, "PV", DELAY, skip_rows=1)
    assert assess_csv(path, "PV", DELAY, skip_rows=3).n_samples == 600


def test_csv_start_until_window_by_row_and_by_time(tmp_path):
    y = _ar1(1200, 11)
    rows = [
        f"2024-03-01 {k // 3600:02d}:{k // 60 % 60:02d}:{k % 60:02d};{v:.8f}"
        for k, v in enumerate(y)
    ]
    path = _write(tmp_path, "time;PV", rows)
    ref = assess({"PV": np.round(y[99:1000], 8)}, "PV", DELAY).harris.index
    by_row = assess_csv(path, "PV", DELAY, start=100, until=1001)
    assert by_row.n_samples == 901 and by_row.harris.index == pytest.approx(ref, rel=1e-9)
    assert (by_row.screening.first_row, by_row.screening.last_row) == (100, 1000)
    by_time = assess_csv(
        path, "PV", DELAY, time="time", start="2024-03-01 00:01:39", until="2024-03-01 00:16:40"
    )
    assert by_time.n_samples == 901 and by_time.harris.index == pytest.approx(ref, rel=1e-9)
    last = assess_csv(path, "PV", DELAY, window=500)
    assert (last.screening.first_row, last.screening.last_row) == (701, 1200)
    assert parse_time("2024-03-01 00:01:40") - parse_time("2024-03-01T00:00:00") == 100.0


def test_refusal_hints_at_the_setpoint_column(tmp_path, capsys):
    """Set-point steps analysed on the PV alone: refused as non-stationary, with the hint to
    pass the file's set-point column; with it, assessed."""
    n = 2000
    sp = np.repeat([50.0, 51.0, 52.0, 53.0, 54.0], n // 5)  # a staircase of set-point steps
    pv = sp + 0.2 * lfilter([1.0], [1.0, -0.5], np.random.default_rng(12).standard_normal(n))
    rows = [f"{k};{sp[k]:.4f};{pv[k]:.8f}" for k in range(n)]
    path = _write(tmp_path, "t;FIC7.SP;FIC7.PV", rows)
    code = main(["assess", str(path), "--primary", "FIC7.PV", "--delays", "2"])
    out, err = capsys.readouterr()
    assert code == 3 and "Hint: the file has a set-point column 'FIC7.SP'" in out
    assert "pass --setpoint FIC7.SP" in out
    report = json.loads((tmp_path / "loop.assessment.json").read_text())
    assert report["harris"]["kind"] in ("integrating", "drift")
    code = main(
        ["assess", str(path), "--primary", "FIC7.PV", "--delays", "2", "--setpoint", "FIC7.SP"]
    )
    assert code == 0
    capsys.readouterr()


def test_cli_names_the_findings_and_never_prints_an_inverted_interval(tmp_path, capsys):
    """White noise under d = 1 (at minimum variance): an estimate above 1 is printed as such,
    with an ordered interval; a spike and a frozen stretch are named."""
    for seed in range(20):
        y = np.random.default_rng(seed).standard_normal(751)
        if assess({"PV": y}, "PV", 1).harris.index > 1.0:
            break
    else:
        pytest.fail("no white-noise record with an index above 1")
    y[700] = 500.0
    y[100:130] = y[100]
    path = _write(tmp_path, "PV", [f"{v:.10f}" for v in y])
    code = main(
        ["assess", str(path), "--primary", "PV", "--delays", "1", "--screen", "frozen=warn"]
    )
    out, _ = capsys.readouterr()
    assert code == 0
    assert "spike: 'PV'" in out and "frozen: 'PV'" in out and "rows 101-130" in out
    report = json.loads((tmp_path / "loop.assessment.json").read_text())
    h = report["harris"]
    assert h["ci"][0] <= h["index"] <= h["ci"][1]
    assert report["screening"]["flags"] == ["spike", "frozen"]
    if h["above_one"]:
        assert "above 1: estimation noise" in out
    code = main(
        ["assess", str(path), "--primary", "PV", "--delays", "1", "--screen", "frozen=refuse"]
    )
    _, err = capsys.readouterr()
    assert code == 2 and "data quality: frozen: 'PV'" in err and "refused" in err
