"""The chance-constrained guarantee of the coordination agent (issue 14): the overshoot of a
candidate configuration as a random variable over delay realizations, losses and step phases.

The paper's method (seed 000, III.E) judges a configuration by simulating its loops with a
*constant* delay, the mean. On the network the gateway emulates, each sample meets its own delay
and some are lost, so the overshoot of a step is random; the agent must assign periods that keep
``P(overshoot <= limit) >= confidence`` for every loop.

Model
-----
:class:`LinearMonteCarlo` simulates the agent's set-point test on the loops linearised at the
equilibrium of the initial set points (the plant data of :class:`agents.wncsca.fast.
LinearPredictor`: central-difference Jacobians, the steady-state feedforward of each stretch of
the test), for ``R`` realizations at once in numpy. In realization ``r``:

* loop ``i`` samples at ``k h_i``; sample ``k`` is lost with the loop's loss probability, else
  delivered after ``max(0, mu_i + delta_rk)``: ``mu_i`` the control-path mean delay being judged,
  ``delta`` a draw of the proposal's distribution minus its mean (its *shape*, held while ``mu``
  varies: so the delay bound is a bound on the mean with that shape);
* at each delivery the loop's law executes with the delivered value, as the controller node
  executes it (:mod:`agents.wncsca.laws`: the PI of :mod:`controllers.pi` with the feedforward of
  the set points in force, or seed 002's 2-DOF laws with their linearising term as it is; the
  integral over the actual time between executions, clamping anti-windup, output limits); a lost
  sample leaves the input held, as on the bus; a late sample overtaken by a newer one is still
  executed, as the controller node does;
* each test step falls at a random phase ``j / 64`` of its loop's period after a sampling instant
  (``j`` uniform), the phases the paper's ``phase: worst`` tries at 4 points;
* between events the plant is LTI, so the state moves exactly (modal exponentials), and the output
  is read on the plant's monitoring grid, where :func:`core.record.loop_metrics` reads it.

The draws are common random numbers: every evaluation of one model reuses the same uniforms, so
candidate periods are compared on the same realizations and the searches see a deterministic,
reproducible function.

Guarantee
---------
``P(overshoot <= limit) >= confidence`` is estimated by the share of realizations within the
limit (the sample-average approximation): at most ``k_max = floor((1 - confidence) R)`` of the
``R`` realizations may exceed it, i.e. the ``(R - k_max)``-th smallest overshoot must be within
the limit. That order statistic is the *risk overshoot* the searches of
:mod:`agents.wncsca.paper` and :mod:`agents.wncsca.bounds` compare with the limit, unchanged.
Every decision reports the estimate with its two-sided 95 % Clopper-Pearson interval.

The linearisation's error is corrected on the non-linear model (:meth:`ChanceModel.check`): the
realizations whose linear overshoot ranks nearest the risk order statistic are replayed on the
direct engine (their delay sequences on a wired path, ``traces:``; their phases exactly), and the
mean paired difference there is added to the linear overshoots. For the JCSTR level (a linear
plant) the two models agree to 1e-8 points realization by realization; for the temperature the
linear model overshoots 0-5 points more, depending on the step phase.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.wncsca.fast import LinearPredictor, phi1
from agents.wncsca.fast.predictor import PlantData
from agents.wncsca.laws import modelled_law, stack
from agents.wncsca.model import Evaluation, LoopModel
from agents.wncsca.spec import JudgedPlant
from agents.wncsca.uncertainty import ModelDraws, model_draws, plant_model
from core.time import TICKS_PER_UNIT, to_ticks, to_units
from gateway import distribution

__all__ = [
    "PHASES",
    "LoopLaw",
    "risk_index",
    "probability_interval",
    "LinearMonteCarlo",
    "ChanceModel",
]

PHASES = 64
"""Step phases are ``j / PHASES`` of the loop's period after a sampling instant."""

