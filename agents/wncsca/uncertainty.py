"""The agent's model uncertainty as parameter sets its guarantee covers (issue 35, item 2).

The agent's model (``model:`` of the agent node) believes a value of each plant parameter and,
for some, states how well it knows it (:class:`~agents.wncsca.config.ParameterUncertainty`):

* ``rel_sd``: the true value is normal about the believed one, relative standard deviation
  ``rel_sd``, drawn within +-2.5 sd (a bounded belief: no draw flips a coefficient's sign);
* ``interval``: the true value lies in ``[low, high]``, drawn uniformly.

:func:`model_draws` turns them into the parameter sets the chance method judges:

* ``uncertainty: probability``: ``model_draws`` sets drawn from the beliefs (independent
  parameters, a seeded generator of the agent's own); realization ``r`` of the Monte Carlo runs
  on set ``r mod M``, so ``P(overshoot <= limit)`` is over delays, losses, phases *and* the
  model's error;
* ``uncertainty: robust``: every corner of the parameters' box (``rel_sd`` read as
  ``+-1.96 sd``, its 95 % interval), each judged over all the realizations; the guarantee must
  hold at the worst corner (the overshoot is monotone in a parameter over a narrow interval in
  the seeds' plants; a non-monotone one would need the box's interior too, which the corners do
  not claim).

Without any stated uncertainty there is one set, the model itself, and the chance method is
today's, bit for bit.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np

from agents.wncsca.config import ParameterUncertainty, WncscaConfig
from agents.wncsca.spec import ClosedLoopSpec, JudgedPlant
from plants import registry

__all__ = [
    "ModelDraws",
    "model_draws",
    "plant_model",
    "believing",
    "interval_of",
    "TRUNCATE_SD",
    "CORNER_SD",
]

TRUNCATE_SD = 2.5
"""A ``rel_sd`` belief is drawn within this many standard deviations of the believed value."""

CORNER_SD = 1.96
"""The robust method reads a ``rel_sd`` belief as this many standard deviations either side."""

ParamSet = Mapping[str, Mapping[str, float]]
"""Plant -> parameter -> value: the parameters a draw replaces (the others are the model's)."""


@dataclass(frozen=True)
class ModelDraws:
    """The parameter sets a guarantee covers (see the module docstring).

    Attributes
    ----------
    mode : {"exact", "probability", "robust"}
        ``exact``: no stated uncertainty, one set (the model's own).
    sets : tuple of mappings
        Plant -> parameter -> value of each set (empty mappings for ``exact``).
    stated : mapping
        Plant -> parameter -> the stated uncertainty, as configured (for the decisions).
    """

    mode: str
    sets: tuple[ParamSet, ...]
    stated: Mapping[str, Mapping[str, dict[str, Any]]]

    @property
    def exact(self) -> bool:
        return self.mode == "exact"

    def summary(self) -> dict[str, Any]:
        """What a decision states of the uncertainty it assumed."""
        return {"mode": self.mode, "sets": len(self.sets), "stated": _plain(self.stated)}

    def describe(self) -> str:
        """One line for a decision's reasons."""
        if self.exact:
            return "model: the agent's parameters taken as exact (no uncertainty stated)"
        parts = []
        for plant, params in sorted(self.stated.items()):
            for name, spread in sorted(params.items()):
                if spread.get("rel_sd") is not None:
                    parts.append(f"{plant}.{name} +-{100 * spread['rel_sd']:.3g} % (1 sd)")
                else:
                    low, high = spread["interval"]
                    parts.append(f"{plant}.{name} in [{low:g}, {high:g}]")
        how = (
            f"over {len(self.sets)} draws of the model"
            if self.mode == "probability"
            else f"at the worst of {len(self.sets)} corners"
        )
        return f"model uncertainty {', '.join(parts)}: covered {how}"


def _plain(stated: Mapping[str, Mapping[str, dict[str, Any]]]) -> dict[str, Any]:
    return {p: {n: dict(v) for n, v in params.items()} for p, params in stated.items()}


def interval_of(value: float, spread: ParameterUncertainty) -> tuple[float, float]:
    """The interval the robust method spans for a believed ``value``."""
    if spread.interval is not None:
        return spread.interval
    assert spread.rel_sd is not None
    half = CORNER_SD * spread.rel_sd * abs(value)
    return value - half, value + half


def model_draws(spec: ClosedLoopSpec, config: WncscaConfig, seed: int) -> ModelDraws:
    """The parameter sets of ``spec``'s stated uncertainty under ``config`` (module docstring),
    drawn from a generator seeded by ``seed`` (the agent's)."""
    uncertain = [
        (p, name, float(plant.params[name]), spread)
        for p, plant in sorted(spec.plants.items())
        for name, spread in sorted(plant.uncertainty.items())
    ]
    stated: dict[str, dict[str, dict[str, Any]]] = {}
    for p, name, _, spread in uncertain:
        stated.setdefault(p, {})[name] = spread.model_dump(exclude_none=True)
    if not uncertain:
        return ModelDraws("exact", ({},), stated)
    if config.uncertainty == "robust":
        boxes = [interval_of(value, spread) for _, _, value, spread in uncertain]
        sets = tuple(_set(uncertain, corner) for corner in itertools.product(*boxes))
        return ModelDraws("robust", sets, stated)
    rng = np.random.default_rng([seed, 35, 2])
    draws = _draw(rng, uncertain, config.model_draws)
    holds = partial(_holds, spec)
    for i in range(len(draws)):
        for _ in range(_REDRAWS):
            if holds(_set(uncertain, draws[i])):
                break
            draws[i] = _draw(rng, uncertain, 1)[0]
        else:
            raise ValueError(
                f"model uncertainty: no draw of {[f'{p}.{n}' for p, n, _, _ in uncertain]} in "
                f"{_REDRAWS} holds the test's set points; the stated uncertainty is too wide"
            )
    return ModelDraws("probability", tuple(_set(uncertain, row) for row in draws), stated)


_REDRAWS = 100
"""Draws tried for one parameter set before the stated uncertainty is called too wide."""


def _draw(
    rng: np.random.Generator, uncertain: list[tuple[str, str, float, ParameterUncertainty]], n: int
) -> np.ndarray:
    """``n`` parameter sets (rows) of the beliefs (module docstring)."""
    columns = []
    for _, _, value, spread in uncertain:
        if spread.interval is not None:
            columns.append(rng.uniform(*spread.interval, size=n))
        else:
            assert spread.rel_sd is not None
            z = _truncated_normal(rng, n)
            columns.append(value * (1.0 + spread.rel_sd * z))
    return np.column_stack(columns)


def _holds(spec: ClosedLoopSpec, params: ParamSet) -> bool:
    """Whether each plant with ``params`` has an equilibrium at every set point of the test
    (its loops' initial set points, then after each step), where the model can say (a plant
    whose outputs are all its loops' sensors and that has an ``equilibrium``). A draw that
    cannot hold them is no plant the agent runs: it is drawn again (the belief truncated to
    plants that do what this one does)."""
    for name, plant in spec.plants.items():
        loops = [lp for lp in spec.loops.values() if lp.plant == name]
        model = plant_model(plant, params.get(name, {}))
        if not hasattr(model, "equilibrium") or set(model.output_names) != {
            lp.sensor for lp in loops
        }:
            continue
        y_bar = {lp.sensor: float(lp.setpoint) for lp in loops}
        points = [dict(y_bar)]
        for step in spec.steps:
            if step.loop in spec.loops and spec.loops[step.loop].plant == name:
                y_bar[spec.loops[step.loop].sensor] = float(step.value)
                points.append(dict(y_bar))
        try:
            for point in points:
                model.equilibrium(point)
        except ValueError:
            return False
    return True


def _truncated_normal(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` standard normal draws within +-:data:`TRUNCATE_SD` (rejection, in order)."""
    out: list[float] = []
    while len(out) < n:
        z = rng.standard_normal(n)
        out.extend(float(v) for v in z if abs(v) <= TRUNCATE_SD)
    return np.array(out[:n])


def _set(uncertain: list[tuple[str, str, float, ParameterUncertainty]], values: Any) -> ParamSet:
    out: dict[str, dict[str, float]] = {}
    for (plant, name, _, _), v in zip(uncertain, values, strict=True):
        out.setdefault(plant, {})[name] = float(v)
    return out


def plant_model(plant: JudgedPlant, params: Mapping[str, float]) -> Any:
    """``plant``'s model with ``params`` replacing some of its parameters."""
    if not params:
        return plant.model
    return registry.build(plant.kind, {**plant.params, **params})


def believing(
    spec: ClosedLoopSpec,
    params: ParamSet,
    uncertainty: Mapping[str, Mapping[str, ParameterUncertainty]],
) -> ClosedLoopSpec:
    """``spec`` with its plants believed anew (an identification's estimate): ``params``
    (plant -> parameter -> value) replace the believed values, and ``uncertainty`` (plant ->
    parameter -> spread) the stated spread of those parameters (others keep theirs); the
    fingerprint follows."""
    plants = dict(spec.plants)
    for name in sorted(set(params) | set(uncertainty)):
        plant = plants[name]
        values = {**plant.params, **params.get(name, {})}
        plants[name] = replace(
            plant,
            model=plant_model(plant, params.get(name, {})),
            params=values,
            uncertainty={**plant.uncertainty, **uncertainty.get(name, {})},
        )
    what = {
        "was": spec.fingerprint,
        "params": {p: dict(v) for p, v in sorted(params.items())},
        "uncertainty": {
            p: {n: u.model_dump(exclude_none=True) for n, u in sorted(v.items())}
            for p, v in sorted(uncertainty.items())
        },
    }
    digest = hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()[:16]
    return replace(spec, plants=plants, fingerprint=digest)
