"""The agent's non-linear check, many trials at once (issue 20, item 5).

:meth:`agents.wncsca.model.LoopModel.evaluate` runs one trial (one period vector, one step phase)
on the ``direct`` engine: every node, message and round of the agent's model. The fast method
checks many candidate period vectors; :class:`BatchTrials` simulates them together, with the state
of every trial in numpy arrays, and gives the same overshoots.

What is simulated
-----------------
A trial of :class:`agents.wncsca.trials.Trials`: each judged loop's plant, its PI
controller (:class:`controllers.pi.PI`: feedforward, forward or backward integral over the time
between executions, clamping anti-windup, output limits) and a wired sensor path of constant
delay ``tau_d``; the sensor is sampled at ``0, h, 2h, ...``; the sample taken at ``k h`` is
used at ``k h + tau_d`` with the set points in force then (a step at that instant included), and
the move holds from that instant (``tau_a = 0``); the test's steps are moved to their phase as
:meth:`Trials.run` does. Plants are independent in the model (every loop's
plant is its own node), so a trial is one plant's loops: a check of a period vector is one trial
per plant and phase, and a plant's trials are memoised by its loops' periods.

Each plant is integrated as the plant node does (:mod:`plants.behaviour`): from stop to stop,
the stops being its monitoring grid, its sensors' sampling instants and the instants its inputs
change, each segment by :func:`plants.integrate.rk4_tuple`'s classical RK4 on ``ceil(span /
max_step)`` equal steps. The batch does the same arithmetic on arrays (the plant's
``rhs_batch``, element by element the operations of its ``rhs_tuple``), so the states, and the
overshoots measured from the monitoring grid as :func:`core.record.loop_metrics` does, equal
the engine's (``tests/unit/test_wncsca_batch.py`` compares them).

Vectorisation
-------------
The trials of one plant model (every plant of that class in the model, every candidate period
vector, every step phase) are the items of one batch. Every item has its own sorted list of
stops (the union above, different per item since its periods and phases differ); the batch
advances all items one stop per iteration (an item that has run out of stops repeats its last,
a segment of zero span). Everything that does not depend on the state is computed for all
``(stop, item)`` pairs before the loop: segment steps (as states x items arrays), and each
execution's sample, set point, feedforward, law and time since the item's previous execution.
The loop does, per stop, the PI law on every execution there (all loops at once: an item's
loops have their own integral and actuator), then the RK4 steps of the segment on one
states x items array; the inputs' terms of the plant's right-hand side are computed once per
segment when the plant offers them (``rhs_batch_inputs``/``rhs_batch_held``: the same
operations, only not repeated). The cost is the number of stops (about 900-1000 for an 8 pu
test on a 0.01 pu monitoring grid, whatever the number of items) times the numpy calls per stop
(two RK4 steps of about 70 calls each for the JCSTR, the PI law's 25-30): about 0.055 s for the
8-24 trials of a JCSTR check, 0.026 s for 4 tank trials, 0.1 s for 256 JCSTR trials
(``bench/wncsca_scale.py``; 0.07-0.1 s for 8-20 before issue 20's tuning).

A plant model takes part only if it offers ``batch_params``, ``rhs_batch`` and
``outputs_batch`` (:class:`plants.jcstr.JCSTR`, :class:`plants.tank.Tank`), its loops are PI loops
on sensors that are states, and it has no measurement noise; otherwise :attr:`BatchTrials.reason`
says why and the fast method checks on the engine.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from agents.wncsca.model import LoopModel
from controllers.pi import PIConfig, pi_update
from core.time import TICKS_PER_UNIT, to_ticks

__all__ = ["BatchTrials"]


class _Batched(Protocol):
    """The class of a plant model that takes part (:class:`plants.jcstr.JCSTR`,
    :class:`plants.tank.Tank`): its right-hand side and outputs on many plants at once, one array
    per constant, state and input (the batch hands states x items arrays, read row by row)."""

    rhs_batch: Callable[..., tuple[NDArray[np.float64], ...]]
    outputs_batch: Callable[..., tuple[NDArray[np.float64], ...]]


@dataclass(frozen=True)
class _Plant:
    """One plant of the model and its loops (sorted by name), as the batch needs them."""

    name: str
    kind: type[_Batched]
    params: tuple[float, ...]
    x0: tuple[float, ...]
    u0: tuple[float, ...]
    max_step: float
    monitor: int
    loops: tuple[str, ...]
    out_idx: tuple[int, ...]  # sampled output of each loop
    state_idx: tuple[int, ...]  # the same signal among the states (the record's)
    act_idx: tuple[int, ...]
    laws: tuple[PIConfig, ...]
    feedforward: tuple[Any, ...]  # per loop, None without
    initial: tuple[float, ...]
    steps: tuple[tuple[int, int, float], ...]  # (tick, loop slot, value) in the test's order

    def structure(self) -> tuple[Any, ...]:
        """Plants with the same structure share a batch."""
        return (
            self.kind,
            self.out_idx,
            self.state_idx,
            self.act_idx,
            self.monitor,
            self.max_step,
            tuple(s[:2] for s in self.steps),
        )


@dataclass(frozen=True)
class _Executions:
    """Every loop's executions in a batch, sorted by stop (those at stop ``j`` are
    ``bounds[j]:bounds[j + 1]``), with everything about them that does not depend on the state;
    the loops of an item are independent there (own integral, own actuator), so the executions
    of a stop run as one vector whatever their loop."""

    bounds: list[int]
    item: NDArray[np.int64]  # the executing item
    state: NDArray[np.int64]  # its PI state: slot * items + item
    act: NDArray[np.int64]  # its actuator in the flattened inputs: input * items + item
    out: NDArray[np.int64] | int  # the output it uses (one int when every loop uses the same)
    src: NDArray[np.int64]  # the stop of the sample it uses
    values: NDArray[np.float64]  # rows: set point, feedforward, Kp, Ki, u_min, u_max, dt
    started: NDArray[np.bool_]  # whether the item executed before (else no integration)
    all_started: list[bool]  # per stop: whether every execution there has a previous one
    forward: NDArray[np.bool_]  # forward integral, per execution
    integral_form: str  # "forward" (every execution), "backward" (every one) or "mixed"


@dataclass(frozen=True)
class _Grid:
    """One batch's stops and what executions are placed from (:meth:`BatchSimulator._simulate`):
    per stop ``j`` and item ``i`` (``S[j, i]`` ticks, ``T`` the same in time units, ``valid``
    inside the item's run), each item's delays ``D`` and periods ``H`` (items x loops), the set
    points ``sp`` and feedforwards ``ubar`` per stretch, the stretch in force at each stop
    (``stretch``), and every column of ``S`` sorted and offset into one sorted array (``flat``)."""

    first: _Plant
    plants: list[_Plant]
    S: NDArray[np.int64]
    T: NDArray[np.float64]
    D: NDArray[np.int64]
    H: NDArray[np.int64]
    valid: NDArray[np.bool_]
    end: int
    sp: NDArray[np.float64]
    ubar: NDArray[np.float64]
    stretch: NDArray[np.int64]
    flat: NDArray[np.int64]


def _slot_executions(g: _Grid, slot: int) -> list[NDArray[Any]]:
    """Loop ``slot``'s executions by item, then stop: its columns of :class:`_Executions`
    (stop, slot, item, sample's stop, actuator, output, values, started, forward)."""
    first, S, T, valid, end, plants = g.first, g.S, g.T, g.valid, g.end, g.plants
    sp, ubar, stretch, flat = g.sp, g.ubar, g.stretch, g.flat
    L, B = S.shape
    ar = np.arange(B)
    d, h = g.D[None, :, slot], g.H[None, :, slot]
    execs = valid & (S >= d) & ((S - d) % h == 0)
    src = np.searchsorted(flat, (S - d + (ar * (end + 1))[None, :]).T.ravel())
    src = src.reshape(B, L).T - (ar * L)[None, :]
    item, stop = np.nonzero(execs.T)  # by item, then stop
    t = T[stop, item]
    started = np.zeros(len(item), dtype=bool)
    started[1:] = item[1:] == item[:-1]
    t_prev = np.zeros(len(item))
    t_prev[1:] = t[:-1]
    dt = t - np.where(started, t_prev, 0.0)
    laws = [p.laws[slot] for p in plants]
    law = np.array([[lw.Kp, lw.Ki, lw.u_min, lw.u_max] for lw in laws]).T[:, item]
    k = stretch[stop, item]
    values = np.vstack([sp[item, k, slot], ubar[item, k, slot], law, dt])
    fwd = np.array([lw.integration == "forward" for lw in laws])[item]
    n = len(item)
    return [
        stop,
        np.full(n, slot),
        item,
        src[stop, item],
        np.full(n, first.act_idx[slot]),
        np.full(n, first.out_idx[slot]),
        values.T,
        started,
        fwd,
    ]


def _executions(g: _Grid) -> _Executions:
    """The loops' executions in the stops ``S`` (stops x items): at stop ``j`` item ``i``
    executes loop ``l`` when ``S - tau_d`` is a sampling instant, on the sample of the stop at
    ``S - tau_d``, with the set point and feedforward of the stretch in force; ``dt`` is the
    time since its previous execution (``t - t_prev`` as :class:`controllers.pi.PI` takes
    it)."""
    first = g.first
    L, B = g.S.shape
    parts = [_slot_executions(g, slot) for slot in range(len(first.loops))]
    stop, slot_, item, src, act, out, values, started, fwd = (
        np.concatenate(col) for col in zip(*parts, strict=True)
    )
    order = np.lexsort((item, slot_, stop))  # by stop, then loop, then item
    stop, slot_, item, src = stop[order], slot_[order], item[order], src[order]
    act, out, values, started, fwd = (
        act[order],
        out[order],
        values[order],
        started[order],
        fwd[order],
    )
    form = "forward" if fwd.all() else ("backward" if not fwd.any() else "mixed")
    outs = set(first.out_idx)
    bounds = np.concatenate([[0], np.cumsum(np.bincount(stop, minlength=L))]).tolist()
    fresh = np.bincount(stop, weights=~started, minlength=L)  # first executions per stop
    return _Executions(
        bounds=bounds,
        item=item,
        state=slot_ * B + item,
        act=act * B + item,
        out=outs.pop() if len(outs) == 1 else out,
        src=src,
        values=np.ascontiguousarray(values.T),
        started=started,
        all_started=(fresh == 0).tolist(),
        forward=fwd,
        integral_form=form,
    )


class _Substeps:
    """The RK4 steps of each segment ``[S[j], S[j + 1]]`` (rk4_tuple's arithmetic): per substep
    and stop, as states x items (a broadcast per numpy call costs more than the arithmetic on a
    few items)."""

    def __init__(self, T: NDArray[np.float64], first: _Plant) -> None:
        self.span = span = T[1:] - T[:-1]
        n_sub = np.maximum(1, np.ceil(span / first.max_step - 1e-9)).astype(np.int64)
        n_sub = np.where(span > 0.0, n_sub, 0)
        h_seg = np.where(n_sub > 0, span / np.maximum(n_sub, 1), 0.0)
        n_max = int(n_sub.max(initial=0))
        n_x = len(first.x0)
        self.h = [
            np.repeat(np.where(n_sub > q, h_seg, 0.0)[:, None, :], n_x, axis=1)
            for q in range(n_max)
        ]
        self.half = [0.5 * v for v in self.h]
        self.sixth = [v / 6.0 for v in self.h]
        self.count: list[int] = (
            n_sub.max(axis=1) if n_max else np.zeros(len(T) - 1, dtype=np.int64)
        ).tolist()


def _integrate(
    first: _Plant, plants: list[_Plant], ex: _Executions, rk4: _Substeps
) -> NDArray[np.float64]:
    """The state of every item at every stop (stops x states x items): the loops' PI
    executions (:func:`controllers.pi.pi_update`) at their stops, and rk4_tuple's arithmetic
    element by element between them."""
    B, n_loops = len(plants), len(first.loops)
    L = len(rk4.count) + 1  # stops
    integral = np.zeros(n_loops * B)  # PI state, slot * items + item
    e_prev = np.zeros(n_loops * B)
    params = tuple(np.array(col) for col in zip(*(p.params for p in plants), strict=True))
    X = np.array([p.x0 for p in plants], dtype=float).T.copy()
    U = np.array([p.u0 for p in plants]).T.copy()  # inputs x items
    U_flat = U.reshape(-1)  # a view: input * items + item
    f = first.kind.rhs_batch
    # the terms of the plant's rhs that the inputs fix, once per segment, when it offers them
    held = getattr(first.kind, "rhs_batch_inputs", None)
    f_held = getattr(first.kind, "rhs_batch_held", None)
    outputs = first.kind.outputs_batch
    XS = np.zeros((L, len(X), B))
    with np.errstate(all="ignore"):
        for j in range(L):
            XS[j] = X
            a, b = ex.bounds[j], ex.bounds[j + 1]
            if a != b:  # the executions at this stop, every loop's at once
                pi_at = ex.state[a:b]
                r, ub, kp, ki, lo, hi, dt = ex.values[:, a:b]
                y_all = outputs(XS[ex.src[a:b], :, ex.item[a:b]].T)  # the samples used
                if isinstance(ex.out, int):
                    y = y_all[ex.out]
                else:
                    y = np.array(y_all)[ex.out[a:b], np.arange(b - a)]
                e = r - y
                if ex.integral_form == "backward":
                    err_i = e
                elif ex.integral_form == "forward":
                    err_i = e_prev[pi_at]
                else:
                    err_i = np.where(ex.forward[a:b], e_prev[pi_at], e)
                incr = ki * err_i * dt
                if not ex.all_started[j]:
                    incr = np.where(ex.started[a:b], incr, 0.0)
                U_flat[ex.act[a:b]], integral[pi_at] = pi_update(
                    e, incr, integral[pi_at], ub, kp, lo, hi
                )
                e_prev[pi_at] = e
            if j == L - 1:
                break
            if not rk4.count[j]:
                continue
            u = tuple(U)
            g, arg = f, u
            if held is not None and f_held is not None:
                g, arg = f_held, held(params, u, X, rk4.span[j])
            for q in range(rk4.count[j]):
                hh, half, sixth = rk4.h[q][j], rk4.half[q][j], rk4.sixth[q][j]
                k1 = np.array(g(params, X, arg))
                k2 = np.array(g(params, X + half * k1, arg))
                k3 = np.array(g(params, X + half * k2, arg))
                k4 = np.array(g(params, X + hh * k3, arg))
                X = X + sixth * (k1 + (k2 + k2) + (k3 + k3) + k4)  # 2 k = k + k
    return XS


class BatchTrials:
    """The agent's trials of ``model``, simulated many at once (module docstring).

    Parameters
    ----------
    model : LoopModel
        The agent's model: its closed-loop spec, test and phase handling.
    """

    def __init__(self, model: LoopModel) -> None:
        cfg = model.config
        spec = model.trials.spec
        self.loops: tuple[str, ...] = tuple(model.loops)
        self.index = {n: k for k, n in enumerate(self.loops)}
        self.end = to_ticks(spec.end_time)
        self.n_phases = 1 if cfg.phase == "fixed" else cfg.phases
        self.shift = cfg.phase == "worst"
        self.items = 0
        self.batches = 0
        self.reason = ""
        self._memo: dict[tuple[str, tuple[int, ...], tuple[int, ...]], tuple[float, ...]] = {}
        self.plants: dict[str, _Plant] = {}
        by_plant: dict[str, list[str]] = {}
        for n in self.loops:
            by_plant.setdefault(spec.loops[n].plant, []).append(n)
        for pname, names in sorted(by_plant.items()):
            plant = spec.plants[pname]
            pm = plant.model
            missing = [
                a for a in ("batch_params", "rhs_batch", "outputs_batch") if not hasattr(pm, a)
            ]
            if missing:
                self.reason = f"plant {pname!r} ({type(pm).__name__}) has no {missing[0]}"
                return
            if any(v > 0 for v in plant.noise.values()):
                self.reason = f"plant {pname!r} has measurement noise"
                return
            names = sorted(names)
            laws = []
            for n in names:
                law = spec.loops[n].law
                if not isinstance(law, PIConfig):
                    self.reason = f"loop {n!r} uses control law {law.type!r}, not 'pi'"
                    return
                laws.append(law)
            sensors = [spec.loops[n].sensor for n in names]
            if any(s not in pm.state_names for s in sensors):
                self.reason = f"plant {pname!r}: a sensor is not a state"
                return
            steps = tuple(
                (to_ticks(s.t), names.index(s.loop), float(s.value))
                for s in spec.steps
                if s.loop in names
            )
            self.plants[pname] = _Plant(
                name=pname,
                kind=type(pm),
                params=tuple(float(v) for v in pm.batch_params()),
                x0=tuple(float(plant.x0[s]) for s in pm.state_names),
                u0=tuple(float(plant.u0[s]) for s in pm.input_names),
                max_step=float(plant.max_step),
                monitor=to_ticks(plant.monitor_period),
                loops=tuple(names),
                out_idx=tuple(pm.output_names.index(s) for s in sensors),
                state_idx=tuple(pm.state_names.index(s) for s in sensors),
                act_idx=tuple(pm.input_names.index(spec.loops[n].actuator) for n in names),
                laws=tuple(laws),
                feedforward=tuple(spec.loops[n].feedforward for n in names),
                initial=tuple(float(spec.loops[n].setpoint) for n in names),
                steps=steps,
            )

    @property
    def available(self) -> bool:
        """Whether every plant of the model can be batched (else :attr:`reason` says why)."""
        return not self.reason

    def overshoots(
        self,
        periods: NDArray[np.float64],
        delays: Mapping[str, float],
        ahead: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """Worst-case overshoot (%) of every loop (columns in :attr:`loops` order; ``inf``:
        diverged or no step) for each row of ``periods`` (rows x loops, time units), under the
        control-path ``delays``: what :meth:`LoopModel.evaluate` gives, row by row.

        ``ahead``: rows likely asked for next; a plant that is simulated for ``periods`` anyway
        simulates them too, in the same batch (a few more items cost little there), and
        memoises them; no plant is simulated for them alone."""
        if not self.available:
            raise ValueError(f"batched trials unavailable: {self.reason}")
        rows = np.atleast_2d(np.asarray(periods, dtype=float))
        ticks = np.rint(rows * TICKS_PER_UNIT).astype(np.int64)
        if (ticks < 1).any():
            raise ValueError("batched trials: a period is shorter than one tick")
        dticks = {n: to_ticks(float(delays.get(n, 0.0))) for n in self.loops}
        todo: dict[tuple[Any, ...], list[tuple[_Plant, tuple[int, ...]]]] = {}
        keys = []
        extra = (
            np.rint(np.atleast_2d(ahead) * TICKS_PER_UNIT).astype(np.int64)
            if ahead is not None and len(ahead)
            else np.zeros((0, len(self.loops)), dtype=np.int64)
        )
        for plant in self.plants.values():
            cols = [self.index[n] for n in plant.loops]
            d = tuple(dticks[n] for n in plant.loops)
            missed = False
            for r in ticks:
                h = tuple(int(v) for v in r[cols])
                key = (plant.name, h, d)
                keys.append(key)
                if key not in self._memo:
                    missed = True
                    group = todo.setdefault(plant.structure(), [])
                    if (plant, h) not in group:
                        group.append((plant, h))
            for r in extra if missed else ():
                h = tuple(int(v) for v in r[cols])
                if min(h) >= 1 and (plant.name, h, d) not in self._memo:
                    group = todo[plant.structure()]
                    if (plant, h) not in group:
                        group.append((plant, h))
        for group in todo.values():
            os_items = self._simulate(group, dticks)
            for (plant, h), worst in zip(group, os_items, strict=True):
                self._memo[(plant.name, h, tuple(dticks[n] for n in plant.loops))] = worst
        out = np.zeros((len(rows), len(self.loops)))
        k = 0
        for plant in self.plants.values():
            cols = [self.index[n] for n in plant.loops]
            for r in range(len(rows)):
                out[r, cols] = self._memo[keys[k]]
                k += 1
        return out

    # -- one batch ---------------------------------------------------------------------------
    def _simulate(
        self, group: list[tuple[_Plant, tuple[int, ...]]], dticks: Mapping[str, int]
    ) -> list[tuple[float, ...]]:
        """Worst-case overshoot of each loop of each ``(plant, periods)`` of ``group`` (plants of
        one structure), over the step phases."""
        n_ph = self.n_phases
        first = group[0][0]
        plants = [p for p, _ in group for _ in range(n_ph)]
        B = len(plants)
        self.items += B
        self.batches += 1
        ar = np.arange(B)
        end = self.end
        H = np.repeat(np.array([h for _, h in group], dtype=np.int64), n_ph, axis=0)
        D = np.array([[dticks[n] for n in p.loops] for p in plants], dtype=np.int64)
        t_step, t_sorted, sp, values, slots = self._placed_steps(len(group), plants, H)
        ubar = self._feedforward(plants, sp)
        S, valid = self._stops(first, H, D)
        T = S / TICKS_PER_UNIT  # as the engine converts: to_units(ticks)
        rk4 = _Substeps(T, first)
        # -- executions: at stop j of item i, loop slot l uses the sample taken at stop src
        flat = (S + (ar * (end + 1))[None, :]).T.ravel()  # every column sorted, then offset
        stretch = np.sum(t_sorted[None, :, :] <= S[:, :, None], axis=2)  # steps at or before
        # the executions of each loop, everything about them that is not state gathered here
        ex = _executions(_Grid(first, plants, S, T, D, H, valid, end, sp, ubar, stretch, flat))
        XS = _integrate(first, plants, ex, rk4)
        return self._overshoots(group, XS, S, valid, t_step, t_sorted, sp, values, slots)

    def _placed_steps(
        self, n_group: int, plants: list[_Plant], H: NDArray[np.int64]
    ) -> tuple[NDArray[Any], ...]:
        """Per item: the steps moved to the phase, sorted, and the set points per stretch;
        ``(t_step, t_sorted, sp, values, slots)``."""
        n_ph, first, B = self.n_phases, plants[0], len(plants)
        ar = np.arange(B)
        n_loops = len(first.loops)
        phase = np.tile(np.arange(n_ph, dtype=np.int64), n_group)
        n_steps = len(first.steps)
        slots = np.array([st[1] for st in first.steps], dtype=np.int64)
        t_test = np.array([st[0] for st in first.steps], dtype=np.int64)
        values = np.array([[st[2] for st in p.steps] for p in plants]).reshape(B, n_steps)
        if self.shift:
            P = H[:, slots]
            t_step = (t_test[None, :] // P) * P + (phase[:, None] * P) // n_ph
        else:
            t_step = np.repeat(t_test[None, :], B, axis=0)
        order = np.argsort(t_step, axis=1, kind="stable")
        t_sorted = np.take_along_axis(t_step, order, axis=1)
        sp = np.zeros((B, n_steps + 1, n_loops))
        sp[:, 0] = [p.initial for p in plants]
        for st in range(n_steps):
            sp[:, st + 1] = sp[:, st]
            sp[ar, st + 1, slots[order[:, st]]] = values[ar, order[:, st]]
        return t_step, t_sorted, sp, values, slots

    def _stops(
        self, first: _Plant, H: NDArray[np.int64], D: NDArray[np.int64]
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Per item the sorted stops (monitoring grid, samples, executions), padded with the
        end: ``(S, valid)``, stops x items."""
        end, B = self.end, len(H)
        parts = [np.repeat(np.arange(0, end + 1, first.monitor)[None, :], B, axis=0)]
        parts.append(np.full((B, 1), end, dtype=np.int64))
        for slot in range(len(first.loops)):
            k = np.arange(int(end // H[:, slot].min()) + 1, dtype=np.int64)[None, :]
            times = k * H[:, slot, None]
            parts.append(np.where(times <= end, times, end))
            times = times + D[:, slot, None]
            parts.append(np.where(times <= end, times, end))
        cand = np.sort(np.concatenate(parts, axis=1), axis=1)
        dup = np.zeros(cand.shape, dtype=bool)
        dup[:, 1:] = cand[:, 1:] == cand[:, :-1]
        cand = np.take_along_axis(cand, np.argsort(dup, axis=1, kind="stable"), axis=1)
        counts = np.sum(~dup, axis=1)
        L = int(counts.max())
        valid = np.arange(L)[:, None] < counts[None, :]
        return np.where(valid, cand[:, :L].T, end), valid

    def _feedforward(self, plants: list[_Plant], sp: NDArray[np.float64]) -> NDArray[np.float64]:
        """Each loop's feedforward per item and stretch (0 for a loop without one)."""
        B, n_stretch, n_loops = sp.shape
        names = {p.name: k for k, p in enumerate(dict.fromkeys(plants))}
        owner = np.repeat(np.array([names[p.name] for p in plants], dtype=float), n_stretch)
        keys, inverse = np.unique(
            np.column_stack([owner, sp.reshape(-1, n_loops)]), axis=0, return_inverse=True
        )
        by_name = {p.name: p for p in plants}
        order = list(names)
        rows = []
        for key in keys:
            plant = by_name[order[int(key[0])]]
            setpoints = dict(zip(plant.loops, map(float, key[1:]), strict=True))
            rows.append(
                [0.0 if ff is None else float(ff.u_bar(setpoints)) for ff in plant.feedforward]
            )
        return np.array(rows)[inverse.reshape(-1)].reshape(B, n_stretch, n_loops)

    def _overshoots(
        self,
        group: list[tuple[_Plant, tuple[int, ...]]],
        XS: NDArray[np.float64],
        S: NDArray[np.int64],
        valid: NDArray[np.bool_],
        t_step: NDArray[np.int64],
        t_sorted: NDArray[np.int64],
        sp: NDArray[np.float64],
        values: NDArray[np.float64],
        slots: NDArray[np.int64],
    ) -> list[tuple[float, ...]]:
        """Each loop's overshoot of its steps on the monitoring grid, as
        :func:`core.record.loop_metrics` measures it, worst over the phases (``inf``: the
        plant's recorded state is not finite, or the loop has no step)."""
        first = group[0][0]
        n_loops, end = len(first.loops), self.end
        B = S.shape[1]
        ar = np.arange(B)
        on_grid = valid & (S % first.monitor == 0)
        finite = np.all(np.isfinite(XS) | ~on_grid[:, None, :], axis=(0, 1))
        worst = np.zeros((n_loops, B))
        has_step = np.zeros((n_loops, B), dtype=bool)
        for slot in range(n_loops):
            y = XS[:, first.state_idx[slot], :]
            mine = [k for k in range(len(slots)) if slots[k] == slot]
            for k in mine:
                t0 = t_step[:, k]
                t1 = np.full(B, end)
                for o in mine:  # the window ends at the loop's next step
                    t1 = np.where(t_step[:, o] > t0, np.minimum(t1, t_step[:, o]), t1)
                r_from = sp[ar, np.sum(t_sorted < t0[:, None], axis=1), slot]
                size = values[:, k] - r_from
                sign = np.where(size > 0, 1.0, -1.0)
                inside = on_grid & (S >= t0[None, :]) & (S <= t1[None, :])
                with np.errstate(invalid="ignore", divide="ignore"):
                    dev = np.where(inside, sign[None, :] * (y - values[None, :, k]), -np.inf)
                    peak = dev.max(axis=0)
                    os_pct = np.where(peak > 0.0, peak, 0.0) / np.abs(size) * 100.0
                stepped = size != 0.0
                worst[slot] = np.where(stepped, np.maximum(worst[slot], os_pct), worst[slot])
                has_step[slot] |= stepped
        worst = np.where(has_step & finite[None, :] & np.isfinite(worst), worst, math.inf)
        per_item = worst.T.reshape(len(group), self.n_phases, n_loops).max(axis=1)
        return [tuple(float(v) for v in row) for row in per_item]
