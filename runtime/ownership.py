"""Who publishes which key: each key's owners, derived once from the scenario (issue 19).

The bus checks every data message's source against the owners of its key (a node drops and
counts a message from anyone else), and the router's access control lets each node put only
on the keys it owns. Both read :func:`publishers`: run-relative key expressions per publisher,
from the key grammar of ``bus_schemas.keys`` and the scenario's wiring:

============================  =====================================================
``plant/<p>/sensor/*``,        plant ``p``
``plant/<p>/state``
``loop/<l>/u``                 loop ``l``'s controller
``loop/<l>/meas``,             loop ``l``'s network (the sensor and actuator paths it
``plant/<p>/sampling/<s>``,    carries), and the operator for the scheduled
``plant/<p>/actuator/<i>``     disturbances of plant inputs
``link/<k>/tx`` / ``rx``       the link's sending controller / its network
``net/*``                      every network and gateway node
``wncsca/*``, ``loop/*/sp``    the coordination agent
``ops/setpoint/*``,            the operator (its schedules) and the clock (the requests
``ops/mode``, ``events/*``     of ``wncs inject`` it stamps)
``plant/<p>/drift``            the operator (its ``drifts:``) and the clock (injected)
``monitor/assessment/<l>``     the monitor of loop ``l``
============================  =====================================================

A test runs every scenario on the direct engine and checks each message's source against this
table, so a node kind that publishes on a new key cannot be forgotten here.
"""

from __future__ import annotations

from agents.monitor.config import MonitorNodeConfig
from bus_schemas import keys
from scenario import HISTORIAN, ControllerNodeConfig, OperatorNodeConfig, Scenario

__all__ = ["CLOCK", "OBSERVERS", "publishers", "readers", "owners_of"]

CLOCK = "clock"
"""The clock's name on the bus (it stamps external requests as its own messages)."""

OBSERVERS = frozenset({HISTORIAN})
"""The participants that observe the rounds (:attr:`kernel.clock.ClockSpec.observers`): they
take the clock's log of ticks (``clock/log``) rather than ticks of their own."""


def publishers(scenario: Scenario) -> dict[str, tuple[str, ...]]:
    """Publisher (every participant and the clock) -> the run-relative key expressions it may
    publish data on, sorted (the historian publishes none)."""
    out: dict[str, set[str]] = {n: set() for n in [*scenario.participants(), CLOCK]}
    for plant in scenario.plants():
        out[plant] |= {f"plant/{plant}/sensor/*", keys.plant_state(plant)}
    for name, loop in scenario.loops.items():
        out[loop.controller].add(keys.move(name))
        if loop.sensor is not None:
            out[loop.network] |= {keys.meas(name), keys.sampling(loop.plant, loop.sensor)}
        if loop.actuator is not None:
            out[loop.network].add(keys.actuator(loop.plant, loop.actuator))
    for name, link in scenario.links.items():
        out[link.from_].add(keys.link_tx(name))
        out[link.network].add(keys.link_rx(name))
    for carrier in scenario.carriers():
        out[carrier].add("net/*")
    agent = scenario.agent_node()
    if agent is not None:
        out[agent] |= {"wncsca/*", "loop/*/sp"}
    requests = {keys.setpoint_all(), keys.ops_mode()}
    for operator in scenario.nodes_of(OperatorNodeConfig):
        out[operator] |= requests
        out[operator] |= {keys.actuator(d.plant, d.input) for d in scenario.disturbances}
        out[operator] |= {keys.drift(d.plant) for d in scenario.drifts}
    for monitor, cfg in scenario.nodes_of(MonitorNodeConfig).items():
        out[monitor].add(keys.monitor_assessment(cfg.loop))
    out[CLOCK] |= requests | {"events/*", "plant/*/drift"}
    return {n: tuple(sorted(p)) for n, p in sorted(out.items())}


def owners_of(table: dict[str, tuple[str, ...]], key: str) -> frozenset[str]:
    """The publishers in ``table`` (:func:`publishers`) that may publish on concrete ``key``."""
    return frozenset(
        n for n, patterns in table.items() if any(keys.intersects(p, key) for p in patterns)
    )


def readers(scenario: Scenario) -> dict[str, tuple[str, ...]]:
    """Participant -> the run-relative key expressions it may subscribe to, by its role (what
    the router's access control lets it read; a test checks that every node kind's
    subscriptions in every scenario fall inside them). Wider than one node's subscriptions
    where a role reads a family of keys (a controller any loop's ``meas``), so that the grant
    costs no behaviour to build (the agent's takes seconds)."""
    out: dict[str, set[str]] = {n: set() for n in scenario.participants()}
    for plant in scenario.plants():
        out[plant] |= {f"plant/{plant}/actuator/*", f"plant/{plant}/sampling/*", keys.drift(plant)}
    for controller in scenario.nodes_of(ControllerNodeConfig):
        out[controller] |= {"loop/*/meas", "link/*/rx", "ops/setpoint/*", "loop/*/sp", "wncsca/*"}
    for carrier in scenario.carriers():
        out[carrier] |= {"loop/*/u", "plant/*/sensor/*", "link/*/tx", "wncsca/*"}
        out[carrier].add(keys.network_events(carrier))
    agent = scenario.agent_node()
    if agent is not None:
        out[agent] |= {"net/*", "ops/*", "ops/setpoint/*", "loop/*/meas"}
    for monitor in scenario.nodes_of(MonitorNodeConfig):
        out[monitor] |= {"plant/**", "loop/**", "ops/**"}
    out[HISTORIAN] |= set(keys.data_all())
    return {n: tuple(sorted(p)) for n, p in sorted(out.items())}