_MONITOR, _SAMPLE, _DELIVER, _STEP, _NONE = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class LoopLaw:
    """A loop's delay law for the realizations: the shape (draws minus their mean, time units,
    a quantile table ``(probabilities, delays)``) and the loss probability."""

    probabilities: tuple[float, ...] = (0.0, 1.0)
    delays: tuple[float, ...] = (0.0, 0.0)
    loss: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.loss < 1.0:
            raise ValueError(f"loss: must be in [0, 1), got {self.loss}")

    @property
    def mean(self) -> float:
        return distribution.mean((self.probabilities, self.delays))

    def draw(
        self, mean: float, u_delay: NDArray[np.float64], u_loss: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Delays (the shape located at ``mean``, at least 0) and loss flags of samples, by
        the inverse CDF at the uniforms ``u_delay`` and ``u_loss < loss``."""
        d = np.interp(u_delay, self.probabilities, self.delays) - self.mean
        return np.maximum(0.0, mean + d), u_loss < self.loss

    def trace(
        self, mean: float, u_delay: NDArray[np.float64], u_loss: NDArray[np.float64]
    ) -> list[float | None]:
        """:meth:`draw` as a wired network's ``traces:`` entry (``None``: lost)."""
        d, lost = self.draw(mean, u_delay, u_loss)
        return [None if x else float(v) for v, x in zip(d, lost, strict=True)]


def risk_index(realizations: int, confidence: float) -> int:
    """``k_max``: the most of ``realizations`` that may exceed the limit,
    ``floor((1 - confidence) R)`` (the sample-average approximation of the chance constraint;
    the 95 % interval of the probability is reported beside it, :func:`probability_interval`)."""
    return int(math.floor((1.0 - confidence) * realizations + 1e-9))


def probability_interval(within: int, total: int) -> tuple[float, float]:
    """Two-sided 95 % Clopper-Pearson interval of ``P(within)`` from ``within`` of ``total``."""
    import scipy.stats

    lo = 0.0 if within == 0 else float(scipy.stats.beta.ppf(0.025, within, total - within + 1))
    hi = 1.0 if within == total else float(scipy.stats.beta.ppf(0.975, within + 1, total - within))
    return lo, hi


class _Uniforms:
    """Uniform draws ``(R, k)`` whose first ``k`` columns do not depend on how many are asked
    for: drawn in blocks of :data:`_BLOCK` columns, in order."""

    def __init__(self, rng: np.random.Generator, rows: int) -> None:
        self._rng, self._rows = rng, rows
        self._data = np.zeros((rows, 0))

    def take(self, k: int) -> NDArray[np.float64]:
        while self._data.shape[1] < k:
            block = self._rng.random((_BLOCK, self._rows)).T
            self._data = np.concatenate([self._data, block], axis=1)
        return self._data[:, :k]


_BLOCK = 64


@dataclass(frozen=True)
class _Windows:
    """The test's steps as the overshoot reads them: each step's loop, start and target values,
    and its window ``[start, end)`` per realization (it ends at the loop's next step)."""

    loop: list[int]
    frm: NDArray[np.float64]
    to: NDArray[np.float64]
    start: NDArray[np.float64]  # steps x realizations
    end: NDArray[np.float64]

    def watch(
        self,
        ext: NDArray[np.float64],
        mon: NDArray[np.bool_],
        t: NDArray[np.float64],
        y: NDArray[np.float64],
    ) -> None:
        """Raise each step's largest excursion ``ext`` (realizations x steps) by the outputs
        ``y`` the monitor reads at ``t`` (where ``mon``) inside the step's window."""
        sign = np.sign(self.to - self.frm)
        for s, i in enumerate(self.loop):
            act = mon & (t >= self.start[s]) & (t < self.end[s])
            if act.any():
                v = sign[s] * (y[:, i] - self.to[s])
                ext[:, s] = np.where(act, np.maximum(ext[:, s], v), ext[:, s])

    def overshoots(self, ext: NDArray[np.float64], n_loops: int) -> NDArray[np.float64]:
        """Each loop's overshoot (%), the worst of its steps', per realization."""
        size = np.abs(self.to - self.frm)
        os_steps = 100.0 * np.maximum(ext, 0.0) / np.where(size > 0, size, np.inf)
        out = np.zeros((len(ext), n_loops))
        for s, i in enumerate(self.loop):
            out[:, i] = np.maximum(out[:, i], os_steps[:, s])
        return out


def _drawn(data: PlantData, plant: JudgedPlant, params: Mapping[str, float]) -> PlantData:
    """The plant data of ``data`` with ``params`` replacing some of its model's parameters (the
    loops' feedforwards on that model too: the controllers know the plant they run on, as the
    bus's controller nodes do)."""
    if not params:
        return data
    model = plant_model(plant, params)
    return dataclasses.replace(
        data,
        model=model,
        feedforward={n: None if ff is None else ff.on(model) for n, ff in data.feedforward.items()},
        _ubar={},
        _lin={},
    )


class LinearMonteCarlo:
    """The agent's test on the linearised loops over ``realizations`` random realizations (see
    the module docstring).

    Parameters
    ----------
    model : LoopModel
        The agent's model (its trial scenario, test, loops and control laws).
    laws : mapping
        Loop -> :class:`LoopLaw` (default: constant delay, no loss).
    realizations : int
        Realizations ``R`` (a robust model: ``R`` per corner, :attr:`R` rows in all).
    seed : int
        Seed of the common random numbers.
    draws : ModelDraws, optional
        The model's parameter sets (:mod:`agents.wncsca.uncertainty`): realization ``r`` runs
        on set ``r mod M`` (probability), or each corner on a block of ``R`` realizations of
        its own (robust: :attr:`blocks`). Default: the model itself.

    Raises
    ------
    ValueError
        A loop's law is not modelled (:mod:`agents.wncsca.laws`), or the linearised plant is
        not diagonalisable.
    """

    def __init__(
        self,
        model: LoopModel,
        laws: Mapping[str, LoopLaw],
        realizations: int,
        seed: int,
        draws: ModelDraws | None = None,
    ) -> None:
        lin = LinearPredictor(model, {})
        self.loops = lin.loops
        self.draws = draws or ModelDraws("exact", ({},), {})
        M = len(self.draws.sets)
        if self.draws.mode == "robust":
            self.R = realizations * M
            self.blocks = [slice(m * realizations, (m + 1) * realizations) for m in range(M)]
            self.draw_of = np.repeat(np.arange(M), realizations)
        else:
            self.R = realizations
            self.blocks = [slice(0, realizations)]
            self.draw_of = np.arange(realizations) % M
        self.laws = {n: laws.get(n, LoopLaw()) for n in self.loops}
        spec = model.trials.spec
        self.control = dict(lin.laws)  # each loop's control law, per realization's draw
        if not self.draws.exact:
            for n in self.loops:
                judged = spec.loops[n]
                plant = spec.plants[judged.plant]
                self.control[n] = stack(
                    [
                        modelled_law(judged.law, plant_model(plant, p.get(judged.plant, {})), n)
                        for p in self.draws.sets
                    ],
                    self.draw_of,
                )
        self.end = to_units(lin.end)
        plants = list(lin.plants.values())
        # one state vector: the plants' states stacked
        offsets, nx, nu = {}, 0, 0
        for p in plants:
            offsets[p.name] = (nx, nu)
            nx += len(p.x0)
            nu += len(p.u0)
        self.x0 = np.zeros(nx)
        self.u0 = np.zeros(nu)
        self.u_col: dict[str, int] = {}
        self.monitor = min(p.monitor for p in plants)
        for p in plants:
            ox, ou = offsets[p.name]
            self.x0[ox : ox + len(p.x0)] = p.x0
            self.u0[ou : ou + len(p.u0)] = p.u0
            for name in p.loops:
                self.u_col[name] = ou + p.u_index[name]
        # the test's steps: stage s holds the set points after the first s steps
        self.steps = sorted(lin.steps)
        sp = dict(lin.initial)
        stage_sp = [dict(sp)]
        for _, loop, value in self.steps:
            sp[loop] = value
            stage_sp.append(dict(sp))
        n_loops = len(self.loops)
        self.n_stages = len(stage_sp)
        for m, params in enumerate(self.draws.sets):
            drawn = [_drawn(p, spec.plants[p.name], params.get(p.name, {})) for p in plants]
            self._linearise_stages(drawn, offsets, nx, nu, stage_sp, m * self.n_stages, M)
        self.initial = np.array([lin.initial[n] for n in self.loops])
        rng = np.random.default_rng(seed)
        self.phase_j = rng.integers(0, PHASES, size=(len(self.steps), self.R))
        # common random numbers: sample k of realization r draws the same uniforms whatever
        # the period (the streams grow in blocks of samples as shorter periods need more)
        self._u_delay = [
            _Uniforms(np.random.default_rng([seed, 1, i]), self.R) for i in range(n_loops)
        ]
        self._u_loss = [
            _Uniforms(np.random.default_rng([seed, 2, i]), self.R) for i in range(n_loops)
        ]
        self.simulations = 0

    def _linearise_stages(
        self,
        plants: list[PlantData],
        offsets: Mapping[str, tuple[int, int]],
        nx: int,
        nu: int,
        stage_sp: list[dict[str, float]],
        first: int = 0,
        sets: int = 1,
    ) -> None:
        """Each stretch of the test on the plants linearised at the equilibrium holding its set
        points (as the fast method does), switched in at the step, in modal form: ``lam``,
        ``V``, ``Vi``, ``Vi B``, ``Vi c``, ``Cy V``, the outputs' offsets and the feedforwards
        per stage; the stages of parameter set ``m`` are ``m S .. m S + S - 1`` (``first``)."""
        n_loops = len(self.loops)
        S = len(stage_sp)
        if first == 0:
            n = S * sets
            self.ubar = np.zeros((n, n_loops))
            self.lam = np.zeros((n, nx), dtype=complex)
            self.V = np.zeros((n, nx, nx), dtype=complex)
            self.Vi = np.zeros((n, nx, nx), dtype=complex)
            self.ViB = np.zeros((n, nx, nu), dtype=complex)
            self.Vic = np.zeros((n, nx), dtype=complex)
            self.CyV = np.zeros((n, n_loops, nx), dtype=complex)
            self.y0 = np.zeros((n, n_loops))
        for k_stage, values in enumerate(stage_sp):
            k = first + k_stage
            A = np.zeros((nx, nx))
            B = np.zeros((nx, nu))
            c = np.zeros(nx)
            Cy = np.zeros((n_loops, nx))
            for p in plants:
                ox, ou = offsets[p.name]
                n_x, n_u = len(p.x0), len(p.u0)
                key = tuple(values[n] for n in p.loops)
                Ap, Bp, Cp, y0, x_bar, u_bar, f0 = p.linearization(key)
                A[ox : ox + n_x, ox : ox + n_x] = Ap
                B[ox : ox + n_x, ou : ou + n_u] = Bp
                c[ox : ox + n_x] = f0 - Ap @ x_bar - Bp @ u_bar
                row = p.u_bar(key)
                for j, name in enumerate(p.loops):
                    i = self.loops.index(name)
                    Cy[i, ox : ox + n_x] = Cp[p.y_index[name]]
                    self.y0[k, i] = y0[p.y_index[name]]
                    self.ubar[k, i] = row[j]
            lam, V = np.linalg.eig(A)
            if not np.isfinite(lam).all() or np.linalg.cond(V) > 1e8:
                raise ValueError("chance model: the linearised plant is not diagonalisable")
            Vi = np.linalg.inv(V)
            self.lam[k], self.V[k], self.Vi[k] = lam, V, Vi
            self.ViB[k], self.Vic[k], self.CyV[k] = Vi @ B, Vi @ c, Cy @ V

    # -- one evaluation -----------------------------------------------------------------------
    def overshoots(
        self, periods: Mapping[str, float], delays: Mapping[str, float]
    ) -> NDArray[np.float64]:
        """Overshoot (%) of every loop's steps (worst over its steps) in every realization:
        shape ``(R, loops)``; ``inf`` where the linear loop diverged."""
        self.simulations += 1
        R, loops = self.R, self.loops
        h = {n: to_units(to_ticks(periods[n])) for n in loops}
        mu = {n: float(delays.get(n, 0.0)) for n in loops}
        times, kinds, who, index = [], [], [], []

        def add(t: NDArray[np.float64], kind: int, w: int, k: NDArray[np.int64]) -> None:
            times.append(t)
            kinds.append(np.full(t.shape, kind))
            who.append(np.full(t.shape, w))
            index.append(np.broadcast_to(k, t.shape))

        grid = np.arange(0.0, self.end + 1e-12, self.monitor)
        add(np.broadcast_to(grid, (R, len(grid))), _MONITOR, 0, np.zeros(len(grid), np.int64))
        n_samples = {}
        for i, n in enumerate(loops):
            ks = np.arange(int(math.floor(self.end / h[n] + 1e-9)) + 1)
            n_samples[n] = len(ks)
            t_s = np.broadcast_to(ks * h[n], (R, len(ks)))
            add(t_s, _SAMPLE, i, ks)
            d, lost = self.laws[n].draw(
                mu[n], self._u_delay[i].take(len(ks)), self._u_loss[i].take(len(ks))
            )
            d = np.rint(d * TICKS_PER_UNIT) / TICKS_PER_UNIT
            t_d = np.where(lost, np.inf, t_s + d)
            add(t_d, _DELIVER, i, ks)
        step_t = np.zeros((len(self.steps), R))
        for s, (tick, loop, _) in enumerate(self.steps):
            p = to_ticks(h[loop])
            base = (tick // p) * p
            step_t[s] = to_units(base + (self.phase_j[s] * p) // PHASES)
            add(step_t[s][:, None], _STEP, s, np.zeros(1, np.int64))
        T = np.concatenate(times, axis=1)
        K = np.concatenate(kinds, axis=1)
        W = np.concatenate(who, axis=1)
        Ix = np.concatenate(index, axis=1)
        # at one instant: a sample before its zero-delay delivery (the bus delivers it in a
        # later round), the step before the execution, the monitor after the move
        rank = np.array([3, 0, 2, 1, 4])  # by kind: monitor, sample, deliver, step, none
        order_key = rank[K]
        order = np.lexsort((order_key, T), axis=1)
        T = np.take_along_axis(T, order, axis=1)
        K = np.take_along_axis(K, order, axis=1)
        W = np.take_along_axis(W, order, axis=1)
        Ix = np.take_along_axis(Ix, order, axis=1)
        K = np.where(T > self.end + 1e-12, _NONE, K)
        return self._run(T, K, W, Ix, n_samples, step_t)

    def _run(
        self,
        T: NDArray[np.float64],
        K: NDArray[np.int64],
        W: NDArray[np.int64],
        Ix: NDArray[np.int64],
        n_samples: Mapping[str, int],
        step_t: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        R, loops = self.R, self.loops
        rows = np.arange(R)
        stage = self.draw_of * self.n_stages  # each realization's parameter set, first stage
        z0 = np.array([self.Vi[m * self.n_stages] @ self.x0 for m in range(len(self.draws.sets))])
        z = z0[self.draw_of]
        u = np.tile(self.u0, (R, 1))

        w = self._forcing(stage, u)
        t_prev = np.zeros(R)
        r = np.tile(self.initial, (R, 1))
        buf = {n: np.zeros((R, n_samples[n])) for n in loops}
        integral = np.zeros((R, len(loops)))
        e_prev = np.zeros((R, len(loops)))
        t_exec = np.full((R, len(loops)), np.nan)
        ext = np.full((R, len(self.steps)), -np.inf)  # each step's largest excursion
        win = self._windows(step_t)
        for e in range(T.shape[1]):
            kind = K[:, e]
            live = kind != _NONE
            if not live.any():
                break
            t = np.where(live, T[:, e], t_prev)
            tau = (t - t_prev)[:, None]
            if (tau > 0).any():
                lt = self.lam[stage] * tau
                ez = np.exp(lt)
                z = ez * z + tau * phi1(lt, ez) * w
            t_prev = t
            y = None
            mon = kind == _MONITOR
            if mon.any():
                y = self._output(stage, z)
                win.watch(ext, mon, t, y)
            for i, n in enumerate(loops):
                smp = (kind == _SAMPLE) & (W[:, e] == i)
                if smp.any():
                    if y is None:
                        y = self._output(stage, z)
                    buf[n][rows[smp], Ix[smp, e]] = y[smp, i]
                dlv = (kind == _DELIVER) & (W[:, e] == i)
                if dlv.any():
                    u = self._execute(
                        i,
                        n,
                        dlv,
                        t,
                        buf[n][rows, np.where(dlv, Ix[:, e], 0)],
                        r,
                        stage,
                        integral,
                        e_prev,
                        t_exec,
                        u,
                    )
                    w = self._forcing(stage, u)
            stp = kind == _STEP
            if stp.any():
                for s in np.unique(W[stp, e]):
                    m = stp & (W[:, e] == s)
                    r[m, win.loop[s]] = win.to[s]
                    x = np.einsum("rij,rj->ri", self.V[stage[m]], z[m]).real
                    stage[m] += 1
                    z[m] = np.einsum("rij,rj->ri", self.Vi[stage[m]], x.astype(complex))
                w = self._forcing(stage, u)
        out = win.overshoots(ext, len(loops))
        diverged = ~np.isfinite(z).all(axis=1) | (np.abs(z) > 1e12).any(axis=1)
        out[diverged] = np.inf
        return out

    def _forcing(self, stage: NDArray[np.int64], u: NDArray[np.float64]) -> NDArray[np.complex128]:
        """The modal forcing ``Vi (B u + c)`` of each realization's stage under inputs ``u``."""
        forced: NDArray[np.complex128] = (
            np.einsum("rnu,ru->rn", self.ViB[stage], u) + self.Vic[stage]
        )
        return forced

    def _output(self, stage: NDArray[np.int64], z: NDArray[np.complex128]) -> NDArray[np.float64]:
        """The loops' outputs ``Cy V z + y0`` of each realization's modal state ``z``."""
        outputs: NDArray[np.float64] = (
            np.einsum("rln,rn->rl", self.CyV[stage], z).real + self.y0[stage]
        )
        return outputs

    def _windows(self, step_t: NDArray[np.float64]) -> _Windows:
        """Per step: its loop, where it starts from and goes to, and its window's end (the
        loop's next step), per realization."""
        s_loop = [self.loops.index(loop) for _, loop, _ in self.steps]
        s_from, s_to = [], []
        current = dict(zip(self.loops, self.initial, strict=True))
        for _, loop, value in self.steps:
            s_from.append(current[loop])
            s_to.append(value)
            current[loop] = value
        s_end = np.full((len(self.steps), self.R), np.inf)
        for s in range(len(self.steps)):
            later = [q for q in range(s + 1, len(self.steps)) if s_loop[q] == s_loop[s]]
            if later:
                s_end[s] = step_t[later[0]]
        return _Windows(s_loop, np.array(s_from), np.array(s_to), step_t, s_end)

    def _execute(
        self,
        i: int,
        name: str,
        mask: NDArray[np.bool_],
        t: NDArray[np.float64],
        y: NDArray[np.float64],
        r: NDArray[np.float64],
        stage: NDArray[np.int64],
        integral: NDArray[np.float64],
        e_prev: NDArray[np.float64],
        t_exec: NDArray[np.float64],
        u: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """The law of loop ``i`` (:mod:`agents.wncsca.laws`) executes in the masked
        realizations at ``t`` on the delivered ``y``."""
        law = self.control[name]
        e = r[:, i] - y
        first = np.isnan(t_exec[:, i])
        dt = np.where(first, 0.0, t - np.nan_to_num(t_exec[:, i]))
        incr = law.increment(e, e_prev[:, i], dt)
        start = integral[:, i]
        if (first & mask).any():
            start = np.where(first, law.start(y, start), start)
        ubar = self.ubar[stage, i]
        out, new_int = law.update(e, y, incr, start, ubar)
        integral[:, i] = np.where(mask, new_int, integral[:, i])
        e_prev[:, i] = np.where(mask, e, e_prev[:, i])
        t_exec[:, i] = np.where(mask, t, t_exec[:, i])
        u = u.copy()
        col = self.u_col[name]
        u[:, col] = np.where(mask, out, u[:, col])
        return u

    def params_of(self, r: int) -> dict[str, dict[str, float]]:
        """The parameters realization ``r`` replaces in the model (empty: the model's own)."""
        drawn = self.draws.sets[int(self.draw_of[r])]
        return {p: dict(v) for p, v in drawn.items()}

    def traces(
        self, periods: Mapping[str, float], delays: Mapping[str, float], r: int
    ) -> tuple[dict[str, list[float | None]], dict[tuple[int, str], int]]:
        """Realization ``r``'s delay sequence per loop (``None``: lost; time units) and each
        step's phase numerator (``j`` of ``j / PHASES``), to replay it on the non-linear
        model."""
        out: dict[str, list[float | None]] = {}
        for i, n in enumerate(self.loops):
            h = to_units(to_ticks(periods[n]))
            count = int(math.floor(self.end / h + 1e-9)) + 1
            out[n] = self.laws[n].trace(
                float(delays.get(n, 0.0)),
                self._u_delay[i].take(count)[r],
                self._u_loss[i].take(count)[r],
            )
        phases = {
            (tick, loop): int(self.phase_j[s, r]) for s, (tick, loop, _) in enumerate(self.steps)
        }
        return out, phases


@dataclass
class ChanceModel:
    """The agent's model judged by risk: :meth:`evaluate` answers the question of
    :meth:`agents.wncsca.model.LoopModel.evaluate` with each loop's risk overshoot (the module
    docstring), so the paper's searches run on it unchanged.

    Parameters
    ----------
    base : LoopModel
        The agent's deterministic model (its non-linear trials check the linear predictions).
    laws : mapping
        Loop -> :class:`LoopLaw` of the proposal's control paths.
    """

    base: LoopModel
    laws: Mapping[str, LoopLaw]
    seed: int = 0
    offsets: dict[str, float] = field(default_factory=dict)
    period_caps: dict[str, float] = field(default_factory=dict)
    _memo: dict[tuple[Any, ...], NDArray[np.float64]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        cfg = self.base.config
        self.config = cfg
        self.loops = self.base.loops
        self.benchmark = dict(self.base.benchmark)
        self.draws = model_draws(self.base.trials.spec, cfg, self.seed)
        self.linear = LinearMonteCarlo(
            self.base, self.laws, cfg.realizations, self.seed, self.draws
        )
        self.k_max = risk_index(cfg.realizations, cfg.confidence)  # per block of realizations
        self.offsets = {n: self.offsets.get(n, 0.0) for n in self.loops}
        laws = {
            n: [list(law.probabilities), list(law.delays), law.loss]
            for n, law in sorted(self.laws.items())
        }
        what: list[Any] = [self.base.fingerprint, laws, cfg.realizations, cfg.confidence, self.seed]
        if not self.draws.exact:
            what.append(self.draws.summary())
        self.fingerprint = hashlib.sha256(json.dumps(what).encode()).hexdigest()[:16]

    @property
    def simulations(self) -> int:
        return self.linear.simulations + self.base.simulations

    def samples(
        self, periods: Mapping[str, float], delays: Mapping[str, float]
    ) -> NDArray[np.float64]:
        """Linear overshoots ``(R, loops)``, corrected by the offsets."""
        per = {n: float(periods.get(n, self.benchmark[n])) for n in self.loops}
        dly = {n: float(delays.get(n, 0.0)) for n in self.loops}
        key = (
            tuple(to_ticks(per[n]) for n in self.loops),
            tuple(to_ticks(dly[n]) for n in self.loops),
        )
        raw = self._memo.get(key)
        if raw is None:
            raw = self._memo[key] = self.linear.overshoots(per, dly)
        corrected: NDArray[np.float64] = raw + np.array([self.offsets[n] for n in self.loops])
        return corrected

    def evaluate(self, periods: Mapping[str, float], delays: Mapping[str, float]) -> Evaluation:
        """Risk overshoot of every loop: the ``(R - k_max)``-th smallest realization (``inf``
        for a loop whose period exceeds its cap in :attr:`period_caps`: the jitter margin)."""
        per = {n: float(periods.get(n, self.benchmark[n])) for n in self.loops}
        dly = {n: float(delays.get(n, 0.0)) for n in self.loops}
        risk = self._risk(self.samples(per, dly))[0]
        for n, cap in self.period_caps.items():
            if per[n] > cap:
                risk[n] = math.inf  # outside the jitter margin: no guarantee of stability
        return Evaluation(per, dly, risk, ())

    def _risk(self, samples: NDArray[np.float64]) -> tuple[dict[str, float], dict[str, int]]:
        """Each loop's risk overshoot, the ``(R - k_max)``-th smallest realization of its
        block, at the worst block (one block but for a robust model: one per corner), and the
        block it is at."""
        risk: dict[str, float] = {}
        worst: dict[str, int] = {}
        for b, rows in enumerate(self.linear.blocks):
            os = np.sort(samples[rows], axis=0)
            for i, n in enumerate(self.loops):
                v = float(os[len(os) - 1 - self.k_max, i])
                if n not in risk or v > risk[n]:
                    risk[n], worst[n] = v, b
        return risk, worst

    def probability(
        self, periods: Mapping[str, float], delays: Mapping[str, float]
    ) -> dict[str, dict[str, float]]:
        """Per loop: the estimated ``P(overshoot <= limit)`` and its 95 % interval (robust: at
        the worst corner)."""
        samples = self.samples(periods, delays)
        limit = self.config.overshoot_limit
        out: dict[str, dict[str, float]] = {}
        for rows in self.linear.blocks:
            os = samples[rows]
            for i, n in enumerate(self.loops):
                within = int(np.sum(os[:, i] <= limit))
                if n in out and within / len(os) >= out[n]["p"]:
                    continue
                lo, hi = probability_interval(within, len(os))
                out[n] = {"p": within / len(os), "low": lo, "high": hi}
        return out

    def check(self, periods: Mapping[str, float], delays: Mapping[str, float]) -> dict[str, Any]:
        """Replay realizations on the non-linear model where the guarantee is decided, and
        correct the linear overshoots by what they differ there.

        For each loop, the ``checks / loops`` realizations whose linear overshoot ranks nearest
        the risk order statistic are replayed (:meth:`ChanceModel.evaluate`); the loop's offset
        is the mean paired difference, non-linear minus linear, over its own selection (``inf``
        when a replay diverged). The linear model's error depends on the step phase and the
        delays, so it is measured in the tail that sets the risk, not on average."""
        per = {n: float(periods.get(n, self.benchmark[n])) for n in self.loops}
        dly = {n: float(delays.get(n, 0.0)) for n in self.loops}
        linear = self.samples(per, dly) - np.array([self.offsets[n] for n in self.loops])
        _, worst = self._risk(linear)
        per_loop = max(1, self.config.checks // len(self.loops))
        chosen = {}
        for i, n in enumerate(self.loops):
            block = self.linear.blocks[worst[n]]  # the corner that sets the risk (robust)
            R = block.stop - block.start
            rank = R - 1 - self.k_max
            lo = max(0, min(rank - per_loop // 2, R - per_loop))
            order = np.argsort(linear[block, i], kind="stable")
            chosen[n] = block.start + order[lo : lo + per_loop]
        replays = sorted({int(r) for rows in chosen.values() for r in rows})
        nonlinear: dict[int, list[float]] = {}
        for r in replays:
            traces, phases = self.linear.traces(per, dly, r)
            params = self.linear.params_of(r) or None
            rec = self.base.trials.run_replay(per, dly, traces, phases, PHASES, params)
            nonlinear[r] = self.base.overshoots_of(rec)
            self.base.simulations += 1
        for i, n in enumerate(self.loops):
            nl = np.array([nonlinear[int(r)][i] for r in chosen[n]])
            li = linear[chosen[n], i]
            if not np.isfinite(nl).all():
                self.offsets[n] = math.inf
            elif not np.isfinite(li).all():
                self.offsets[n] = 0.0
            else:
                self.offsets[n] = float(np.mean(nl - li))
        return {
            "checks": len(replays),
            "offsets": dict(self.offsets),
            "nonlinear_overshoot_pct": {
                n: [float(nonlinear[int(r)][i]) for r in chosen[n]]
                for i, n in enumerate(self.loops)
            },
            "linear_overshoot_pct": {
                n: [float(linear[int(r), i]) for r in chosen[n]] for i, n in enumerate(self.loops)
            },
        }
