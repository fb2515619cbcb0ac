"""Generalized binary noise (Tulleken 1990): the pseudo-random perturbation of an identification
experiment.

A GBN signal takes the values ``+amplitude`` and ``-amplitude`` and, at each sampling instant of
its clock, switches with probability ``p_switch``: its mean dwell time is ``period / p_switch``,
which sets where its power lies (a long dwell excites the slow dynamics). A PRBS is the special
case of a shift register; GBN is its seeded, any-length relative, used here because the
experiment's length is free. Every draw comes from the generator given (the node owns it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["gbn"]


def gbn(n: int, p_switch: float, amplitude: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """``n`` values of a GBN signal (see the module docstring), starting at ``+amplitude``.

    Raises
    ------
    ValueError
        ``n < 1``, ``p_switch`` outside ``(0, 1]`` or ``amplitude <= 0``.
    """
    if n < 1 or not 0.0 < p_switch <= 1.0 or not amplitude > 0.0:
        raise ValueError(
            f"gbn: n={n} >= 1, 0 < p_switch={p_switch} <= 1, amplitude={amplitude} > 0"
        )
    switches = rng.random(n) < p_switch
    switches[0] = False
    sign = np.where(np.cumsum(switches) % 2 == 0, 1.0, -1.0)
    return amplitude * sign
