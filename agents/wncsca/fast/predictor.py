"""The fast method's predictor: the test's worst-case overshoots on the linearised, exactly
discretised loops, for batches of candidate periods (:mod:`agents.wncsca.fast`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from agents.wncsca.fast.lti import PADE_ORDER, Modal, Models, distinct_ticks, pade
from agents.wncsca.laws import Law, modelled_law
from agents.wncsca.model import LoopModel
from core.time import TICKS_PER_UNIT, to_ticks
from plants.linearization import equilibrium, jacobians


@dataclass
class PlantData:
    name: str
    model: Any
    x0: NDArray[np.float64]
    u0: NDArray[np.float64]
    loops: tuple[str, ...]  # the loops of this plant, sorted
    y_index: dict[str, int]
    u_index: dict[str, int]
    feedforward: dict[str, Any]  # loop -> SteadyStateFeedforward or None
    monitor: float
    _ubar: dict[tuple[float, ...], NDArray[np.float64]] = field(default_factory=dict)
    _lin: dict[tuple[float, ...], tuple[NDArray[np.float64], ...]] = field(default_factory=dict)

    def u_bar(self, setpoints: tuple[float, ...]) -> NDArray[np.float64]:
        """Feedforward of each loop of the plant (0 without one) at these set points."""
        hit = self._ubar.get(setpoints)
        if hit is None:
            sp = dict(zip(self.loops, setpoints, strict=True))
            hit = np.array(
                [
                    0.0 if ff is None else ff.u_bar(sp)
                    for ff in map(self.feedforward.get, self.loops)
                ]
            )
            self._ubar[setpoints] = hit
        return hit

    def linearization(self, setpoints: tuple[float, ...]) -> tuple[NDArray[np.float64], ...]:
        """``(A, B, Cy, y0, x_bar, u_bar, f0)`` at the equilibrium ``(x_bar, u_bar)`` that holds
        these set points: ``x' ~ f0 + A (x - x_bar) + B (u - u_bar)``, ``y ~ Cy x + y0``
        (``f0 ~ 0``), so the loops' feedforward holds the set points in the linear model too."""
        hit = self._lin.get(setpoints)
        if hit is None:
            x_bar, u_bar = self._equilibrium(setpoints)
            A, B, Cy = jacobians(self.model, x_bar, u_bar)
            y0 = np.asarray(self.model.outputs(x_bar), dtype=float) - Cy @ x_bar
            f0 = np.asarray(self.model.rhs(0.0, x_bar, u_bar), dtype=float)
            hit = self._lin[setpoints] = (A, B, Cy, y0, x_bar, u_bar, f0)
        return hit

    def _equilibrium(
        self, setpoints: tuple[float, ...]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        y_bar = {
            self.model.output_names[self.y_index[n]]: v
            for n, v in zip(self.loops, setpoints, strict=True)
        }
        free = [self.u_index[n] for n in self.loops]
        return equilibrium(self.model, y_bar, self.x0, self.u0, free)


class LinearPredictor:
    """Predicted worst-case overshoots of the agent's test on the linearised, exactly discretised
    loops (see the module docstring), for batches of candidate periods.

    Parameters
    ----------
    model : LoopModel
        The agent's model: its closed-loop spec, test, phase handling and limit.
    delays : mapping
        Control-path delay of each loop, time units (default 0).

    Raises
    ------
    ValueError
        If a loop's control law is not ``pi`` (the only law modelled).
    """

    def __init__(self, model: LoopModel, delays: Mapping[str, float]) -> None:
        cfg = model.config
        spec = model.trials.spec
        self.loops: tuple[str, ...] = tuple(model.loops)
        self.index = {n: k for k, n in enumerate(self.loops)}
        self.end = to_ticks(spec.end_time)
        self.delay = {n: to_ticks(float(delays.get(n, 0.0))) for n in self.loops}
        self.n_phases = 1 if cfg.phase == "fixed" else cfg.phases
        self.shift = cfg.phase == "worst"
        self.predictions = 0
        self.items = 0
        self.laws: dict[str, Law] = {
            n: modelled_law(spec.loops[n].law, spec.plants[spec.loops[n].plant].model, n)
            for n in self.loops
        }
        self.plant_of = {n: spec.loops[n].plant for n in self.loops}
        self.plants: dict[str, PlantData] = {}
        for pname in sorted(set(self.plant_of.values())):
            plant = spec.plants[pname]
            pm = plant.model
            names = tuple(sorted(n for n in self.loops if self.plant_of[n] == pname))
            self.plants[pname] = PlantData(
                name=pname,
                model=pm,
                x0=np.array([plant.x0[s] for s in pm.state_names], dtype=float),
                u0=np.array([plant.u0[s] for s in pm.input_names], dtype=float),
                loops=names,
                y_index={n: pm.output_names.index(spec.loops[n].sensor) for n in names},
                u_index={n: pm.input_names.index(spec.loops[n].actuator) for n in names},
                feedforward={n: spec.loops[n].feedforward for n in names},
                monitor=plant.monitor_period,
            )
        self.initial = {n: float(spec.loops[n].setpoint) for n in self.loops}
        self.steps = [(to_ticks(s.t), s.loop, float(s.value)) for s in spec.steps]
        self._pade: dict[int, tuple[NDArray[np.float64], ...]] = {}
        self._models: dict[tuple[Any, ...], Modal] = {}
        self.depends = {n: self._depends(n) for n in self.loops}

    def _depends(self, loop: str) -> tuple[str, ...]:
        """The loops whose periods can change the prediction of ``loop``: itself, and each other
        loop of its plant whose input reaches the states its output depends on, or whose steps
        change that part of the model or its feedforward (structurally, over the test's
        linearisations; e.g. none for the JCSTR level, whose dynamics ignore the jacket)."""
        plant = self.plants[self.plant_of[loop]]
        pl = plant.loops
        sp = [tuple(self.initial[n] for n in pl)]
        changes: list[str] = []
        for _, n, v in sorted(self.steps, key=lambda s: s[0]):
            if n in pl:
                nxt = list(sp[-1])
                nxt[pl.index(n)] = v
                sp.append(tuple(nxt))
                changes.append(n)
        lins = [plant.linearization(v) for v in sp]
        # a sum of boolean arrays from 0 (lins is not empty): the count of each entry, an int array
        pattern = cast("NDArray[np.int64]", sum(np.abs(lin[0]) > 0 for lin in lins))
        sensor = plant.y_index[loop]
        states = set(np.flatnonzero(sum(np.abs(lin[2][sensor]) > 0 for lin in lins)).tolist())
        grown = True
        while grown:
            new = {c for r in states for c in np.flatnonzero(pattern[r]).tolist()} - states
            states |= new
            grown = bool(new)
        rows = sorted(states)

        def local(k: int) -> NDArray[np.float64]:
            A, B, Cy, y0, x_bar, u_bar, f0 = lins[k]
            const = f0 - A @ x_bar - B @ u_bar
            ff = plant.u_bar(sp[k])[pl.index(loop)]
            return np.concatenate(
                [A[rows].ravel(), B[rows].ravel(), const[rows], Cy[sensor], [y0[sensor], ff]]
            )

        out = [loop]
        for j in pl:
            if j == loop:
                continue
            column = plant.u_index[j]
            reaches = any(np.abs(lin[1][rows, column]).max(initial=0.0) > 0 for lin in lins)
            moves = any(
                not np.allclose(local(k), local(k + 1), rtol=1e-9, atol=1e-12)
                for k, n in enumerate(changes)
                if n == j
            )
            if reaches or moves:
                out.append(j)
        return tuple(n for n in self.loops if n in out)

    # -- public ------------------------------------------------------------------------------
    def overshoots(self, loop: str, periods: NDArray[np.float64]) -> NDArray[np.float64]:
        """Predicted worst-case overshoot (%) of ``loop`` for each row of ``periods``
        (candidates x loops, in the order of :attr:`loops`, time units)."""
        periods = np.atleast_2d(np.asarray(periods, dtype=float))
        ticks = np.rint(periods * TICKS_PER_UNIT).astype(np.int64)
        if (ticks < 1).any():
            raise ValueError("fast method: a candidate period is shorter than one tick")
        os_items = self._simulate(loop, np.repeat(ticks, self.n_phases, axis=0))
        self.predictions += 1
        self.items += len(os_items)
        worst: NDArray[np.float64] = os_items.reshape(len(periods), self.n_phases).max(axis=1)
        return worst

    # -- the simulation of one batch ----------------------------------------------------------
    def _pade_of(self, delay_ticks: int) -> tuple[NDArray[np.float64], ...]:
        hit = self._pade.get(delay_ticks)
        if hit is None:
            hit = self._pade[delay_ticks] = pade(delay_ticks / TICKS_PER_UNIT)
        return hit

    def _model(
        self,
        plant: PlantData,
        loop: str,
        setpoints: tuple[float, ...],
        others_h: tuple[int, ...],
    ) -> Modal:
        """The continuous model of ``plant`` seen by ``loop``: the other loops closed by their
        laws' linear forms (:class:`agents.wncsca.laws.LinearForm`, about their set points)
        with measurement delay ``tau_d + h/2`` (Pade)."""
        A, B, Cy, y0, x_bar, u_bar, f0 = plant.linearization(setpoints)
        y_start = np.asarray(plant.model.outputs(plant.x0), dtype=float)
        others = [n for n in plant.loops if n != loop]
        nx = A.shape[0]
        pades = [
            self._pade_of(self.delay[j] + max(h // 2, 1))
            for j, h in zip(others, others_h, strict=True)
        ]
        sizes = [1 + p[0].shape[0] for p in pades]
        n = nx + sum(sizes)
        nw = 1 + 2 * len(others)
        F = np.zeros((n, n))
        G = np.zeros((n, 1))
        Gw = np.zeros((n, nw))
        F[:nx, :nx] = A
        # constant: f0 - A x_bar - B u_bar + B u (non-loop inputs held at u0)
        loop_inputs = {plant.u_index[j] for j in plant.loops}
        u_const = np.array([0.0 if k in loop_inputs else plant.u0[k] for k in range(B.shape[1])])
        Gw[:nx, 0] = f0 - A @ x_bar - B @ u_bar + B @ u_const
        G[:nx, 0] = B[:, plant.u_index[loop]]
        at = nx
        for k, (j, (Ap, Bp, Cp, Dp)) in enumerate(zip(others, pades, strict=True)):
            law = self.laws[j].linear(
                setpoints[plant.loops.index(j)], float(y_start[plant.y_index[j]])
            )
            b = B[:, plant.u_index[j]]
            cy = Cy[plant.y_index[j]]
            yo = y0[plant.y_index[j]]
            dp = float(Dp[0, 0])
            q, w = at, at + 1
            npd = Ap.shape[0]
            # delayed measurement: y~ = Cp w + Dp (cy x + yo); w' = Ap w + Bp (cy x + yo)
            # u_j = c_j + u_bar_j + k_r r_j - k_y y~ + k_i q ; q' = r_j - y~
            F[:nx, :nx] -= law.k_y * dp * np.outer(b, cy)
            F[:nx, q] = law.k_i * b
            F[q, :nx] = -dp * cy
            Gw[q, 0] = -dp * yo
            Gw[:nx, 0] += (law.c - law.k_y * dp * yo) * b
            if npd:
                F[:nx, w : w + npd] = -law.k_y * np.outer(b, Cp[0])
                F[q, w : w + npd] = -Cp[0]
                F[w : w + npd, :nx] = np.outer(Bp[:, 0], cy)
                F[w : w + npd, w : w + npd] = Ap
                Gw[w : w + npd, 0] = Bp[:, 0] * yo
            Gw[:nx, 1 + k] = law.k_r * b  # r_j
            Gw[q, 1 + k] = 1.0
            Gw[:nx, 1 + len(others) + k] = b  # u_bar_j
            at += 1 + npd
        return Modal(F, G, Gw)

    def _simulate(self, loop: str, ticks: NDArray[np.int64]) -> NDArray[np.float64]:
        """Overshoot (%) of ``loop`` per item (rows of period ticks, phases interleaved)."""
        batch = _Batch(self, loop, ticks)
        pieces = batch.pieces()
        return batch.overshoots(pieces, batch.recursion(pieces))


@dataclass
class _Pieces:
    """Each period of loop ``i`` in two pieces: ``[t_k, t_exec)`` under the stretch's model
    before the execution (``a``), ``[t_exec, t_k + h)`` after it (``b``); per item and stretch
    (``phi_*``, ``g_*``) and per item and period (``*_k``, the constants ``const_*``)."""

    phi_a: NDArray[np.float64]
    g_a: NDArray[np.float64]
    phi_b: NDArray[np.float64]
    g_b: NDArray[np.float64]
    phi_ak: NDArray[np.float64]
    g_ak: NDArray[np.float64]
    phi_bk: NDArray[np.float64]
    g_bk: NDArray[np.float64]
    w_a: NDArray[np.float64]
    w_b: NDArray[np.float64]
    const_a: NDArray[np.float64]
    const_b: NDArray[np.float64]


@dataclass
class _Trajectory:
    """The recursion's states at the sampling instants (``xs``) and just after the executions
    (``xe``), the input before and after each execution, and the samples ``ybuf``."""

    xs: NDArray[np.float64]
    xe: NDArray[np.float64]
    u_before: NDArray[np.float64]
    u_after: NDArray[np.float64]
    ybuf: NDArray[np.float64]


class _Batch:
    """One batch of items (candidate periods x phases) of one loop ``i``: where the test's steps
    fall, the stretches' models, and loop ``i``'s sampling and execution instants; its methods
    build the pieces' matrices, run the recursion and read the overshoots."""

    def __init__(self, p: LinearPredictor, loop: str, ticks: NDArray[np.int64]) -> None:
        self.p, self.loop, self.ticks = p, loop, ticks
        self.plant = plant = p.plants[p.plant_of[loop]]
        self.pl = plant.loops
        self.li = self.pl.index(loop)
        self.others = [n for n in self.pl if n != loop]
        self.n_items = len(ticks)
        self.ar = np.arange(self.n_items)
        self.hi = hi = ticks[:, p.index[loop]]
        self.h = hi / TICKS_PER_UNIT
        self.d_i = p.delay[loop]
        self.lag = self.d_i // hi
        self.theta = (self.d_i - self.lag * hi) / TICKS_PER_UNIT
        self._place_steps()
        self._stretch_models()
        self._timing()

    def _place_steps(self) -> None:
        """The test's steps on this plant, moved to their phase (Trials.run), and the set points
        of each stretch between them."""
        p, pl, ticks, n_items = self.p, self.pl, self.ticks, self.n_items
        phase = np.tile(np.arange(p.n_phases), n_items // p.n_phases)
        self.steps = steps = [(t, pl.index(n), v) for t, n, v in p.steps if n in pl]
        self.n_steps = n_steps = len(steps)
        self.t_step = t_step = np.zeros((n_items, n_steps), dtype=np.int64)
        for s, (t, lj, _) in enumerate(steps):
            if p.shift:
                per = ticks[:, p.index[pl[lj]]]
                t_step[:, s] = (t // per) * per + (phase * per) // p.n_phases
            else:
                t_step[:, s] = t
        order = np.argsort(t_step, axis=1, kind="stable")
        self.t_sorted = np.take_along_axis(t_step, order, axis=1)
        self.sp = sp = np.zeros((n_items, n_steps + 1, len(pl)))
        sp[:, 0] = [p.initial[n] for n in pl]
        step_loop = np.array([s[1] for s in steps], dtype=np.int64)
        self.step_value = step_value = np.array([s[2] for s in steps])
        for s in range(n_steps):
            sp[:, s + 1] = sp[:, s]
            sp[self.ar, s + 1, step_loop[order[:, s]]] = step_value[order[:, s]]

    def _stretch_models(self) -> None:
        """Feedforwards and linearisation points of each stretch, and the distinct models."""
        p, plant, pl, n_items, n_steps = self.p, self.plant, self.pl, self.n_items, self.n_steps
        flat, inverse = np.unique(self.sp.reshape(-1, len(pl)), axis=0, return_inverse=True)
        ubar = np.stack([plant.u_bar(tuple(map(float, r))) for r in flat])[inverse]
        self.ubar = ubar.reshape(n_items, n_steps + 1, len(pl))
        self.others_h = (
            np.stack([self.ticks[:, p.index[j]] for j in self.others], axis=1)
            if self.others
            else (np.zeros((n_items, 0), dtype=np.int64))
        )
        key_rows = np.concatenate(
            [
                self.sp.reshape(-1, len(pl)),
                np.repeat(self.others_h, n_steps + 1, axis=0).astype(float),
            ],
            axis=1,
        )
        self.keys, mid_of = np.unique(key_rows, axis=0, return_inverse=True)
        self.mid_of = mid_of.reshape(n_items, n_steps + 1)
        modal = []
        for k in self.keys:
            key = (
                self.loop,
                tuple(map(float, k[: len(pl)])),
                tuple(int(v) for v in k[len(pl) :]),
            )
            hit = p._models.get(key)
            if hit is None:
                hit = p._models[key] = p._model(plant, *key)
            modal.append(hit)
        self.models = Models(modal)
        self.n = modal[0].F.shape[0]
        self.nw = modal[0].Gw.shape[1]

    def _timing(self) -> None:
        """Loop ``i``'s sampling instants, executions and the stretch of each piece."""
        ar, hi, d_i, lag = self.ar, self.hi, self.d_i, self.lag
        self.k_max = k_max = int((self.p.end // hi).max()) + 1
        self.kk = kk = np.arange(k_max, dtype=np.int64)
        self.t_k = t_k = kk[None, :] * hi[:, None]  # sampling instants (items x periods)
        self.t_exec = t_exec = t_k + (d_i - lag * hi)[:, None]  # loop i's execution in each
        self.m_exec = kk[None, :] - lag[:, None]  # ... acting on sample m_exec (none when < 0)
        c_exec = self.count_le(t_exec)
        self.r_exec = self.sp[ar[:, None], c_exec, self.li]
        self.ub_exec = self.ubar[ar[:, None], c_exec, self.li]
        # each stretch's model is switched in at loop i's first execution after its change
        first = d_i + np.maximum(0, -(-(self.t_sorted - d_i) // hi[:, None])) * hi[:, None]
        self.seg_b = np.sum(first[:, None, :] <= t_exec[:, :, None], axis=2)  # after the exec.
        self.seg_a = np.sum(first[:, None, :] < t_exec[:, :, None], axis=2)  # before it
        self.mid_a = self.mid_of[ar[:, None], self.seg_a]
        self.mid_b = self.mid_of[ar[:, None], self.seg_b]

    def count_le(self, times: NDArray[np.int64]) -> NDArray[np.int64]:
        """Number of (sorted) steps at or before each time (items x ...)."""
        shape = (self.n_items,) + (1,) * (times.ndim - 1) + (self.n_steps,)
        count: NDArray[np.int64] = np.sum(self.t_sorted.reshape(shape) <= times[..., None], axis=-1)
        return count

    def applied(self, times: NDArray[np.int64]) -> NDArray[np.float64]:
        """The other loops' set points and feedforwards, applied at their executions: ``w = (1,
        r_j..., u_bar_j...)`` in force at ``times`` (items x ...)."""
        w = np.ones(times.shape + (self.nw,))
        front = (self.n_items,) + (1,) * (times.ndim - 1)
        for k, j in enumerate(self.others):
            hj = self.ticks[:, self.p.index[j]].reshape(front)
            dj = self.p.delay[j]
            last = np.where(times >= dj, dj + ((times - dj) // hj) * hj, -1)
            c = self.count_le(last)
            idx = (self.ar.reshape(front), c, self.pl.index(j))
            w[..., 1 + k] = self.sp[idx]
            w[..., 1 + len(self.others) + k] = self.ubar[idx]
        return w

    def pieces(self) -> _Pieces:
        """The matrices of each piece: ``[t_k, t_exec)`` under model a, ``[t_exec, t_k + h)``
        under model b."""
        models, n_items, ar = self.models, self.n_items, self.ar
        w_a = self.applied(self.t_k)
        w_b = self.applied(self.t_exec)
        n_seg = self.n_steps + 1
        flat_mid = self.mid_of.reshape(-1)
        phi_a, g_a, gw_a = (
            v.reshape((n_items, n_seg) + v.shape[1:])
            for v in models.step(flat_mid, np.repeat(self.theta, n_seg))
        )
        phi_b, g_b, gw_b = (
            v.reshape((n_items, n_seg) + v.shape[1:])
            for v in models.step(flat_mid, np.repeat(self.h - self.theta, n_seg))
        )
        sel_a, sel_b = (ar[:, None], self.seg_a), (ar[:, None], self.seg_b)
        pieces = _Pieces(
            phi_a,
            g_a,
            phi_b,
            g_b,
            phi_a[sel_a],
            g_a[sel_a],
            phi_b[sel_b],
            g_b[sel_b],
            w_a,
            w_b,
            np.einsum("iknw,ikw->ikn", gw_a[sel_a], w_a),
            np.einsum("iknw,ikw->ikn", gw_b[sel_b], w_b),
        )
        self._other_changes(pieces)
        return pieces

    def _other_changes(self, pieces: _Pieces) -> None:
        """The other loops' set-point and feedforward changes inside a piece, added to its
        constant."""
        ar, hi, d_i, lag, k_max = self.ar, self.hi, self.d_i, self.lag, self.k_max
        for j in self.others:
            hj = self.ticks[:, self.p.index[j]]
            dj = self.p.delay[j]
            prev = None
            for s in range(self.n_steps):
                a = dj + np.maximum(0, -(-(self.t_sorted[:, s] - dj) // hj)) * hj
                k_ev = a // hi
                off = a - k_ev * hi
                use = (off > 0) & (k_ev < k_max) & (off != d_i - lag * hi)
                if prev is not None:
                    use &= a != prev
                prev = a
                if not use.any():
                    continue
                items = ar[use]
                kev = k_ev[use]
                dw = (self.applied(np.where(use, a, 0)) - self.applied(np.where(use, a - 1, 0)))[
                    use
                ]
                early = off[use] < (d_i - lag[use] * hi[use])
                end_a = d_i - lag[use] * hi[use]  # offset of the execution
                rest = np.where(early, end_a - off[use], hi[use] - off[use]) / TICKS_PER_UNIT
                mids = np.where(early, self.mid_a[items, kev], self.mid_b[items, kev])
                corr = self.models.gamma_w(mids, rest, dw)
                ea, eb = items[early], items[~early]
                pieces.const_a[ea, kev[early]] += corr[early]
                pieces.const_b[eb, kev[~early]] += corr[~early]

    def _output_rows(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Loop ``i``'s output row and offset of each distinct model (``y = Cy xi + y0``)."""
        pd_y = self.plant.y_index[self.loop]
        cy_rows = np.zeros((len(self.keys), self.n))
        y0_rows = np.zeros(len(self.keys))
        for k, key in enumerate(self.keys):
            _, _, Cy, y0, *_ = self.plant.linearization(tuple(map(float, key[: len(self.pl)])))
            cy_rows[k, : Cy.shape[1]] = Cy[pd_y]
            y0_rows[k] = y0[pd_y]
        return cy_rows, y0_rows

    def _initial_state(self) -> NDArray[np.float64]:
        """The plant's initial state, each other loop's delay filter at its steady state."""
        plant = self.plant
        xi = np.zeros((self.n_items, self.n))
        nx = len(plant.x0)
        xi[:, :nx] = plant.x0
        at = nx
        y_meas = np.asarray(plant.model.outputs(plant.x0), dtype=float)
        for k, j in enumerate(self.others):
            hj = self.others_h[:, k]
            npd = PADE_ORDER
            for r in np.unique(hj):
                Ap, Bp, _, _ = self.p._pade_of(self.p.delay[j] + max(int(r) // 2, 1))
                ws = -np.linalg.solve(Ap, Bp[:, 0]) * y_meas[plant.y_index[j]]
                xi[hj == r, at + 1 : at + 1 + npd] = ws
            at += 1 + npd
        return xi

    def recursion(self, pc: _Pieces) -> _Trajectory:
        """The recursion, one sampling period of loop ``i`` per step."""
        ar, n_items, k_max, n = self.ar, self.n_items, self.k_max, self.n
        law = self.p.laws[self.loop]
        cy_rows, y0_rows = self.rows = self._output_rows()
        cy_k = cy_rows[self.mid_a]
        y0_k = y0_rows[self.mid_a]
        xi = self._initial_state()
        # one period: xi(k+1) = Phi_b (Phi_a xi + g_a u_before + c_a) + g_b u_after + c_b
        # Phi_b Phi_a and Phi_b g_a take one value per pair of pieces' models (n_seg^2 per
        # item): computed once per pair, looked up per period in the recursion
        n_seg = self.n_steps + 1
        pa = np.repeat(np.arange(n_seg), n_seg)  # pair p = sa * n_seg + sb
        pb = np.tile(np.arange(n_seg), n_seg)
        phi_pair = pc.phi_b[:, pb] @ pc.phi_a[:, pa]
        g_pair = (pc.phi_b[:, pb] @ pc.g_a[:, pa, :, None])[..., 0]
        pair = self.seg_a * n_seg + self.seg_b
        c_k = (pc.phi_bk @ pc.const_a[..., None])[..., 0] + pc.const_b
        g_bk = pc.g_bk
        xs = np.zeros((n_items, k_max, n))  # at the sampling instants
        u_before = np.zeros((n_items, k_max))
        u_after = np.zeros((n_items, k_max))
        ybuf = np.zeros((n_items, k_max))
        u_cur = np.full(n_items, self.plant.u0[self.plant.u_index[self.loop]])
        integral = np.zeros(n_items)
        e_prev = np.zeros(n_items)
        h, r_exec, ub_exec, valid = self.h, self.r_exec, self.ub_exec, self.m_exec >= 0
        m_idx = np.maximum(self.m_exec, 0)
        later = self.m_exec > 0  # the first execution does not integrate (controllers.pi)
        # per period (numpy types a reduction's tolist() as bool | Any: a list here, axis given)
        all_ok = cast("list[bool]", valid.all(axis=0).tolist())
        all_later = cast("list[bool]", later.all(axis=0).tolist())
        with np.errstate(over="ignore", invalid="ignore"):
            for k in range(k_max):
                xs[:, k] = xi
                ybuf[:, k] = np.add.reduce(cy_k[:, k] * xi, axis=1) + y0_k[:, k]  # np.sum's
                # the loop's law on sample k - lag, executed at offset theta
                y_k = ybuf[ar, m_idx[:, k]]
                err = r_exec[:, k] - y_k
                incr = law.increment(err, e_prev, h)
                if not all_later[k]:  # the first execution: no integration, the start rule
                    incr = np.where(later[:, k], incr, 0.0)
                    first = valid[:, k] & ~later[:, k]
                    integral = np.where(first, law.start(y_k, integral), integral)
                if not all_ok[k]:  # the items whose sample k - lag does not exist yet wait
                    incr = np.where(valid[:, k], incr, 0.0)
                u_new, integral = law.update(err, y_k, incr, integral, ub_exec[:, k])
                if all_ok[k]:
                    e_prev = err
                else:
                    u_new = np.where(valid[:, k], u_new, u_cur)
                    e_prev = np.where(valid[:, k], err, e_prev)
                u_before[:, k] = u_cur
                u_after[:, k] = u_new
                pk = pair[:, k]
                xi = (phi_pair[ar, pk] @ xi[:, :, None])[:, :, 0]
                xi += g_pair[ar, pk] * u_cur[:, None] + g_bk[:, k] * u_new[:, None] + c_k[:, k]
                u_cur = u_new
            xe = (pc.phi_ak @ xs[..., None])[..., 0] + pc.g_ak * u_before[..., None] + pc.const_a
        return _Trajectory(xs, xe, u_before, u_after, ybuf)

    def overshoots(self, pc: _Pieces, tr: _Trajectory) -> NDArray[np.float64]:
        """The output on the agent's monitoring grid, and the overshoot of loop ``i``'s steps:
        the grid is evaluated in the periods whose output at the events (samples, executions)
        comes within 2 % of the step of the largest, where the peak lies."""
        own = [s for s in range(self.n_steps) if self.steps[s][1] == self.li]
        if not own:
            return np.zeros(self.n_items)
        windows, cand = self._windows(own, tr)
        pick_i, pick_g, y = self._on_grid(own, cand, pc, tr)
        worst = np.zeros(self.n_items)
        starts = np.flatnonzero(np.concatenate([[True], pick_i[1:] != pick_i[:-1]]))
        for t0, t1, sign, value, size in windows:
            inside = (pick_g >= t0[pick_i]) & (pick_g <= t1[pick_i])
            dev = np.where(inside, sign[pick_i, 0] * (y - value), -np.inf)
            peak = np.full(self.n_items, -np.inf)
            if len(dev):  # pick_i is sorted: each item's picks are one run
                peak[pick_i[starts]] = np.maximum.reduceat(dev, starts)
            with np.errstate(divide="ignore", invalid="ignore"):
                os_pct = np.maximum(0.0, peak) / np.abs(size) * 100.0
            os_pct = np.where(np.isfinite(os_pct), os_pct, np.inf)
            worst = np.maximum(worst, np.where(size == 0, 0.0, os_pct))
        return worst

    def _windows(
        self, own: list[int], tr: _Trajectory
    ) -> tuple[list[tuple[Any, ...]], NDArray[np.bool_]]:
        """Each own step's window (from it to the loop's next step), and the periods whose
        output at the events comes within 2 % of the step of the window's largest."""
        ar, n_items, k_max, t_step, hi = self.ar, self.n_items, self.k_max, self.t_step, self.hi
        cy_rows, y0_rows = self.rows
        y_exec = np.sum(cy_rows[self.mid_b] * tr.xe, axis=2) + y0_rows[self.mid_b]
        t_next = self.t_k + hi[:, None]
        y_next = np.concatenate([tr.ybuf[:, 1:], tr.ybuf[:, -1:]], axis=1)
        windows = []
        cand = np.zeros((n_items, k_max), dtype=bool)
        for s in own:
            t0 = t_step[:, s]
            t1 = np.full(n_items, self.p.end)
            for o in own:  # the window ends at the loop's next step
                after_s = t_step[:, o] > t0
                t1 = np.where(after_s, np.minimum(t1, t_step[:, o]), t1)
            r_from = self.sp[ar, self.count_le(t0 - 1), self.li]  # the set point just before
            value = self.step_value[s]
            size = value - r_from
            sign = np.sign(size)[:, None]
            env = np.full((n_items, k_max), -np.inf)
            for tt, yy in ((self.t_k, tr.ybuf), (self.t_exec, y_exec), (t_next, y_next)):
                inside = (tt >= t0[:, None]) & (tt <= t1[:, None])
                env = np.maximum(env, np.where(inside, sign * (yy - value), -np.inf))
            top = env.max(axis=1, keepdims=True)
            kk = self.kk[None, :]
            edges = (kk == (t0 // hi)[:, None]) | (kk == (t1 // hi)[:, None])
            cand |= (env >= top - 0.02 * np.abs(size)[:, None]) | edges
            windows.append((t0, t1, sign, value, size))
        return windows, cand

    def _on_grid(
        self, own: list[int], cand: NDArray[np.bool_], pc: _Pieces, tr: _Trajectory
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
        """The output at the monitoring grid's times in the candidate periods: ``(item, time,
        y)`` of each pick, sorted by item."""
        hi, theta_t = self.hi, self.d_i - self.lag * self.hi
        dt_mon = to_ticks(self.plant.monitor)
        g_lo = -(-int(self.t_step[:, own].min()) // dt_mon)
        grid = np.arange(g_lo, self.p.end // dt_mon + 1, dtype=np.int64) * dt_mon
        k_g = grid[None, :] // hi[:, None]  # the period of each grid time (items x grid)
        pick_i, pick_g = np.nonzero(cand[self.ar[:, None], k_g])
        kp = k_g[pick_i, pick_g]
        s_g = grid[pick_g] - kp * hi[pick_i]
        after = s_g >= theta_t[pick_i]
        local = np.where(after, s_g - theta_t[pick_i], s_g)
        mid_g = np.where(after, self.mid_b[pick_i, kp], self.mid_a[pick_i, kp])
        # y = [xi, u, w] . [R, rg, Rw] with the output offset in w's constant
        zz = np.stack(
            [
                np.concatenate([tr.xs, tr.u_before[..., None], pc.w_a], axis=2),
                np.concatenate([tr.xe, tr.u_after[..., None], pc.w_b], axis=2),
            ],
            axis=2,
        )  # items x periods x (before, after the execution) x (xi, u, w)
        z = zz[pick_i, kp, after.astype(np.intp)]
        cy_rows, y0_rows = self.rows
        first, inverse = distinct_ticks(mid_g, local)
        R, rg, Rw = self.models.rows(
            mid_g[first], cy_rows, (local[first] / TICKS_PER_UNIT)[:, None]
        )
        Rw[:, 0, 0] += y0_rows[mid_g[first]]
        rows = np.concatenate([R[:, 0], rg, Rw[:, 0]], axis=1)[inverse]
        with np.errstate(over="ignore", invalid="ignore"):
            y = np.sum(z * rows, axis=1)
        return pick_i, grid[pick_g], y


# -- the searches on the predictions ---------------------------------------------------------
