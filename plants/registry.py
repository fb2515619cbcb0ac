"""Plant models by the name a scenario uses in ``model:`` (a :class:`~core.registry.Registry`).

To add a plant: a module with its parameter model (pydantic) and its class (built from the
parameters; ``state_names``, ``input_names``, ``output_names``, ``rhs`` or ``rhs_tuple``,
``outputs``), and one :class:`~core.registry.Kind` entry in :data:`MODELS`.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from core.registry import Kind, Registry
from plants.cascade.plant import CascadeCT, CascadeCTParams
from plants.column import ColumnParams
from plants.column_plant import ColumnPlant
from plants.cstr_recycle import CSTRRecycle, CSTRRecycleParams
from plants.jcstr import JCSTR, JCSTRParams
from plants.perturbed_reduced import PerturbedReduced, PerturbedReducedParams
from plants.tank import Tank, TankParams
from plants.tank_train import TankTrain, TankTrainParams

__all__ = ["MODELS", "build", "params_type"]

MODELS: Registry[Any] = Registry(
    "plant model",
    tag=None,  # the node names the model (model:) beside its parameters (params:)
    kinds=[
        Kind("jcstr", JCSTRParams, JCSTR, "seed 000: the jacketed CSTR"),
        Kind("tank", TankParams, Tank, "seed 002: a tank with a free outlet"),
        Kind(
            "tank_train",
            TankTrainParams,
            TankTrain,
            "seed 002's tanks in series, each feeding part of its outflow to the next",
        ),
        Kind("cstr_recycle", CSTRRecycleParams, CSTRRecycle, "seed 001: two CSTRs with recycle"),
        Kind("cascade_ct", CascadeCTParams, CascadeCT, "seed 004: the cascade process"),
        Kind("column", ColumnParams, ColumnPlant, "seed 003: the non-linear distillation column"),
        Kind(
            "perturbed_reduced",
            PerturbedReducedParams,
            PerturbedReduced,
            "seed 003, section 6.3.1: the perturbed reduced column",
        ),
    ],
)


def params_type(model: str) -> type[BaseModel]:
    """The parameter model of plant ``model`` (``KeyError`` naming the known ones if unknown)."""
    return MODELS[model].config


def build(model: str, params: BaseModel | dict[str, Any]) -> Any:
    """A plant object of kind ``model`` from validated or raw parameters."""
    kind = MODELS[model]
    if not isinstance(params, kind.config):
        params = kind.config.model_validate(params)
    assert kind.build is not None
    return kind.build(params)
