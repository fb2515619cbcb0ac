"""The distillation column of seed 003 as a plant node runs it.

:class:`plants.column.Column` with every stage composition an output: a loop's sensor names the
stage it measures (``x16`` = ``x_D`` at the top, ``x1`` = ``x_B`` at the bottom). The run's record
keeps the true state on the monitoring grid, and each loop's true output is read from it by the
sensor's name, so the sensors are named by states. The dynamics are
:meth:`plants.column.Column.rhs` unchanged; :meth:`ColumnPlant.equilibrium` takes set points by
these names.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from plants.column import FITTED_PARAMS, Column, ColumnParams

__all__ = ["ColumnPlant"]


class ColumnPlant(Column):
    """The column with outputs ``x1 ... xN`` (reboiler to condenser).

    Parameters
    ----------
    params : ColumnParams
        Column data; defaults to :data:`plants.column.FITTED_PARAMS`.
    """

    def __init__(self, params: ColumnParams = FITTED_PARAMS) -> None:
        super().__init__(params)
        self.output_names: tuple[str, ...] = self.state_names

    def outputs(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Every stage composition (``x[-1]`` is ``x_D``, ``x[0]`` is ``x_B``)."""
        return np.array(x, dtype=float)

    def equilibrium(self, y_bar: Mapping[str, float]) -> tuple[NDArray, NDArray]:
        """:meth:`Column.equilibrium` with the top and bottom set points named ``xN`` and
        ``x1``."""
        top, bottom = self.state_names[-1], self.state_names[0]
        missing = [n for n in (top, bottom) if n not in y_bar]
        if missing:
            raise ValueError(f"ColumnPlant.equilibrium: set points missing for outputs {missing}")
        return Column(self.params).equilibrium({"x_D": y_bar[top], "x_B": y_bar[bottom]})
