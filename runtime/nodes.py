"""A scenario's nodes and clock on the bus: each node's behaviour
(:func:`runtime.direct.behaviour_of`, the same the direct engine runs) on the kernel, and the
historian, the bus engines' own recorder (:mod:`runtime.historian`).
"""

from __future__ import annotations

from typing import Any

from core.time import to_ticks
from kernel.bus import Session
from kernel.clock import ClockRunner, ClockSpec
from kernel.heartbeat import Heartbeat
from kernel.node import BusNode, NodeContext
from runtime.direct import behaviour_of, check_node
from runtime.historian import HistorianNode
from runtime.inject import interpreter
from runtime.ownership import OBSERVERS, publishers
from scenario import HISTORIAN, Scenario

__all__ = ["bus_node", "check_node", "clock_spec", "clock_runner"]


def bus_node(
    scenario: Scenario,
    name: str,
    run_id: str,
    session: Session,
    options: dict[str, Any] | None = None,
    *,
    heartbeat: Heartbeat | None = None,
) -> BusNode:
    """Node ``name`` of ``scenario`` as a bus participant of run ``run_id`` on ``session``,
    beating on ``heartbeat`` (shared by a process's nodes) or on a heartbeat of its own."""
    ctx = NodeContext(
        name,
        run_id,
        session,
        participants=frozenset(scenario.participants()),
        round_timeout_s=scenario.clock.round_timeout_s,
        options=dict(options or {}),
        publishers=publishers(scenario),
        heartbeat=heartbeat,
    )
    if name == HISTORIAN:
        return HistorianNode(ctx, scenario_name=scenario.name, seed=scenario.seed)
    return BusNode(ctx, behaviour_of(scenario, name))


def clock_spec(scenario: Scenario) -> ClockSpec:
    """What the clock of a run of ``scenario`` needs to know."""
    return ClockSpec(
        participants=frozenset(scenario.participants()),
        end=to_ticks(scenario.end_time),
        time_unit=scenario.time_unit,
        round_timeout_s=scenario.clock.round_timeout_s,
        startup_timeout_s=scenario.clock.startup_timeout_s,
        work_timeout_s=scenario.clock.work_timeout_s,
        max_microsteps=scenario.clock.max_microsteps,
        max_rounds=scenario.clock.max_rounds,
        may_drop=frozenset(scenario.clock.may_drop),
        observers=OBSERVERS,
    )


def clock_runner(
    scenario: Scenario, session: Session, run_id: str, *, realtime: float | None = None
) -> ClockRunner:
    """The clock of run ``run_id`` of ``scenario`` on ``session``."""
    return ClockRunner(
        session, run_id, clock_spec(scenario), interpret=interpreter(scenario), realtime=realtime
    )
