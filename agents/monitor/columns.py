"""The columns of a run, by name (seed 004): what ``wncs assess RUN_DIR`` and a monitor node's
secondaries name. Plain Python (the monitor's configuration checks names with it, and scenarios
import that configuration).

Columns of a run
----------------
``LOOP``
    The samples delivered to loop ``LOOP``'s controller (``loop/<l>/meas``): what the controller
    saw, measurement noise included. The primary is always a loop; its samples define the rows.
``LOOP.sp``
    The loop's set point in force when each primary sample was handled (from operations or from
    the coordination agent, :meth:`runtime.scenario.Scenario.setpoint_key`).
``PLANT.STATE``
    A plant state on its monitoring grid (``plant/<p>/state``: the true value, no measurement
    noise), at the grid point at or before each primary sample's sampling instant (with the grid
    at the sampling instants, as in ``scenarios/cascade_routine.yaml``, its value at that instant).

A secondary loop's column ``LOOP`` holds, at each primary sample, that loop's latest sample taken
at or before the primary's sampling instant (:class:`agents.monitor.run_data.RunSeries`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

__all__ = ["SP_SUFFIX", "Column", "resolve_column"]

SP_SUFFIX = ".sp"


@dataclass(frozen=True)
class Column:
    """A column of a run: a loop's delivered samples, its set point, or a plant state."""

    name: str
    kind: Literal["meas", "sp", "state"]
    loop: str | None = None
    plant: str | None = None
    state: str | None = None


def _plant_states(scenario: Any) -> dict[str, tuple[str, ...]]:
    return {n: tuple(cfg.build().state_names) for n, cfg in sorted(scenario.plants().items())}


def resolve_column(scenario: Any, name: str) -> Column:
    """The column ``name`` of a run of ``scenario`` (module docstring).

    Raises
    ------
    ValueError
        Unknown or ambiguous name, listing the run's columns.
    """
    loops = scenario.loops
    plants = _plant_states(scenario)
    hits: list[Column] = []
    if name in loops:
        hits.append(Column(name, "meas", loop=name))
    head, dot, tail = name.partition(".")
    if dot:
        if tail == SP_SUFFIX[1:] and head in loops:
            hits.append(Column(name, "sp", loop=head))
        if tail in plants.get(head, ()):
            hits.append(Column(name, "state", plant=head, state=tail))
    if len(hits) == 1:
        return hits[0]
    if hits:
        raise ValueError(f"{name!r} is ambiguous: both a loop's set point and a plant state")
    states = ", ".join(f"{p}.{s}" for p, names in plants.items() for s in names)
    raise ValueError(
        f"{name!r} is not a column of this run; columns are LOOP (samples delivered to the "
        f"loop's controller), LOOP.sp (its set point) and PLANT.STATE (a plant state on its "
        f"monitoring grid): loops {sorted(loops)}, plant states {states}"
    )
