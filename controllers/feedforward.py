"""Steady-state feedforward ``u_bar`` from a plant model's equilibrium (seed 000, eq. (2)-(7)).

A loop's feedforward depends on the set points of *all* loops of its plant (for the JCSTR,
``u2_bar`` depends on both the level and the temperature set points), so it is computed from the
plant model, not from the loop alone. Generic over plants with ``equilibrium(y_bar)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["SteadyStateFeedforward"]


class SteadyStateFeedforward:
    """``u_bar`` of one plant input as a function of the plant's loops' set points.

    Parameters
    ----------
    plant : object
        Plant with ``output_names``, ``input_names`` and ``equilibrium(y_bar)``.
    output_of_loop : mapping
        Loop name -> the plant output it controls, for every loop of the plant.
    input_name : str
        The plant input whose ``u_bar`` is wanted.
    """

    def __init__(self, plant: Any, output_of_loop: Mapping[str, str], input_name: str) -> None:
        if input_name not in plant.input_names:
            raise ValueError(f"feedforward: plant has no input {input_name!r}")
        self._plant = plant
        self._output_of_loop = dict(output_of_loop)
        self._index = plant.input_names.index(input_name)

    def on(self, plant: Any) -> SteadyStateFeedforward:
        """The same feedforward (loops, input) on another model of the plant (other parameters:
        the agent's draws of its model, :mod:`agents.wncsca.uncertainty`)."""
        return SteadyStateFeedforward(plant, self._output_of_loop, plant.input_names[self._index])

    def u_bar(self, setpoints: Mapping[str, float]) -> float:
        """Feedforward for the loops' current set points (loop name -> value)."""
        y_bar = {self._output_of_loop[loop]: float(v) for loop, v in setpoints.items()}
        _, u = self._plant.equilibrium(y_bar)
        return float(u[self._index])
