"""The fast method's search: the paper's question (or the least energy) on the predictor's
overshoots, verified on the non-linear model (:mod:`agents.wncsca.fast`)."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from agents.wncsca.assignment import Assignment, Trial
from agents.wncsca.batch import BatchTrials
from agents.wncsca.fast.grid import Curves, grid, longest
from agents.wncsca.fast.predictor import LinearPredictor
from agents.wncsca.model import LoopModel

OBJECTIVES = ("paper", "energy")
"""What the fast method optimises: the paper's answer, or the least network energy."""

MAX_VERIFY = 8  # bias-corrected re-solves before stepping down the grid
MAX_PROBES = 3  # energy objective: grid steps up tried per loop at the end
PIN_FACTORS = (0.95, 0.9, 0.8, 0.7, 0.6, 0.5)  # first trial pinned periods
PIN_COARSE = 5  # the trades are explored on a grid this many times coarser


def energy_rate(periods: Mapping[str, float], weights: Mapping[str, float] | None = None) -> float:
    """Network energy per time unit of the loops' samples: ``sum(weights[l] / periods[l])``
    (``weights[l]``: cost of one sample of loop ``l``, e.g. its transmissions; default 1)."""
    w = weights or {}
    return float(sum(float(w.get(n, 1.0)) / p for n, p in periods.items()))


# -- the linear model --------------------------------------------------------------------------


