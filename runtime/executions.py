"""Executions of multi-loop controllers, rebuilt from a run's record (any engine).

The record of a run holds every delivered sample and every set-point change; the controller
behaviour's hold rule (:mod:`controllers.behaviour`) gives when a multi-loop law executed and
with what. Feeding them to a fresh law reproduces the run's moves and the law's internal signals
(for the MRAC: ``x_m``, ``e``, ``theta``), which are not on the bus.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from bus_schemas import keys
from core.record import RunRecord
from scenario import ControllerNodeConfig, Scenario

__all__ = ["Execution", "multi_loop_executions"]


@dataclass(frozen=True)
class Execution:
    """One execution of a multi-loop controller: its time (ticks), the held measurement and the
    set point of each of its loops."""

    t: int
    y: dict[str, float]
    r: dict[str, float]


def multi_loop_executions(scenario: Scenario, rec: RunRecord, controller: str) -> list[Execution]:
    """The executions of multi-loop controller ``controller`` in a run, rebuilt from its record.

    The record of any engine holds every delivered sample (delivery time, value, sampling time)
    and every set-point change; the node's rule (:mod:`controllers.node`, step 4 above) gives when
    it executed and with what. Feeding them to a fresh law reproduces the run's moves, and the
    law's internal signals with them (for the MRAC: the reference model's ``x_m``, the error
    ``e``, ``theta``), which are not on the bus.

    Raises
    ------
    ValueError
        If ``controller`` is not a multi-loop controller of ``scenario``.
    """
    cfg = scenario.nodes_of(ControllerNodeConfig).get(controller)
    if cfg is None or cfg.loops is None:
        raise ValueError(f"{controller!r} is not a multi-loop controller of {scenario.name!r}")
    names = [n for n in cfg.loops if scenario.loops[n].sensor is not None]
    # (t, batch: 0 delayed / 1 zero-delay, key, position) -> sample
    arrivals = []
    for name in names:
        lr = rec.loops[name]
        for i, (t, y, ts) in enumerate(zip(lr.t, lr.y, lr.t_sampled, strict=True)):
            arrivals.append((t, int(ts == t), keys.meas(name), i, name, y, ts))
    arrivals.sort(key=lambda a: a[:4])
    changes = {n: rec.loops[n].setpoints for n in cfg.loops}
    held: dict[str, tuple[int, float]] = {}
    out: list[Execution] = []
    for (t, _), group in itertools.groupby(arrivals, key=lambda a: a[:2]):
        for *_, name, y, ts in group:
            if name not in held or ts >= held[name][0]:
                held[name] = (ts, y)
        if len(held) == len(names):
            r = {n: [v for tc, v in changes[n] if tc <= t][-1] for n in cfg.loops}
            out.append(Execution(t=t, y={n: held[n][1] for n in names}, r=r))
    return out
