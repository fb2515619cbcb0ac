"""`wncs report DIR` redraws a run's plots and summary from what the run left behind."""

from __future__ import annotations

import json

import pytest

from cli.main import main
from runtime.launcher import launch
from tests.conftest import BENCHMARK


@pytest.mark.parametrize("engine", ["direct", "threads"])
def test_report_redraws_plots_and_summary(tmp_path, capsys, engine):
    out = tmp_path / engine
    res = launch(BENCHMARK, out, engine=engine)
    assert res.code == 0, res.error
    before = json.loads((out / "summary.json").read_text())
    for png in out.glob("*.png"):
        png.unlink()
    (out / "summary.json").unlink()
    assert main(["report", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "level" in printed and "temperature" in printed
    for loop in ("level", "temperature"):
        assert (out / f"{loop}.png").read_bytes()[:4] == b"\x89PNG"
    after = json.loads((out / "summary.json").read_text())
    assert after["loops"] == before["loops"]  # rebuilt from history.sqlite / record.json


def test_report_refuses_a_directory_that_is_not_a_run(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "not a run directory" in capsys.readouterr().err