@dataclass
class Solver:
    """The linear searches of one call, the non-linear checks and their trace."""

    model: LoopModel
    delays: dict[str, float]
    curves: Curves
    order: list[str]
    weights: dict[str, float]
    trace: list[Trial] = field(default_factory=list)
    alternations: int = 0
    checked: list[tuple[dict[str, float], dict[str, float], bool]] = field(default_factory=list)
    history: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    batch: BatchTrials | None = None

    @property
    def loops(self) -> tuple[str, ...]:
        return self.curves.predictor.loops

    def ideal(self, loop: str) -> float:
        cfg = self.model.config
        return float(grid(cfg.ideal_period.get(loop, self.model.benchmark[loop]), cfg.resolution))

    def vector(self, periods: Mapping[str, float]) -> NDArray[np.float64]:
        return np.array([periods[n] for n in self.loops], dtype=float)

    def as_dict(self, p: NDArray[np.float64]) -> dict[str, float]:
        return {n: float(p[k]) for k, n in enumerate(self.loops)}

    def energy_of(self, rows: NDArray[np.float64]) -> NDArray[np.float64]:
        w = np.array([self.weights[n] for n in self.loops])
        energy: NDArray[np.float64] = np.sum(w[None, :] / np.atleast_2d(rows), axis=1)
        return energy

    def predicted(self, periods: Mapping[str, float]) -> dict[str, float]:
        vec = self.vector(periods)[None, :]
        return {n: float(self.curves.overshoots(n, vec)[0]) for n in self.loops}

    def longest(
        self,
        loop: str,
        rows: NDArray[np.float64],
        starts: NDArray[np.float64],
        limit: float,
        cold: bool = False,
        coarse: int = 1,
    ) -> NDArray[np.float64]:
        """:func:`longest` on the ``resolution`` grid (``coarse`` times coarser)."""
        cfg = self.model.config
        return longest(
            self.curves,
            loop,
            rows,
            starts,
            limit,
            res=cfg.resolution * coarse,
            max_period=cfg.max_period,
            cold=cold,
        )

    # -- the objectives on the predictions ------------------------------------------------------
    def paper(
        self,
        start: Mapping[str, float],
        limits: Mapping[str, float],
        *,
        first: bool = False,
        fixed: tuple[str, ...] = (),
    ) -> dict[str, float] | None:
        """Each loop's longest predicted period with the others fixed, alternating until no
        period changes (seed 000, III.E step 3 on the predictions); loops in ``fixed`` keep
        their period. The first search of a loop starts at its ideal period when ``first``, else
        at its current period."""
        cfg = self.model.config
        p = self.vector(start)
        idx = self.curves.predictor.index
        alternation = 0
        for alternation in range(1, cfg.max_alternations + 1):
            changed = False
            for loop in self.order:
                if loop in fixed:
                    continue
                cold = first and alternation == 1
                begin = self.ideal(loop) if cold else p[idx[loop]]
                new = self.longest(loop, p[None, :], np.array([begin]), limits[loop], cold)[0]
                if not np.isfinite(new):
                    self.alternations += alternation
                    return None
                if new == p[idx[loop]] and not cold:
                    continue
                changed = True
                p[idx[loop]] = new
                value = float(self.curves.overshoots(loop, p[None, :])[0])
                self.trace.append(
                    Trial(
                        self.alternations + alternation,
                        loop,
                        "predict",
                        float(new),
                        self.as_dict(p),
                        {loop: value},
                        value <= limits[loop],
                    )
                )
            if not changed:
                break
        self.alternations += alternation
        return self.as_dict(p)

    def pinned(
        self, base: Mapping[str, float], limits: Mapping[str, float]
    ) -> tuple[dict[str, float], str] | None:
        """A choice of less predicted energy than ``base`` (each loop at its longest period),
        or ``None``: one loop at a time is pinned at shorter periods while the others take their
        longest periods; the best choice whose every predicted overshoot is within its limit."""
        cfg = self.model.config
        idx = self.curves.predictor.index
        p0 = self.vector(base)
        best: tuple[float, NDArray[np.float64], str] = (float(self.energy_of(p0)[0]), p0, "")
        for factors in (PIN_FACTORS, None):
            for loop_pinned in self.order if factors is not None else [best[2]]:
                if not loop_pinned:
                    continue
                now = best[1][idx[loop_pinned]]
                if factors is None:  # refine around the best pinned period found
                    ratio = now / p0[idx[loop_pinned]]
                    fs = ratio * np.array([0.97, 0.985, 1.015, 1.03])
                    vals = grid(p0[idx[loop_pinned]] * fs, cfg.resolution)
                else:
                    vals = grid(now * np.array(factors), cfg.resolution)
                vals = np.unique(vals)
                vals = vals[(vals >= cfg.resolution) & (vals < p0[idx[loop_pinned]])]
                if not len(vals):
                    continue
                rows = np.repeat(p0[None, :], len(vals), axis=0)
                rows[:, idx[loop_pinned]] = vals
                alive = np.ones(len(rows), dtype=bool)
                for _round in range(cfg.max_alternations):
                    before = rows.copy()
                    for loop in self.order:
                        if loop == loop_pinned:
                            continue
                        new = self.longest(
                            loop, rows, rows[:, idx[loop]], limits[loop], coarse=PIN_COARSE
                        )
                        alive &= np.isfinite(new)
                        rows[:, idx[loop]] = np.where(np.isfinite(new), new, rows[:, idx[loop]])
                    if np.array_equal(before, rows):
                        break
                for loop in self.loops:
                    alive &= self.curves.overshoots(loop, rows) <= limits[loop]
                e = np.where(alive, self.energy_of(rows), np.inf)
                k = int(np.argmin(e))
                if e[k] < best[0] * (1 - 1e-9):
                    best = (float(e[k]), rows[k].copy(), loop_pinned)
        if not best[2]:
            return None
        choice = self.as_dict(best[1])
        self.trace.append(
            Trial(
                self.alternations,
                best[2],
                "predict",
                choice[best[2]],
                choice,
                self.predicted(choice),
                True,
            )
        )
        return choice, best[2]

    # -- the non-linear checks ------------------------------------------------------------------
    def nonlinear(self, periods: Mapping[str, float]) -> dict[str, float]:
        """Overshoots of ``periods`` on the non-linear model: the batch's (the engine's numbers,
        :class:`agents.wncsca.batch.BatchTrials`) when the solver has one, else the engine's
        (:meth:`LoopModel.evaluate`)."""
        if self.batch is None:
            return dict(self.model.evaluate(periods, self.delays).overshoot_pct)
        rows = self.vector(periods)[None, :]
        # the loops the calibration moved since the last check often end a grid step from here:
        # their neighbours ride along in this check's batches (memoised, no batch of their own)
        moved: NDArray[np.intp] | list[int] = (
            np.flatnonzero(rows[0] != self.vector(self.checked[-1][0])) if self.checked else []
        )
        if len(moved):
            cfg = self.model.config
            ahead = np.repeat(rows, 2 * len(moved), axis=0)
            for m, k in enumerate(moved):
                for sgn, r in ((-1.0, 2 * m), (1.0, 2 * m + 1)):
                    ahead[r, k] = grid(ahead[r, k] + sgn * cfg.resolution, cfg.resolution)
            keep = np.all((ahead >= cfg.resolution) & (ahead <= cfg.max_period), axis=1)
            return self.as_dict(self.batch.overshoots(rows, self.delays, ahead[keep])[0])
        return self.as_dict(self.batch.overshoots(rows, self.delays)[0])

    def check(self, periods: Mapping[str, float]) -> tuple[dict[str, float], bool]:
        """Overshoots of ``periods`` on the non-linear model (:meth:`nonlinear`), traced;
        remembers each loop's (predicted, checked) pair for the calibration."""
        limit = self.model.config.overshoot_limit
        os_pct = self.nonlinear(periods)
        ok = all(v <= limit for v in os_pct.values())
        self.trace.append(
            Trial(self.alternations, None, "verify", None, dict(periods), dict(os_pct), ok)
        )
        self.checked.append((dict(periods), dict(os_pct), ok))
        predicted = self.predicted(periods)
        for n in self.loops:
            if math.isfinite(os_pct[n]) and math.isfinite(predicted[n]):
                self.history.setdefault(n, []).append((predicted[n], os_pct[n]))
        return dict(os_pct), ok

    def calibrated_limits(self, target: float) -> dict[str, float]:
        """Per loop, the predicted overshoot that corresponds to ``target`` checked: the checked
        overshoot is taken as ``a + c * predicted``, with ``c`` from the last two checks of the
        loop whose predictions differ (a secant) and ``c = 1`` (a constant bias) before that."""
        limit = target
        out = {}
        for n in self.loops:
            pairs = self.history.get(n, [])
            if not pairs:
                out[n] = limit
                continue
            p2, o2 = pairs[-1]
            slope = 1.0
            for p1, o1 in reversed(pairs[:-1]):
                if abs(p2 - p1) > 0.05:
                    slope = float(np.clip((o2 - o1) / (p2 - p1), 0.25, 4.0))
                    break
            out[n] = p2 + (limit - o2) / slope
        return out

    def probe(self, periods: Mapping[str, float]) -> dict[str, float]:
        """Lengthen each loop (in order) more than a quarter of ``os_tolerance`` below the limit
        one grid step at a time while the non-linear check passes (at most
        :data:`MAX_PROBES` steps a loop): the calibrated predictions may stop a grid step or
        so short of where the non-linear overshoot crosses the limit."""
        cfg = self.model.config
        best = dict(periods)
        checked = {tuple(sorted(c[0].items())): c[1] for c in self.checked}
        for loop in self.order:
            os_now = checked.get(tuple(sorted(best.items())), {}).get(loop, -math.inf)
            if os_now >= cfg.overshoot_limit - cfg.os_tolerance / 4:
                continue
            for _ in range(MAX_PROBES):
                trial = {**best, loop: float(grid(best[loop] + cfg.resolution, cfg.resolution))}
                if trial[loop] > cfg.max_period or any(c[0] == trial for c in self.checked):
                    break
                if not self.check(trial)[1]:
                    break
                best = trial
        return best

    def correct(
        self,
        start: Mapping[str, float],
        *,
        early: bool,
        fixed: tuple[str, ...] = (),
    ) -> tuple[dict[str, float] | None, bool]:
        """Check ``start``; while it changes, solve the paper objective again on the calibrated
        predictions and check the new choice (a loop over the limit that the calibration does not
        move steps down the grid, further after each failure). Returns the choice within the
        limit (the last one at a fixed point, else the one of least energy) and whether a fixed
        point was reached (or, with ``early``, every loop is within ``os_tolerance`` of the
        limit, as the paper stops)."""
        cfg = self.model.config
        limit, res = cfg.overshoot_limit, cfg.resolution
        periods: dict[str, float] | None = dict(start)
        last_ok: dict[str, float] | None = None
        passed: list[dict[str, float]] = []
        failures = 0
        for _ in range(MAX_VERIFY + cfg.max_trials):
            if periods is None:
                break
            os_pct, ok = self.check(periods)
            if ok:
                last_ok = dict(periods)
                passed.append(last_ok)
                close = all(
                    os_pct[n] >= limit - cfg.os_tolerance or periods[n] >= cfg.max_period
                    for n in self.loops
                    if n not in fixed
                )
                if early and close:
                    return last_ok, True
            nxt = None
            if len(self.checked) <= MAX_VERIFY:
                # aim inside the paper's band when stopping there (and keep the loops already
                # in it), else at the limit itself
                target = limit - cfg.os_tolerance / 2 if early else limit
                keep = fixed
                if early:
                    band = [n for n in self.loops if limit - cfg.os_tolerance <= os_pct[n] <= limit]
                    keep = tuple(dict.fromkeys([*fixed, *band]))
                nxt = self.paper(periods, self.calibrated_limits(target), fixed=keep)
            if ok and nxt == periods:
                return last_ok, True
            if nxt is None or nxt == periods or any(nxt == c[0] for c in self.checked):
                if ok or (passed and nxt is not None):  # settled, or cycling through checks
                    return min(
                        passed, key=lambda p: float(self.energy_of(self.vector(p))[0])
                    ), False
                failures += 1
                nxt = dict(periods)
                for n in self.loops:
                    if os_pct[n] > limit:
                        nxt[n] = float(grid(max(res, periods[n] - res * 2 ** (failures - 1)), res))
                        self.trace.append(
                            Trial(self.alternations, n, "down", nxt[n], dict(nxt), os_pct, False)
                        )
                if nxt == periods:
                    return last_ok, False
            periods = nxt
        if not passed:
            return None, False
        return min(passed, key=lambda p: float(self.energy_of(self.vector(p))[0])), False


