"""Plant models by the name a scenario uses in ``model:``."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from plants.cascade_ct import CascadeCT, CascadeCTParams
from plants.column import ColumnParams
from plants.column_plant import ColumnPlant
from plants.cstr_recycle import CSTRRecycle, CSTRRecycleParams
from plants.jcstr import JCSTR, JCSTRParams
from plants.perturbed_reduced import PerturbedReduced, PerturbedReducedParams
from plants.tank import Tank, TankParams

__all__ = ["MODELS", "build", "params_type"]

MODELS: dict[str, tuple[type[Any], type[BaseModel]]] = {
    "jcstr": (JCSTR, JCSTRParams),
    "tank": (Tank, TankParams),
    "cstr_recycle": (CSTRRecycle, CSTRRecycleParams),
    "cascade_ct": (CascadeCT, CascadeCTParams),
    "column": (ColumnPlant, ColumnParams),  # seed 003: the non-linear distillation column
    "perturbed_reduced": (PerturbedReduced, PerturbedReducedParams),  # seed 003, section 6.3.1
}


def params_type(model: str) -> type[BaseModel]:
    """The parameter model of plant ``model`` (``KeyError`` if unknown)."""
    return MODELS[model][1]


def build(model: str, params: BaseModel | dict) -> Any:
    """A plant object of kind ``model`` from validated or raw parameters."""
    cls, ptype = MODELS[model]
    if not isinstance(params, ptype):
        params = ptype.model_validate(params)
    return cls(params)
