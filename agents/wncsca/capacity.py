"""Can the network carry the periods? The agent asks a TSCH gateway's manager itself (issue 15).

A TSCH gateway's proposals carry what its manager schedules with (``Proposal.tsch``:
:class:`bus_schemas.TschCapacity`). Before the agent assigns periods it runs the manager's very
scheduler (:func:`gateway.tsch.schedule.schedule_for`) on the proposal's routes at those periods:
if a link lacks cells, the periods cannot be carried, which the agent treats as it treats a
violated limit: the proposal is rejected naming the link and the paths over it (the gateway then
proposes its next alternative), and a mode whose rates cannot be carried is refused. The agent
does not know the phases of the sensors' samples, so it schedules every path from slot 0; the
gateway checks again with the real phases when the rates arrive (``rates_refused``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from bus_schemas import TschCapacity
from bus_schemas.bodies import PathConfig
from core.time import to_ticks
from gateway.tsch.schedule import Cell, Schedule, schedule_for

__all__ = ["Manager", "describe", "path_ticks"]


def path_ticks(
    paths: Iterable[str], periods: Mapping[str, float], link_periods: Mapping[str, float]
) -> dict[str, int]:
    """Path name (``<loop>.<direction>``, ``<link>.link``) -> its packets' period in ticks: a
    loop's sensor and actuator paths at the loop's period, a link at its own (time units);
    paths without one are left out."""
    out: dict[str, int] = {}
    for path in paths:
        name, _, direction = path.rpartition(".")
        period = link_periods.get(name) if direction == "link" else periods.get(name)
        if period is not None:
            out[path] = to_ticks(period)
    return out


class Manager:
    """A TSCH gateway's manager, as the agent asks it: its capacity and the proposal's routes."""

    def __init__(self, capacity: TschCapacity, paths: Mapping[str, PathConfig]) -> None:
        self.capacity = capacity
        self.routes: dict[str, tuple[str, ...] | None] = {
            name: tuple(entry.route) if len(entry.route) >= 2 else None
            for name, entry in paths.items()
        }

    def schedule(self, periods: Mapping[str, float], link_periods: Mapping[str, float]) -> Schedule:
        """The schedule for loops sampled at ``periods`` and links sent at ``link_periods``
        (time units): a loop's sensor and actuator paths at its period."""
        cap = self.capacity
        return schedule_for(
            self.routes,
            path_ticks(self.routes, periods, link_periods),
            slot_ticks=cap.slot_ticks,
            length=cap.length,
            channels=cap.channel_offsets,
            retry_cells=cap.retry_cells,
            written=[Cell(**c.model_dump()) for c in cap.cells],
            static=cap.static,
        )

    def offending(self, schedule: Schedule) -> tuple[str, ...]:
        """The paths whose routes cross a link that lacks cells."""
        lacking = set(schedule.lacking)
        return tuple(
            path
            for path, nodes in sorted(self.routes.items())
            if nodes is not None and lacking & set(zip(nodes[:-1], nodes[1:], strict=True))
        )


def describe(periods: Mapping[str, float], schedule: Schedule) -> str:
    """``"the manager cannot carry periods level 0.05, temperature 0.05 pu: link r2->gw lacks
    18 cells"``."""
    per = ", ".join(f"{n} {p:g}" for n, p in sorted(periods.items()))
    return f"the manager cannot carry periods {per}: {schedule.describe_lack()}"