def fast_periods(
    model: LoopModel,
    delays: Mapping[str, float],
    *,
    objective: str = "paper",
    weights: Mapping[str, float] | None = None,
    order: Sequence[str] | None = None,
    batched: bool | None = None,
) -> Assignment:
    """Sampling periods by the fast method (module docstring), checked on the non-linear model.

    Parameters
    ----------
    model : LoopModel
        The agent's closed-loop model (limit, tolerances, grid, phases, test).
    delays : mapping
        Control-path delay of each loop, time units (default 0).
    objective : {"paper", "energy"}
        ``"paper"``: each loop's longest period with the others fixed, alternating (the paper's
        answer, seed 000 III.E step 3); ``"energy"``: the least ``sum(weights[l] / period[l])``
        with every overshoot within the limit.
    weights : mapping, optional
        Energy cost of one sample of each loop (e.g. transmissions per delivery); default 1.
    order : sequence of str, optional
        Loops in the order they are searched; default ``model.config.order``, else sorted.
    batched : bool, optional
        Run the non-linear checks as one batch per check (every plant and step phase at once,
        each plant's trials memoised: :class:`agents.wncsca.batch.BatchTrials`, the same
        overshoots as the engine's, so the same choices) when every plant allows it; ``False``:
        one engine trial per plant-wide check and phase (:meth:`LoopModel.evaluate`). Default:
        batched when the loops are on more than one plant (on one plant a check is a few engine
        trials, cheaper than a batch).

    Returns
    -------
    Assignment
        ``method="fast"``; ``extra`` holds the objective, weights, energy rate, the linear
        predictions and biases at the periods, the counts of predictions and checks, and of
        batched trials and batches (``simulations`` counts engine runs only).

    Raises
    ------
    ValueError
        For an unknown objective or loop, a weight that is not positive, or a loop whose law is
        not ``pi``.
    """
    t0 = time.perf_counter()
    sims0 = model.simulations
    order_l, w = _order_and_weights(model, objective, weights, order)
    delays = {n: float(delays.get(n, 0.0)) for n in model.loops}
    predictor = LinearPredictor(model, delays)
    batch = _batch(model, batched)
    solver = Solver(model, delays, Curves(predictor), order_l, w, batch=batch)
    choice, converged = _search(solver, model, objective, w)
    final, feasible, reason = _outcome(solver, model, choice, converged)
    os_final = solver.nonlinear(final)
    predicted = solver.predicted(final)
    return Assignment(
        method="fast",
        delays=delays,
        periods=final,
        overshoot_pct=os_final,
        feasible=feasible and all(v <= model.config.overshoot_limit for v in os_final.values()),
        converged=converged,
        alternations=solver.alternations,
        trace=solver.trace,
        simulations=model.simulations - sims0,
        decision_time_s=time.perf_counter() - t0,
        reason=reason,
        extra={
            "objective": objective,
            "weights": w,
            "energy_rate": energy_rate(final, w),
            "predicted_pct": {n: _finite(v) for n, v in predicted.items()},
            "bias_pct": {n: _finite(os_final[n] - predicted[n]) for n in model.loops},
            **_counts(predictor, solver, batch),
        },
    )


