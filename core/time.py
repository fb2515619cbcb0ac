"""Integer virtual time.

Time on the bus and in every scheduler is an integer number of ticks; one time unit of the
scenario (``pu`` in seed 000) is :data:`TICKS_PER_UNIT` ticks. Floats appear only at the call
into a numerical core and in plots.
"""

from __future__ import annotations

__all__ = ["TICKS_PER_UNIT", "to_ticks", "to_units"]

TICKS_PER_UNIT = 1_000_000


def to_ticks(t_units: float) -> int:
    """Convert a time in scenario units to ticks, rounding to the nearest tick."""
    return int(round(t_units * TICKS_PER_UNIT))


def to_units(t_ticks: int) -> float:
    """Convert ticks to scenario units (the only float conversion of time)."""
    return t_ticks / TICKS_PER_UNIT
