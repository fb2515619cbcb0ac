"""The agent's identification experiment (issue 35, item 3): its plan of set-point moves, what
it keeps of the delivered samples, and the scenario checks that refuse a bad ``identify:``."""

from __future__ import annotations

import numpy as np
import pytest

from agents.identify.excitation import gbn
from agents.wncsca.config import IdentifyConfig
from agents.wncsca.experiment import STREAM, Experiment
from bus_schemas import ModeRequest, Setpoint
from core.errors import ConfigError
from core.time import to_ticks, to_units
from runtime.direct import simulate
from scenario import load_scenario, views
from tests.conftest import SCENARIOS, write_variant

JITTER = SCENARIOS / "jcstr_wncs_jitter.yaml"
CONFIG = IdentifyConfig(
    params={"reactor": ["U"]},
    duration=8.0,
    clock=0.4,
    amplitude={"level": 0.02, "temperature": 1.0},
)
BASE = {"level": 0.70, "temperature": 52.0}
PERIODS = {"level": 0.05, "temperature": 0.05}


def _plan(seed: int = 7) -> Experiment:
    return Experiment.plan(CONFIG, BASE, PERIODS, seed, "startup")


def _set_point_at(exp: Experiment, loop: str, t: float) -> float:
    value = exp.base[loop]
    for tc, lp, v in exp.changes:
        if lp == loop and to_ticks(tc) <= to_ticks(t):
            value = v
    return value


def test_the_plan_is_the_seeded_gbn_on_the_clock_within_the_amplitude_and_back_at_the_end():
    exp = _plan()
    n = 20  # 8.0 / 0.4
    rng = np.random.default_rng([7, STREAM])
    for loop in sorted(CONFIG.amplitude):  # drawn in loop order from the agent's own stream
        a = CONFIG.amplitude[loop]
        swing = gbn(n, CONFIG.switch, a, rng)
        for k in range(1, n):
            t = k * CONFIG.clock
            assert _set_point_at(exp, loop, t) == pytest.approx(BASE[loop] + swing[k])
        assert _set_point_at(exp, loop, 0.0) == BASE[loop]
        assert _set_point_at(exp, loop, CONFIG.duration) == BASE[loop]
        moves = [v for _, lp, v in exp.changes if lp == loop]
        assert all(abs(v - BASE[loop]) <= a + 1e-12 for v in moves)
        assert all(a != b for a, b in zip(moves, moves[1:], strict=False))  # only real moves
    times = [to_ticks(t) for t, _, _ in exp.changes]
    assert times == sorted(times)
    assert _plan().changes == exp.changes  # the same seed, the same experiment
    assert _plan(seed=8).changes != exp.changes


def test_what_the_fit_sees_is_each_sampling_instants_delay_none_for_the_lost_and_late():
    exp = _plan()
    p = to_ticks(0.05)
    exp.record("level", 0.71, 0, 3)
    exp.record("level", 0.72, 2 * p, 2 * p + 5)  # the sample at p was lost
    exp.record("level", 0.73, 2 * p + 1, 2 * p + 9)  # off the grid: left out, counted
    exp.record("level", 0.74, to_ticks(8.0), to_ticks(8.0) + 1)  # at the end: after the window
    exp.record("temperature", 52.1, p, p + 2)
    seen = exp.seen({"level": 0.17})
    assert exp.off_grid == 1 and exp.delivered() == 3
    assert seen.traces["level"][:3] == [to_units(3), None, to_units(5)]
    assert len(seen.traces["level"]) == 160 and set(seen.traces["level"][3:]) == {None}
    assert seen.samples["level"] == ([0.0, to_units(2 * p)], [0.71, 0.72])
    assert seen.delays == {"level": 0.17, "temperature": 0.0}
    assert seen.steps[:2] == ((0.0, "level", 0.70), (0.0, "temperature", 52.0))
    assert all(t < 8.0 for t, _, _ in seen.steps)
    assert exp.cost()["level"] == pytest.approx(np.sqrt(np.mean(np.square([0.01, 0.02]))))


def _identifying(tmp_path, edit_more=None):
    def edit(data: dict) -> None:
        data["nodes"]["wncsca"]["identify"] = {
            "params": {"reactor": ["U"]},
            "duration": 8.0,
            "clock": 0.4,
            "amplitude": {"level": 0.02, "temperature": 1.0},
        }
        data["setpoints"] = [
            {"t": 9.8, "loop": "level", "value": 0.75},
            {"t": 10.4, "loop": "temperature", "value": 56.0},
        ]
        data["modes"] = [{"t": 11.0, "mode": "steady_state"}]
        if edit_more is not None:
            edit_more(data)

    return write_variant(tmp_path, JITTER, "identify.yaml", edit)


def test_a_well_formed_experiment_loads(tmp_path):
    s = load_scenario(_identifying(tmp_path))
    cfg = s.nodes["wncsca"].identify
    assert cfg is not None and cfg.amplitude == {"level": 0.02, "temperature": 1.0}


@pytest.mark.parametrize(
    ("edit", "names"),
    [
        (
            lambda d: d["setpoints"].insert(0, {"t": 1.8, "loop": "level", "value": 0.75}),
            "setpoints[0].t",
        ),
        (lambda d: d["modes"].insert(0, {"t": 4.0, "mode": "steady_state"}), "modes[0].t"),
        (
            lambda d: d["nodes"]["wncsca"]["identify"]["params"].update(reactor=["nope"]),
            "identify.params.reactor",
        ),
        (
            lambda d: d["nodes"]["wncsca"]["identify"]["params"].update(tank=["U"]),
            "identify.params.tank",
        ),
        (
            lambda d: d["nodes"]["wncsca"]["identify"]["amplitude"].update(flow=0.1),
            "identify.amplitude.flow",
        ),
        (
            lambda d: d["nodes"]["wncsca"]["modes"]["identification"].pop("level"),
            "modes.identification",
        ),
        (lambda d: d["nodes"]["wncsca"]["identify"].update(duration=12.0), "identify.duration"),
        (lambda d: d["nodes"]["wncsca"]["identify"].update(clock=9.0), "identify"),
        (
            lambda d: d["nodes"]["wncsca"]["identify"]["amplitude"].update(level=-0.1),
            "amplitude.level",
        ),
    ],
)
def test_a_bad_experiment_is_refused_on_load_naming_where(tmp_path, edit, names):
    with pytest.raises(ConfigError) as err:
        load_scenario(_identifying(tmp_path, edit))
    assert names in str(err.value), str(err.value)


def test_the_agent_refuses_steps_during_its_experiment_and_a_mode_request_aborts_it(tmp_path):
    co = views.coordinator(load_scenario(_identifying(tmp_path)), simulate=simulate)
    started = co.start_identification()
    assert started is not None and co.mode == "identification" and co.experiment is not None
    assert "experiment to t=8" in started.reasons[0]
    assert co.rates()["periods"] == {"level": 0.05, "temperature": 0.05}
    d, value, _ = co.on_setpoint("level", Setpoint(value=0.75), to_ticks(1.0))
    assert d.verdict == "refuse" and value is None
    assert "identification experiment" in d.reasons[0]
    co.setpoints["level"] = 0.72  # a move of the experiment passed on
    d = co.on_mode(ModeRequest(mode="steady_state"))
    assert d.verdict == "accept" and "aborted" in d.reasons[1]
    assert co.experiment is None and co.setpoints["level"] == 0.70
    d, value, _ = co.on_setpoint("level", Setpoint(value=0.75), to_ticks(2.0))
    assert value is not None  # asked after the experiment: judged as ever
