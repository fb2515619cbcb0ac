"""Seeded Gaussian knots of a drifting disturbance, a pure function of their index.

A plant that adds a slowly drifting random disturbance (linear interpolation between unit
Gaussian knots ``w_k`` at ``k x period``) must give every engine the same value at the same time,
whatever order and step the integrator asks in. So knot ``k`` is drawn from
``np.random.default_rng([seed, stream, c])`` in chunks of :data:`CHUNK` knots (chunk ``c`` holds
knots ``c*CHUNK ...``) and cached: the same ``(seed, stream, k)`` always gives the same value.
Used by :mod:`plants.cascade.plant` and :mod:`plants.perturbed_reduced`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CHUNK", "Knots"]

CHUNK = 4096
"""Disturbance knots drawn per generator call (chunk ``c`` holds knots ``c*CHUNK ...``)."""


class Knots:
    """Unit Gaussian knots ``w_k`` of one disturbance stream, drawn chunk by chunk, cached."""

    __slots__ = ("_seed", "_stream", "_chunks")

    def __init__(self, seed: int, stream: int) -> None:
        self._seed, self._stream = seed, stream
        self._chunks: dict[int, list[float]] = {}

    def __getitem__(self, k: int) -> float:
        c, i = divmod(k, CHUNK)
        chunk = self._chunks.get(c)
        if chunk is None:
            rng = np.random.default_rng([self._seed, self._stream, c])
            chunk = self._chunks[c] = rng.standard_normal(CHUNK).tolist()
        return chunk[i]
