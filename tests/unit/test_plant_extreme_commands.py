"""A command the plant model cannot bear is refused, not fatal (issue 19, item 2).

Finite but extreme actuator commands (1e300, -1e300, an outflow of -1e9 on the JCSTR) drive the
reactor's state to NaN. Before this, the plant node died of it (its state record failed its
schema). Now it refuses the command, counted as dropped, and lives on.
"""

from __future__ import annotations

from typing import NamedTuple

import pytest

from bus_schemas import Move, keys
from runtime.direct import behaviour_of
from scenario import load_scenario
from tests.conftest import BENCHMARK

KEY = keys.actuator("reactor", "F_out")
T_COMMAND = 150_000  # between the samples at 0.1 and 0.2 pu


class _Env(NamedTuple):
    src: str
    seq: int
    round: int
    t: int


UNLIMITED = [
    "nodes.reactor.input_range={}"
]  # no valve limits: any finite command reaches the model


def _run(command: float | None, end: int, overrides: list[str] = UNLIMITED) -> tuple[list, object]:
    """The reactor alone, round by round at its own timers (and at ``T_COMMAND``, where the
    command arrives), to ``end`` ticks: its outputs and next times, and the behaviour. By
    default without the benchmark's valve ranges (``input_range``), which would hold a negative
    flow at 0 before the model sees it."""
    plant = behaviour_of(load_scenario(BENCHMARK, overrides=overrides), "reactor")
    outputs = []
    r, t = 0, 0
    while t <= end:
        inbox = []
        if command is not None and t == T_COMMAND:
            move = Move(value=command, t_computed=t)
            inbox = [(KEY, _Env("network", 0, r - 1, t), lambda _type, m=move: m)]
        out, nxt = plant.run_round(r, t, inbox)
        outputs.append((t, out, nxt))
        r, t = r + 1, (T_COMMAND if t < T_COMMAND < nxt else nxt)
    return outputs, plant


def test_a_command_caught_before_the_plant_publishes_again_changes_nothing():
    """-1e300 on the outflow: NaN before the next sample, so the plant goes back to the
    command's instant and holds the input it replaced: bit for bit the run without it."""
    clean, _ = _run(None, 2_000_000)
    hit, plant = _run(-1e300, 2_000_000)
    assert len(clean) > 20
    assert hit == clean  # every output, every next_time: as if the command never came
    assert plant.dropped_invalid == {KEY: 1}


@pytest.mark.parametrize("value", [1e300, -1e9])
def test_a_command_that_diverges_later_is_refused_and_the_plant_lives_on(value):
    """1e300 and -1e9 on the outflow: finite at the next sample (which the plant publishes),
    NaN after it. The plant refuses the command then (counted), and its state holds where no
    input can integrate it any further: every later round still answers, with finite values."""
    hit, plant = _run(value, 2_000_000)
    assert plant.dropped_invalid == {KEY: 1}
    assert hit[-1][0] > 2_000_000 - 200_000  # it went on to the end
    for _t, outputs, _next in hit:
        for _key, body in outputs:
            values = body.model_dump()
            flat = [values.get("value")] + [
                v for col in values.get("values", {}).values() for v in col
            ]
            assert all(v is None or abs(v) < float("inf") for v in flat)


def test_a_bearable_command_is_applied():
    clean, _ = _run(None, 1_000_000)
    hit, plant = _run(0.5, 1_000_000)
    assert hit[-1] != clean[-1] and plant.dropped_invalid == {}


@pytest.mark.parametrize("value", [-1e300, -1e9, -0.5])
def test_with_its_valve_range_a_negative_flow_is_held_at_zero(value):
    """The benchmark's outflow valve passes ``[0, inf)`` (``input_range``): any negative command
    is the valve shut, bit for bit the run commanded 0, and nothing is refused."""
    shut, _ = _run(0.0, 1_000_000, overrides=[])
    hit, plant = _run(value, 1_000_000, overrides=[])
    assert hit == shut and plant.dropped_invalid == {}
    assert plant.u[0] == 0.0
    unlimited, _ = _run(-0.5, 1_000_000)
    assert unlimited != shut  # without the range the same command does reach the model
