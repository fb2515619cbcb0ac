"""`wncs run` and `wncs report` draw the MRAC's Fig. 6.3-6.5 and theta's drift (seed 003) for every
multi-loop controller whose law is the MRAC, on any engine, and nothing of the kind otherwise.

What the figures hold is checked in ``tests/unit/test_mrac_plots.py``.
"""

from __future__ import annotations

import struct

import pytest

from cli.main import main
from runtime.launcher import launch
from tests.conftest import BENCHMARK, SCENARIOS, write_variant

FIGURES = ("states", "outputs", "errors", "theta")


def _png_size(path):
    """Width and height of a PNG from its signature and IHDR chunk (fails on anything else)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name} is not a PNG"
    assert data[12:16] == b"IHDR", f"{path.name}: no IHDR chunk"
    return struct.unpack(">II", data[16:24])


@pytest.mark.parametrize("engine", ["direct", "threads"])
def test_run_and_report_draw_the_mrac_figures(tmp_path, capsys, engine):
    def shorten(d):
        d["end_time"] = 2.0
        d["setpoints"] = [{"t": 1.0, "loop": "x1", "value": -0.5}]

    scenario = write_variant(tmp_path, SCENARIOS / "column_mrac.yaml", "short.yaml", shorten)
    out = tmp_path / engine
    res = launch(scenario, out, engine=engine)
    assert res.code == 0, res.error
    expected = {f"mrac_mrac_{key}.png" for key in FIGURES}
    assert expected <= {p.name for p in out.glob("*.png")}
    for png in out.glob("*.png"):
        png.unlink()
    assert main(["report", str(out)]) == 0
    printed = capsys.readouterr().out
    drawn = {p.name for p in out.glob("mrac_*.png")}
    assert drawn == expected
    for name in sorted(drawn):
        width, height = _png_size(out / name)
        assert width > 300 and height > 200
        assert str(out / name) in printed  # `wncs report` lists it


def test_a_run_without_an_mrac_draws_no_mrac_figures(tmp_path):
    out = tmp_path / "run"
    res = launch(BENCHMARK, out, engine="direct")
    assert res.code == 0, res.error
    assert main(["report", str(out)]) == 0
    assert list(out.glob("*.png"))  # the per-loop plots
    assert not list(out.glob("mrac_*"))