def _outcome(
    solver: Solver, model: LoopModel, choice: dict[str, float] | None, converged: bool
) -> tuple[dict[str, float], bool, str]:
    """The periods to assign, whether a choice was found, and the reason when it was not (the
    benchmark periods are assigned then) or when the search did not settle."""
    if choice is not None:
        unsettled = "the corrected search did not settle: the last checked choice is assigned"
        return dict(choice), True, "" if converged else unsettled
    cfg = model.config
    return (
        dict(model.benchmark),
        False,
        f"no periods down to {cfg.resolution:g} keep every overshoot within "
        f"{cfg.overshoot_limit:g} % on the non-linear check ({len(solver.checked)} checked)",
    )


def _batch(model: LoopModel, batched: bool | None) -> BatchTrials | None:
    """The batched checks when asked for (default: when the loops are on more than one plant,
    where the batch pays off) and every plant allows them, else ``None``."""
    if batched is None:
        batched = len({model.trials.spec.loops[n].plant for n in model.loops}) > 1
    batch = BatchTrials(model) if batched else None
    return batch if batch is not None and batch.available else None


def _counts(
    predictor: LinearPredictor, solver: Solver, batch: BatchTrials | None
) -> dict[str, int]:
    """The work a search did: linear predictions (and their items), checks, batched trials."""
    return {
        "predictions": predictor.predictions,
        "predicted_items": predictor.items,
        "checks": len(solver.checked),
        "batched_trials": batch.items if batch is not None else 0,
        "batches": batch.batches if batch is not None else 0,
    }


