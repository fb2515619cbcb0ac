"""Seed 004's prediction against reality on the platform's own scenarios (issue 7): the monitor
assesses the simple-feedback run of ``cascade_routine.yaml`` / ``cascade_routine_primary.yaml``,
then the same process (same disturbances, seeds, sensor noise) is switched to the PI-P cascade
(``type: pip_cascade``, settings :data:`controllers.cascade.law.ROUTINE_CASCADE`) on each
secondary, and the variance of the control error is measured over the same window (direct
engine; ``bench/monitor_cascade_switch.py`` prints the table).

The band is ``[1a + 2a/2, 1a + 2a]`` (the cascade removes at most half of 2a), 1a the floor."""

from __future__ import annotations

import numpy as np
import pytest

from agents.monitor.config import MonitorConfig, SecondarySpec
from agents.monitor.run_data import RunSeries, assess_series, feed_run_record
from controllers.cascade.law import ROUTINE_CASCADE, cascade_variant
from core.time import to_ticks
from runtime.direct import simulate
from scenario import Scenario, parse_scenario
from scenario.views import run_shape
from tests.conftest import SCENARIOS, load_yaml

LOOP, WINDOW, START = "temperature", 2000, 100.0
COLUMNS = {"reactor.y2": "y2", "reactor.y3": "y3"}


def _series(scenario: Scenario, rec, columns) -> RunSeries:
    series = RunSeries(
        run_shape(scenario), LOOP, [f"{LOOP}.sp", *columns], start=to_ticks(START), window=WINDOW
    )
    feed_run_record(rec, series, until=to_ticks(scenario.end_time))
    return series


@pytest.fixture(scope="module", params=["cascade_routine", "cascade_routine_primary"])
def switch(request) -> dict:
    """The monitor's assessment of the simple-feedback run and the measured variance under the
    cascade on each secondary, for one scenario."""
    name = request.param
    data = load_yaml(SCENARIOS / f"{name}.yaml")
    base = parse_scenario(data)
    specs = [SecondarySpec(name=c, d1=3, d2=1) for c in COLUMNS]  # the scenario's monitor
    result, _ = assess_series(
        _series(base, simulate(base), COLUMNS),
        4,
        specs,
        setpoint=True,
        config=MonitorConfig(max_order=30),
    )
    measured = {}
    for column, secondary in COLUMNS.items():
        gains = ROUTINE_CASCADE[name][secondary]
        sc = parse_scenario(cascade_variant(data, loop=LOOP, secondary=secondary, gains=gains))
        table, _ = _series(sc, simulate(sc), []).table(min_rows=WINDOW)
        measured[column] = float(np.var(table[f"{LOOP}.sp"] - table[LOOP]))
    bands = {
        c.name: c.decomposition.prediction(result.config.removed_2a) for c in result.candidates
    }
    return {"name": name, "result": result, "bands": bands, "measured": measured}


# Measured (README, "prediction against reality"): the PI-P cascade removes more than half of 2a
# on the jacket temperature (58 % and 62 %), so that cascade lies *below* the band the paper's rule
# predicts, though above the floor 1a; and in cascade_routine_primary the two secondaries' bands
# differ by 1.5 % (a tie the monitor breaks for the flow) while the jacket's cascade does far
# better. The tests below state these outcomes as they are (each would fail if they changed).


def test_every_cascade_lies_between_the_floor_and_the_pessimistic_end(switch):
    """1a <= measured <= 1a + 2a for either secondary: the band's outer bounds hold."""
    for column, measured in switch["measured"].items():
        pr = switch["bands"][column]
        assert pr.minimum <= measured <= pr.high, (switch["name"], column, measured, pr)
        assert measured < switch["result"].variance  # and every cascade improves on the PI


def test_cascade_on_the_first_ranked_secondary_against_the_predicted_band(switch):
    """cascade_routine_primary: the first-ranked cascade (flow) lies in its band.
    cascade_routine: the first-ranked cascade (jacket) lies below its band and above 1a: it
    removes more of 2a than the band's "at most half" allows."""
    first = switch["result"].ranking[0]
    pr, measured = switch["bands"][first], switch["measured"][first]
    if switch["name"] == "cascade_routine_primary":
        assert first == "reactor.y3"
        assert pr.low <= measured <= pr.high, (first, measured, pr.low, pr.high)
    else:
        assert first == "reactor.y2"
        assert pr.minimum <= measured < pr.low, (first, measured, pr.minimum, pr.low)


def test_ranking_against_the_measured_cascades(switch):
    """cascade_routine: the first-ranked secondary's cascade gives the lower variance.
    cascade_routine_primary: the two bands tie (within 5 %) and the tie-break picks the flow,
    whose cascade is the worse one."""
    ranking, measured, bands = switch["result"].ranking, switch["measured"], switch["bands"]
    assert sorted(ranking) == sorted(COLUMNS)
    if switch["name"] == "cascade_routine":
        assert measured[ranking[0]] < measured[ranking[1]], (ranking, measured)
    else:
        a, b = (bands[c].low for c in ranking)
        assert abs(a - b) < 0.05 * max(a, b), (ranking, a, b)
        assert measured[ranking[0]] > measured[ranking[1]], (ranking, measured)


def test_the_jacket_cascade_is_the_better_one_in_both_scenarios(switch):
    """What the implemented cascades show: the jacket temperature is the secondary to use."""
    assert switch["measured"]["reactor.y2"] < 0.7 * switch["measured"]["reactor.y3"]
