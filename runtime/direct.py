"""The ``direct`` engine: a scenario's nodes run in one process, no bus (DESIGN section 3).

:data:`scenario.kinds.NODE_KINDS` says how to build the behaviour of a node of each kind (the
scenario's ``kind:``); :func:`behaviour_of` builds one, for every engine: the bus engines put it
on the kernel (:mod:`runtime.nodes`), :func:`simulate` runs them all on the
:class:`~runtime.engine.DirectEngine`, round by round as the clock would, so its traces,
decisions and assignments are those of the bus engines, bit for bit, for every scenario:
plants, controllers, networks, the coordination agent and the monitor. The record is built from
the messages in the historian's order by the same :class:`~runtime.records.RecordBuilder` that
rebuilds a bus run's record from its history.

The coordination agent is handed a simulator of its loops
(:class:`scenario.views.ScenarioSimulator`) that runs on this same engine: :func:`simulate`
itself.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from agents.wncsca.config import WncscaConfig
from agents.wncsca.coordinator import Coordinator
from agents.wncsca.model import LoopModel
from core.behaviour import Behaviour
from core.record import RunRecord
from core.time import to_ticks
from runtime.engine import DirectEngine, Message
from runtime.records import RecordBuilder
from scenario import HISTORIAN, NODE_KINDS, Scenario, views

__all__ = [
    "behaviour_of",
    "check_node",
    "simulate",
    "loop_model",
    "coordinator",
]


def check_node(scenario: Scenario, name: str) -> None:
    """Raise ``KeyError`` naming the known nodes if ``scenario`` has no node ``name``."""
    if name != HISTORIAN and name not in scenario.nodes:
        known = ", ".join(["clock", *scenario.participants()])
        raise KeyError(f"scenario {scenario.name!r} has no node {name!r} (nodes: {known})")


def behaviour_of(scenario: Scenario, name: str) -> Behaviour:
    """The behaviour of node ``name`` (``KeyError`` with the known names if there is none)."""
    check_node(scenario, name)
    build = NODE_KINDS.of(scenario.nodes[name]).build
    assert build is not None  # every node kind has one
    return build(name, scenario, simulate)


def simulate(
    scenario: Scenario,
    *,
    engine: str = "direct",
    observe: Callable[[list[Message]], None] | None = None,
) -> RunRecord:
    """Run ``scenario`` on the direct engine and return its record.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario; use :meth:`Scenario.with_loops` to vary ``tau_s`` / ``tau_d``.
    observe : callable, optional
        Called with each round's messages as the bus would carry them (a test's witness).
    """
    wall0 = time.perf_counter()
    behaviours = {name: behaviour_of(scenario, name) for name in sorted(scenario.nodes)}
    builder = RecordBuilder(scenario, engine=engine)

    def record(messages: list[Message]) -> None:
        for m in messages:
            # the record keeps some bodies whole (decisions, proposals): those as the bus has them
            builder.add(m.t, m.key, m.mapping if builder.keeps(m.key) else m.fields)
        if observe is not None:
            observe(messages)

    run = DirectEngine(
        behaviours,
        end=to_ticks(scenario.end_time),
        max_microsteps=scenario.clock.max_microsteps,
        max_rounds=scenario.clock.max_rounds,
        on_round=record,
    )
    run.run()
    rec = builder.finish(dropped_invalid=run.dropped_invalid(), dropped_nodes={})
    rec.wall_s = time.perf_counter() - wall0
    rec.phases = {"run": rec.wall_s}
    return rec


def loop_model(scenario: Scenario, config: WncscaConfig | None = None) -> LoopModel:
    """The coordination agent's model of ``scenario``'s loops, simulated on this engine."""
    return views.loop_model(scenario, config, simulate=simulate)


def coordinator(scenario: Scenario, config: WncscaConfig | None = None) -> Coordinator:
    """The coordination agent of ``scenario``, its model simulated on this engine."""
    return views.coordinator(scenario, config, simulate=simulate)
