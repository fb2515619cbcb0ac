"""``wncs run --plots`` (issue 41, item 3): which figures a run draws, by its loops' count."""

from __future__ import annotations

import pytest

from cli.main import main
from core.errors import ConfigError
from runtime.launcher import launch
from runtime.report import AUTO_LOOPS, SUMMARY_FIGURE
from runtime.scale import write_scale
from tests.conftest import BENCHMARK


def _pngs(out) -> set[str]:
    return {p.name for p in out.glob("*.png")}


def test_a_few_loops_get_a_figure_each_and_none_draws_nothing(tmp_path):
    res = launch(BENCHMARK, tmp_path / "auto", engine="direct")
    assert res.code == 0, res.error
    assert _pngs(tmp_path / "auto") == {"level.png", "temperature.png"}
    res = launch(BENCHMARK, tmp_path / "none", engine="direct", plots="none")
    assert res.code == 0 and _pngs(tmp_path / "none") == set()
    res = launch(BENCHMARK, tmp_path / "summary", engine="direct", plots="summary")
    assert res.code == 0 and _pngs(tmp_path / "summary") == {SUMMARY_FIGURE}


def test_beyond_the_limit_one_summary_figure_and_report_draws_the_rest(tmp_path, capsys):
    scenario = tmp_path / "many.yaml"
    write_scale(AUTO_LOOPS + 2, scenario, plant="tank", end_time=2.0)
    out = tmp_path / "run"
    res = launch(scenario, out, engine="direct")
    assert res.code == 0, res.error
    assert _pngs(out) == {SUMMARY_FIGURE}
    assert (out / SUMMARY_FIGURE).read_bytes()[:4] == b"\x89PNG"
    assert main(["report", str(out), "--plots", "all"]) == 0
    loops = set(res.summary["loops"])
    assert len(loops) == AUTO_LOOPS + 2
    assert _pngs(out) == {SUMMARY_FIGURE} | {f"{n}.png" for n in loops}


def test_an_unknown_choice_is_refused_before_anything_starts(tmp_path):
    with pytest.raises(ConfigError, match="--plots"):
        launch(BENCHMARK, tmp_path / "x", engine="direct", plots="some")
    assert not (tmp_path / "x").exists()
