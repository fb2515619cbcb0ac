"""Figures of a multi-loop law's own signals, by the law's ``type``, for the run report.

A multi-loop law's internal signals (the MRAC's reference model, error and adaptive parameters)
are not on the bus, but its executions can be rebuilt from a run's record
(:func:`runtime.executions.multi_loop_executions`) and the law replayed over them. A law that can be
drawn that way registers a function in :data:`LAW_FIGURES`::

    figures(config, loops, executions, *, title, unit) -> dict[str, Figure]

with ``executions`` an iterable of ``(t, y, r)`` (time in units, held measurement and set point
by loop). The run report (:func:`runtime.report.write_plots`) saves each figure ``key`` of
controller ``name`` as ``<type>_<name>_<key>.png``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pydantic import BaseModel

from controllers import mrac_plots

__all__ = ["LAW_FIGURES", "figures_of"]

LAW_FIGURES: dict[str, Callable[..., dict[str, Any]]] = {
    "mrac": mrac_plots.figures,  # seed 003: Fig. 6.3-6.5 and the adaptive parameters' drift
}


def figures_of(config: BaseModel) -> Callable[..., dict[str, Any]] | None:
    """The figure function registered for the law of ``config`` (``None``: it draws none)."""
    return LAW_FIGURES.get(getattr(config, "type", ""))
