"""A scenario, validated whole: the schema's fields (:class:`~scenario.schema.ScenarioSchema`)
and the checks across them (:mod:`scenario.checks`)."""

from __future__ import annotations

from pydantic import model_validator

from scenario.checks import check_graph
from scenario.schema import ScenarioSchema

__all__ = ["Scenario"]


class Scenario(ScenarioSchema):
    """A whole run: process graph, loops, schedule and end time, every field checked alone and
    all of them together (:func:`scenario.checks.check_graph`), before anything starts."""

    @model_validator(mode="after")
    def _check_graph(self) -> Scenario:
        check_graph(self)
        return self
