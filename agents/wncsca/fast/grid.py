"""The fast method's grids of candidate periods and the overshoot curves it walks along them
(:mod:`agents.wncsca.fast`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.wncsca.fast.predictor import LinearPredictor
from core.time import TICKS_PER_UNIT, to_ticks

COARSE_RATIO = 1.1  # geometric step of the first, coarse scan of a loop's periods
FINE_POINTS = 48  # candidates per refinement of a bracket
WINDOW = 1.08  # a search from a previous answer first tries every period within this ratio


class Curves:
    """Memoised predictions: per loop and context (the periods of the loops it depends on,
    itself excepted), the predicted overshoot at each of its periods (ticks)."""

    def __init__(self, predictor: LinearPredictor) -> None:
        self.predictor = predictor
        self.memo: dict[tuple[str, tuple[int, ...]], dict[int, float]] = {}

    def _keys(self, loop: str, ticks: NDArray[np.int64]) -> list[tuple[tuple[int, ...], int]]:
        col = self.predictor.index[loop]
        cols = [self.predictor.index[n] for n in self.predictor.depends[loop] if n != loop]
        return [(tuple(int(v) for v in r[cols]), int(r[col])) for r in ticks]

    def known(self, loop: str, row: NDArray[np.float64]) -> dict[int, float]:
        """Period of ``loop`` (ticks) -> memoised prediction, the other periods as in ``row``."""
        ticks = np.rint(np.atleast_2d(row) * TICKS_PER_UNIT).astype(np.int64)
        return self.memo.get((loop, self._keys(loop, ticks)[0][0]), {})

    def overshoots(self, loop: str, rows: NDArray[np.float64]) -> NDArray[np.float64]:
        """Predicted worst-case overshoot of ``loop`` per row of periods (rows x loops)."""
        ticks = np.rint(np.atleast_2d(rows) * TICKS_PER_UNIT).astype(np.int64)
        keys = self._keys(loop, ticks)
        missing: dict[tuple[tuple[int, ...], int], int] = {}
        for k, (ctx, h) in enumerate(keys):
            if h not in self.memo.get((loop, ctx), {}) and (ctx, h) not in missing:
                missing[(ctx, h)] = k
        if missing:
            batch = ticks[list(missing.values())].astype(float) / TICKS_PER_UNIT
            for (ctx, h), v in zip(missing, self.predictor.overshoots(loop, batch), strict=True):
                self.memo.setdefault((loop, ctx), {})[h] = float(v)
        return np.array([self.memo[(loop, ctx)][h] for ctx, h in keys])


def grid(value: float | NDArray[np.float64], res: float) -> Any:
    return np.round(np.round(np.asarray(value) / res) * res, 12)


def walk(
    known: Mapping[int, float], start: int, limit: float, res: int, top: int
) -> tuple[str, int, int]:
    """From ``start`` (ticks, known), up through the known periods while the prediction is
    within ``limit`` (down while it is not): ``(mode, lo, hi)`` with ``lo`` the longest
    acceptable period before the first crossing and ``hi`` the violating one after it (-1 when
    unknown); mode ``done``, ``fine`` (unknown grid periods between them), ``up`` or ``down``."""
    hs = sorted(known)
    lo = hi = -1
    if known[start] <= limit:
        lo = start
        for h in hs[hs.index(start) + 1 :]:
            if known[h] > limit:
                hi = h
                break
            lo = h
        if hi < 0:
            return ("done" if lo >= top else "up"), lo, hi
    else:
        hi = start
        for h in reversed(hs[: hs.index(start)]):
            if known[h] <= limit:
                lo = h
                break
            hi = h
        if lo < 0:
            return ("done" if hi <= res else "down"), lo, hi
    return ("fine" if hi - lo > 1.5 * res else "done"), lo, hi


def longest(
    curves: Curves,
    loop: str,
    rows: NDArray[np.float64],
    starts: NDArray[np.float64],
    limit: float,
    *,
    res: float,
    max_period: float,
    cold: bool,
) -> NDArray[np.float64]:
    """For each row of periods, the longest period of ``loop`` on the ``res`` grid whose
    predicted overshoot is within ``limit``: from ``starts`` up to the first crossing (down to
    the first acceptable period when the start is over the limit); ``nan`` when no period down
    to ``res`` is. The first round tries a geometric spread around the start (``cold``: mostly
    above it, from the ideal period) and, from a previous answer, every grid period within a few
    per cent of it; the crossing is then bracketed and refined to the grid. The rows are
    searched together, one batch of candidates per round."""
    col = curves.predictor.index[loop]
    n = len(rows)
    res_t = to_ticks(res)
    top_t = to_ticks(float(grid(max_period, res)))
    start_t = np.clip([to_ticks(float(v)) for v in grid(starts, res)], res_t, top_t)
    mode = ["start"] * n
    lo = np.full(n, -1, dtype=np.int64)
    hi = np.full(n, -1, dtype=np.int64)
    for r in range(n):  # what is already predicted for a row may settle or bracket it
        known = curves.known(loop, rows[r])
        if not cold and int(start_t[r]) in known:
            mode[r], lo[r], hi[r] = walk(known, int(start_t[r]), limit, res_t, top_t)
    for _round in range(64):
        cands: list[NDArray[np.float64]] = []
        for r in range(n):
            s = start_t[r] / TICKS_PER_UNIT
            if mode[r] == "start" and cold:
                c = np.append(s * COARSE_RATIO ** np.arange(-3, 17), s)
            elif mode[r] == "start":
                a, b = grid(s / WINDOW, res), grid(s * WINDOW, res)
                k = int(round((b - a) / res))
                c = a + res * np.round(np.linspace(0, k, min(k + 1, FINE_POINTS)))
                c = np.concatenate([c, [s], s * COARSE_RATIO ** np.arange(-3, 6)])
            elif mode[r] == "up":
                c = lo[r] / TICKS_PER_UNIT * COARSE_RATIO ** np.arange(1, 9)
            elif mode[r] == "down":
                c = hi[r] / TICKS_PER_UNIT / COARSE_RATIO ** np.arange(1, 9)
            elif mode[r] == "fine":
                k = int(round((hi[r] - lo[r]) / res_t)) - 1
                steps_ = np.unique(np.round(np.linspace(1, k, min(k, FINE_POINTS))))
                c = lo[r] / TICKS_PER_UNIT + res * steps_
            else:
                c = np.zeros(0)
            cands.append(np.unique(np.clip(grid(c, res), res, top_t / TICKS_PER_UNIT)))
        if not any(len(c) for c in cands):
            break
        owner = np.concatenate([np.full(len(c), r) for r, c in enumerate(cands)]).astype(int)
        batch = rows[owner].copy()
        batch[:, col] = np.concatenate(cands)
        curves.overshoots(loop, batch)
        for r in range(n):
            if mode[r] != "done":
                mode[r], lo[r], hi[r] = walk(
                    curves.known(loop, rows[r]), int(start_t[r]), limit, res_t, top_t
                )
    return np.where(lo >= 0, lo / TICKS_PER_UNIT, np.nan)
