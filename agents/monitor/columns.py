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
    the coordination agent, :meth:`scenario.Scenario.setpoint_key`).
``PLANT.STATE``
    A plant state on its monitoring grid (``plant/<p>/state``: the true value, no measurement
    noise), at the grid point at or before each primary sample's sampling instant (with the grid
    at the sampling instants, as in ``scenarios/cascade_routine.yaml``, its value at that instant).

A secondary loop's column ``LOOP`` holds, at each primary sample, that loop's latest sample taken
at or before the primary's sampling instant (:class:`agents.monitor.run_data.RunSeries`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

__all__ = ["SP_SUFFIX", "RunLoop", "RunShape", "Column", "resolve_column"]

SP_SUFFIX = ".sp"


@dataclass(frozen=True)
class Column:
    """A column of a run: a loop's delivered samples, its set point, or a plant state."""

    name: str
    kind: Literal["meas", "sp", "state"]
    loop: str | None = None
    plant: str | None = None
    state: str | None = None


@dataclass(frozen=True)
class RunLoop:
    """A loop of a run as the monitor reads it."""

    tau_s: float | None
    """Its sampling period (time units; ``None``: it samples nothing)."""
    setpoint: float | None
    """Its set point at t = 0."""
    setpoint_key: str
    """Where its controller reads its set points (run-relative key)."""


@dataclass(frozen=True)
class RunShape:
    """What a run's columns are made of (:func:`scenario.views.run_shape` computes it from the
    scenario): its loops, its plants' states, its end."""

    loops: Mapping[str, RunLoop]
    plant_states: Mapping[str, tuple[str, ...]]
    end_time: float


def resolve_column(run: RunShape, name: str) -> Column:
    """The column ``name`` of ``run`` (module docstring).

    Raises
    ------
    ValueError
        Unknown or ambiguous name, listing the run's columns.
    """
    loops = run.loops
    plants = run.plant_states
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
