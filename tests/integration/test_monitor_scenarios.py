"""Seed 004's contrast on the bus scenarios (direct engine for speed; the monitor's bus and CLI
agree, see test_monitor_bus.py): where the strong disturbance enters the jacket
(``cascade_routine.yaml``) the jacket temperature's components 1b + 2b dominate and a cascade on
it is predicted to pay off; where it enters the reactor itself (``cascade_routine_primary.yaml``)
2a dominates and even the optimistic end of the band leaves most of the variance."""

from __future__ import annotations

import json

import pytest

from cli.main import main as wncs
from tests.conftest import SCENARIOS

pytestmark = pytest.mark.slow


def _assess(tmp_path, name: str) -> dict:
    out = tmp_path / name
    assert (
        wncs(
            [
                "run",
                str(SCENARIOS / f"{name}.yaml"),
                "--out",
                str(out),
                "--engine",
                "direct",
                "--quiet",
            ]
        )
        == 0
    )
    args = ["assess", str(out), "--primary", "temperature", "--secondary", "reactor.y2,reactor.y3"]
    assert wncs([*args, "--delays", "3,1,3,1", "--window", "2000"]) == 0
    report = json.loads((out / "assessment_temperature.json").read_text())
    return {c["name"]: c for c in report["candidates"]}


def _shares(c: dict) -> dict:
    comp = c["components"]
    total = sum(comp.values())
    assert abs(total / c["variance"] - 1.0) <= 0.05  # the components account for the variance
    return {k: v / total for k, v in comp.items()}


def test_cascade_pays_off_when_the_disturbance_enters_the_jacket(tmp_path):
    jacket = _assess(tmp_path, "cascade_routine")["reactor.y2"]
    shares = _shares(jacket)
    assert shares["1b"] + shares["2b"] > 0.5
    assert jacket["prediction"]["band"][1] < 0.5 * jacket["variance"]  # even the pessimistic end


def test_cascade_helps_little_when_the_disturbance_enters_the_reactor(tmp_path):
    jacket = _assess(tmp_path, "cascade_routine_primary")["reactor.y2"]
    shares = _shares(jacket)
    assert shares["2a"] > 0.7
    assert (
        jacket["prediction"]["band"][1] > 0.9 * jacket["variance"]
    )  # the pessimistic end: ~nothing