def _order_and_weights(
    model: LoopModel,
    objective: str,
    weights: Mapping[str, float] | None,
    order: Sequence[str] | None,
) -> tuple[list[str], dict[str, float]]:
    """The loops in search order and each loop's weight, checked (``ValueError`` naming the
    argument)."""
    if objective not in OBJECTIVES:
        raise ValueError(f"objective: expected one of {list(OBJECTIVES)}, got {objective!r}")
    order_l = list(order or model.config.order or model.loops)
    unknown = [n for n in order_l if n not in model.loops]
    if unknown:
        raise ValueError(f"order: unknown loop(s) {unknown} (loops: {list(model.loops)})")
    order_l += [n for n in model.loops if n not in order_l]
    w = {n: float((weights or {}).get(n, 1.0)) for n in model.loops}
    bad = {n: v for n, v in w.items() if not v > 0}
    if bad:
        raise ValueError(f"weights: must be > 0, got {bad}")
    return order_l, w


def _search(
    solver: Solver, model: LoopModel, objective: str, w: Mapping[str, float]
) -> tuple[dict[str, float] | None, bool]:
    """The searches on the predictions, corrected by the non-linear checks: ``(choice,
    converged)``, ``None`` when no checked choice keeps every overshoot within the limit."""
    limit = model.config.overshoot_limit
    first = solver.paper(dict(model.benchmark), {n: limit for n in model.loops}, first=True)
    # when the raw predictions see nothing within the limit, the checks calibrate them from the
    # benchmark periods
    start = first if first is not None else dict(model.benchmark)
    choice, converged = solver.correct(start, early=objective == "paper")
    if objective == "energy" and choice is not None:
        # trade: a loop shorter than its longest period if the others gain more
        alt = solver.pinned(choice, solver.calibrated_limits(limit))
        if alt is not None:
            other, ok_alt = solver.correct(alt[0], early=False, fixed=(alt[1],))
            if other is not None and energy_rate(other, w) < energy_rate(choice, w):
                choice, converged = other, ok_alt
        choice = solver.probe(choice)
    passed = [c for c in solver.checked if c[2]]
    if objective == "energy" and passed:  # the checked choice of least energy
        choice = min((c[0] for c in passed), key=lambda p: energy_rate(p, w))
    return choice, converged


def _finite(value: float) -> float | None:
    """``value``, or ``None`` when it is not finite (diverged), for JSON summaries."""
    return float(value) if math.isfinite(value) else None
