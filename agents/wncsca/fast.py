"""The fast sampling-period method: the agent's loops linearised and discretised exactly, many
candidate periods at once, every choice checked on the non-linear model (seed 000, III.E step 3
asks for the longest periods within the overshoot limit; this answers the same question, or the
one of least network energy, with far fewer non-linear simulations).

Prediction
----------
For a loop ``i`` and a batch of candidate period vectors, :class:`LinearPredictor` simulates the
agent's whole set-point test (the test, step phases and end time of
:class:`~agents.wncsca.model.LoopModel`) on a linear model:

* the plant (any plant with ``rhs`` and ``outputs``) is linearised by central differences at the
  equilibrium holding the set points of each stretch of the test (``equilibrium()`` when the
  plant has one, else a root solve), anchored there so that the loops' feedforward holds the set
  points in the linear model too; a stretch's model is switched in at loop ``i``'s first
  execution after the set-point change (before it, the plant still sits near the previous
  equilibrium);
* loop ``i`` is exact: zero-order hold at its period ``h`` and the sensor-path delay
  ``tau_d = l h + theta`` (``0 <= theta < h``; the modified z-transform as two pieces per period,
  the held input before and after the delivery at ``theta``, with the ``l`` samples in flight
  kept), the PI law of :mod:`controllers.pi` executed sample by sample (forward or backward
  integral, output limits, clamping anti-windup, the feedforward and set point in force at each
  execution);
* the other loops of the same plant are closed in continuous time: their PI acts on their output
  delayed by ``tau_d + h/2`` (the sample-and-hold's mean delay; Pade approximant of order 3), their
  set point and feedforward change at their first execution after each step, and their output
  limits are ignored. Loops on other plants cannot interact, and a loop's prediction is keyed
  only by the periods that can structurally reach its output (for the JCSTR, the level does not
  depend on the temperature loop);
* between the events of loop ``i`` the model is LTI, so a period is two matrix steps
  (exponentials by eigen-decomposition; block ``expm`` when the eigenvectors are
  ill-conditioned), the whole batch (candidates x step phases) advancing together in numpy;
  the output is evaluated between the samples too, on the agent's monitoring grid (the plant's
  ``monitor_period``: where the agent judges the plant output), in the periods whose output at
  the sampling and execution instants comes within 2 % of the step of the largest (a tenth
  before issue 20; every prediction of the N-loop problems and of the worked example's grid of
  delays is the same to the bit with either).

The overshoot is measured as :func:`core.record.loop_metrics` does (from the loop's step to
its next step or the end), worst case over the step phases. The JCSTR level, a linear plant,
is predicted exactly (to 0.01 points); for small temperature steps from equilibrium the
prediction is within a point and the difference halves with the step (the linearisation's);
for the worked example's 4 C step the linear model overshoots 3-5 points more than the
non-linear one (the jacket's input gain falls as it heats), which the checks below calibrate
away.

Choice and checks
-----------------
``objective="paper"``: each loop in turn (``order``) takes the longest period on the
``resolution`` grid whose predicted overshoot is within the limit (the first crossing above its
ideal period, on a geometric scan refined to the grid), the others fixed, alternating until no
period changes. Each choice is then checked on the non-linear model
(:meth:`LoopModel.evaluate`), and the searches are repeated on calibrated predictions: a loop's
checked overshoot is taken as ``a + c * predicted`` (``c = 1`` after one check, a secant after
two), aiming at the middle of the paper's band ``[limit - os_tolerance, limit]`` and keeping the
loops already in it, until every loop is in the band (the paper's stop) or the choice no longer
changes. A loop over the limit that the calibration does not move steps down the grid, further
after each failure, until the check passes.

``objective="energy"``: the least network energy rate ``sum(weights[l] / period[l])`` with every
overshoot within the limit. The calibrated paper search is run to its fixed point at the limit;
then one loop at a time is pinned 5-50 % shorter while the others take their longest predicted
periods (on a grid 5 times coarser), and the best trade (if any) is corrected and checked the
same way with the pinned loop held; finally each loop more than ``os_tolerance / 4`` below the
limit is lengthened a grid step at a time while the check passes. The checked choice of least
energy is returned.

Every returned choice passed the non-linear check; if none did, the assignment holds the
benchmark periods with ``feasible=False`` and the reason.

Batched checks
--------------
With the loops on several plants, a check on the engine runs every plant once per step phase
(:meth:`LoopModel.evaluate`), and the paper's method does that for every trial of every loop.
There the checks run as batches instead (:class:`agents.wncsca.batch.BatchTrials`: every plant
and phase of a check at once, as numpy arrays of state, each plant's trials memoised by its
loops' periods, so a later check re-simulates only the plants whose periods changed). A batch
gives the engine's overshoots to the last bit, so the choices are those of the engine checks;
``simulations`` then counts no engine runs, and ``extra`` says how many trials were batched and
in how many batches. A check after the first also simulates, in the batches it runs anyway,
each loop the calibration moved one grid step shorter and longer (the others as checked):
the corrected searches often end there, and the next check then costs no batch (memoised
only: the choices are unchanged). A batch of a check's 8-24 JCSTR trials costs about 0.055 s
here, about what 5 engine trials of one plant cost, so on one plant (a check of 4 phases) the
engine is kept.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from agents.wncsca.assignment import Assignment, Trial
from agents.wncsca.batch import BatchTrials
from agents.wncsca.model import LoopModel
from controllers.pi import PIConfig
from core.time import TICKS_PER_UNIT, to_ticks
from plants.linearization import equilibrium, jacobians

__all__ = ["OBJECTIVES", "LinearPredictor", "energy_rate", "fast_periods"]

OBJECTIVES = ("paper", "energy")
"""What the fast method optimises: the paper's answer, or the least network energy."""

_PADE_ORDER = 3
_COARSE_RATIO = 1.1  # geometric step of the first, coarse scan of a loop's periods
_FINE_POINTS = 48  # candidates per refinement of a bracket
_WINDOW = 1.08  # a search from a previous answer first tries every period within this ratio
_MAX_VERIFY = 8  # bias-corrected re-solves before stepping down the grid
_MAX_PROBES = 3  # energy objective: grid steps up tried per loop at the end
_PIN_FACTORS = (0.95, 0.9, 0.8, 0.7, 0.6, 0.5)  # first trial pinned periods
_PIN_COARSE = 5  # the trades are explored on a grid this many times coarser
_COND_LIMIT = 1e8  # eigenvector condition number above which expm is used instead


def energy_rate(periods: Mapping[str, float], weights: Mapping[str, float] | None = None) -> float:
    """Network energy per time unit of the loops' samples: ``sum(weights[l] / periods[l])``
    (``weights[l]``: cost of one sample of loop ``l``, e.g. its transmissions; default 1)."""
    w = weights or {}
    return float(sum(float(w.get(n, 1.0)) / p for n, p in periods.items()))


# -- the linear model --------------------------------------------------------------------------


@dataclass(frozen=True)
class _Law:
    kp: float
    ki: float
    u_min: float
    u_max: float
    forward: bool


@dataclass
class _PlantData:
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


def _pade(delay: float, order: int = _PADE_ORDER) -> tuple[NDArray[np.float64], ...]:
    """State-space ``(Ap, Bp, Cp, Dp)`` of the Pade approximant of ``exp(-s delay)``,
    ``delay > 0``."""
    import scipy.signal

    n = order
    c = [
        math.factorial(2 * n - k)
        * math.factorial(n)
        / (math.factorial(2 * n) * math.factorial(k) * math.factorial(n - k))
        for k in range(n + 1)
    ]
    den = [c[k] * delay**k for k in range(n, -1, -1)]
    num = [c[k] * (-delay) ** k for k in range(n, -1, -1)]
    Ap, Bp, Cp, Dp = scipy.signal.tf2ss(num, den)
    return Ap, Bp, Cp, Dp


class _Modal:
    """Exponentials of one LTI model ``xi' = F xi + G u + Gw w``: eigen-decomposition, or the
    matrix exponential itself when the eigenvectors are ill-conditioned."""

    def __init__(self, F: NDArray[np.float64], G: NDArray[np.float64], Gw: NDArray[np.float64]):
        self.F, self.G, self.Gw = F, G, Gw
        lam, V = np.linalg.eig(F)
        self.modal = bool(np.isfinite(lam).all()) and np.linalg.cond(V) < _COND_LIMIT
        if self.modal:
            self.lam, self.V = lam, V
            self.Vi = np.linalg.inv(V)
            self.ViG = self.Vi @ G
            self.ViGw = self.Vi @ Gw


def phi1(
    z: NDArray[np.complex128] | NDArray[np.float64],
    ez: NDArray[np.complex128] | NDArray[np.float64] | None = None,
) -> Any:
    """``(exp(z) - 1) / z`` (1 at 0); ``ez = exp(z)`` when already known. ``z`` is complex, or
    real where the eigenvalues are (``np.linalg.eig`` returns real eigenvalues as a real
    array)."""
    if ez is None:
        ez = np.exp(z)
    small = np.abs(z) < 1e-5
    with np.errstate(divide="ignore", invalid="ignore"):
        out = (ez - 1.0) / z
    if small.any():
        out = np.where(small, 1.0 + z / 2.0 + z * z / 6.0, out)
    return out


def _expm_pair(F: NDArray[np.float64], t: float) -> tuple[NDArray[np.float64], ...]:
    """``(Phi(t), Gamma(t))`` with ``Gamma(t) = int_0^t exp(F s) ds`` by one block ``expm``."""
    n = F.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = F * t
    M[:n, n:] = np.eye(n) * t
    E = scipy.linalg.expm(M)
    return E[:n, :n], E[:n, n:]


def _distinct(mid: NDArray[np.int64], key: NDArray[Any]) -> tuple[NDArray[np.int64], ...]:
    """Indices of the distinct ``(mid, key)`` items and, per item, its distinct one (``key``: one
    number per item that fixes its times)."""
    _, kid = np.unique(key, return_inverse=True)
    _, first, inverse = np.unique(
        mid.astype(np.int64) * (int(kid.max()) + 1) + kid.reshape(-1),
        return_index=True,
        return_inverse=True,
    )
    return first, inverse.reshape(-1)


def _distinct_ticks(
    mid: NDArray[np.int64], ticks: NDArray[np.int64]
) -> tuple[NDArray[np.int64], ...]:
    """:func:`_distinct` for a key of non-negative integers (ticks): the same items in the same
    order (by model, then key), found with a table instead of a sort."""
    span = int(ticks.max(initial=0)) + 1
    key = mid.astype(np.int64) * span + ticks
    size = int(key.max(initial=0)) + 1
    if size > 8 * len(key) + 4096:  # a sparse key: sort
        return _distinct(mid, ticks)
    seen = np.zeros(size, dtype=bool)
    seen[key] = True
    keys = np.flatnonzero(seen)
    lookup = np.zeros(size, dtype=np.int64)
    lookup[keys] = np.arange(len(keys))
    inverse = lookup[key]
    first = np.zeros(len(keys), dtype=np.int64)
    first[inverse[::-1]] = np.arange(len(key) - 1, -1, -1)  # the first item of each key
    return first, inverse


class _Models:
    """The distinct LTI models of one batch, and their exponentials at per-item times."""

    def __init__(self, models: list[_Modal]) -> None:
        self.models = models
        self.all_modal = all(m.modal for m in models)
        if self.all_modal:
            self.lam = np.stack([m.lam for m in models])
            self.V = np.stack([m.V for m in models])
            self.Vi = np.stack([m.Vi for m in models])
            self.ViG = np.stack([m.ViG[:, 0] for m in models])
            self.ViGw = np.stack([m.ViGw for m in models])

    def step(
        self, mid: NDArray[np.int64], t: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        """Per item ``Phi(t)``, ``Gamma(t) G`` and ``Gamma(t) Gw`` of model ``mid``."""
        first, inverse = _distinct(mid, t)
        return tuple(v[inverse] for v in self._step(mid[first], t[first]))

    def _step(
        self, mid: NDArray[np.int64], t: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        if not self.all_modal:
            out = []
            for m, tt in zip(mid, t, strict=True):
                model = self.models[int(m)]
                phi, gam = _expm_pair(model.F, float(tt))
                out.append((phi, (gam @ model.G)[:, 0], gam @ model.Gw))
            return tuple(np.stack(v) for v in zip(*out, strict=True))
        lam, V = self.lam[mid], self.V[mid]
        tt = t[:, None]
        ez = np.exp(lam * tt)
        phi = np.real((V * ez[:, None, :]) @ self.Vi[mid])
        c = tt * phi1(lam * tt, ez)
        g = np.real(np.einsum("inm,im->in", V, c * self.ViG[mid]))
        gw = np.real(V @ (c[:, :, None] * self.ViGw[mid]))
        return phi, g, gw

    def gamma_w(
        self, mid: NDArray[np.int64], t: NDArray[np.float64], dw: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Per item ``Gamma(t) Gw dw``."""
        gw: NDArray[np.float64] = np.einsum("inw,iw->in", self.step(mid, t)[2], dw)
        return gw

    def rows(
        self, mid: NDArray[np.int64], cy: NDArray[np.float64], t: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        """Output rows at times ``t`` (items x points) after a state ``xi``, input ``u`` held and
        affine input ``w``: ``y(t) = R xi + rg u + Rw w`` (``cy``: output row per model)."""
        return self._rows(mid, cy[mid], t)

    def _rows(
        self, mid: NDArray[np.int64], cy: NDArray[np.float64], t: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        if not self.all_modal:
            n_items, n_pts = t.shape
            n, nw = self.models[0].F.shape[0], self.models[0].Gw.shape[1]
            R = np.zeros((n_items, n_pts, n))
            rg = np.zeros((n_items, n_pts))
            Rw = np.zeros((n_items, n_pts, nw))
            for i in range(n_items):
                m = self.models[int(mid[i])]
                for q in range(n_pts):
                    phi, gam = _expm_pair(m.F, float(t[i, q]))
                    R[i, q] = cy[i] @ phi
                    rg[i, q] = cy[i] @ gam @ m.G[:, 0]
                    Rw[i, q] = cy[i] @ gam @ m.Gw
            return R, rg, Rw
        lam = self.lam[mid][:, None, :]  # items, 1, n
        cyv = np.einsum("in,inm->im", cy, self.V[mid])[:, None, :]
        tt = t[:, :, None]
        ez = np.exp(lam * tt)
        R = np.real((cyv * ez) @ self.Vi[mid])
        c = cyv * tt * phi1(lam * tt, ez)
        rg = np.real(np.sum(c * self.ViG[mid][:, None, :], axis=2))
        Rw = np.real(c @ self.ViGw[mid])
        return R, rg, Rw


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
        self.laws: dict[str, _Law] = {}
        for n in self.loops:
            law = spec.loops[n].law
            if not isinstance(law, PIConfig):
                raise ValueError(
                    f"fast method: loop {n!r} uses control law {law.type!r}; only 'pi' loops "
                    "are modelled (use method 'paper')"
                )
            self.laws[n] = _Law(law.Kp, law.Ki, law.u_min, law.u_max, law.integration == "forward")
        self.plant_of = {n: spec.loops[n].plant for n in self.loops}
        self.plants: dict[str, _PlantData] = {}
        for pname in sorted(set(self.plant_of.values())):
            plant = spec.plants[pname]
            pm = plant.model
            names = tuple(sorted(n for n in self.loops if self.plant_of[n] == pname))
            self.plants[pname] = _PlantData(
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
        self._models: dict[tuple[Any, ...], _Modal] = {}
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
            hit = self._pade[delay_ticks] = _pade(delay_ticks / TICKS_PER_UNIT)
        return hit

    def _model(
        self,
        plant: _PlantData,
        loop: str,
        setpoints: tuple[float, ...],
        others_h: tuple[int, ...],
    ) -> _Modal:
        """The continuous model of ``plant`` seen by ``loop``: the other loops closed by their PI
        with measurement delay ``tau_d + h/2`` (Pade)."""
        A, B, Cy, y0, x_bar, u_bar, f0 = plant.linearization(setpoints)
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
            law = self.laws[j]
            b = B[:, plant.u_index[j]]
            cy = Cy[plant.y_index[j]]
            yo = y0[plant.y_index[j]]
            dp = float(Dp[0, 0])
            q, w = at, at + 1
            npd = Ap.shape[0]
            # delayed measurement: y~ = Cp w + Dp (cy x + yo); w' = Ap w + Bp (cy x + yo)
            # u_j = u_bar_j + Kp (r_j - y~) + Ki q ; q' = r_j - y~
            F[:nx, :nx] -= law.kp * dp * np.outer(b, cy)
            F[:nx, q] = law.ki * b
            F[q, :nx] = -dp * cy
            Gw[q, 0] = -dp * yo
            Gw[:nx, 0] -= law.kp * dp * yo * b
            if npd:
                F[:nx, w : w + npd] = -law.kp * np.outer(b, Cp[0])
                F[q, w : w + npd] = -Cp[0]
                F[w : w + npd, :nx] = np.outer(Bp[:, 0], cy)
                F[w : w + npd, w : w + npd] = Ap
                Gw[w : w + npd, 0] = Bp[:, 0] * yo
            Gw[:nx, 1 + k] = law.kp * b  # r_j
            Gw[q, 1 + k] = 1.0
            Gw[:nx, 1 + len(others) + k] = b  # u_bar_j
            at += 1 + npd
        return _Modal(F, G, Gw)

    def _simulate(self, loop: str, ticks: NDArray[np.int64]) -> NDArray[np.float64]:
        """Overshoot (%) of ``loop`` per item (rows of period ticks, phases interleaved)."""
        plant = self.plants[self.plant_of[loop]]
        pl = plant.loops
        li = pl.index(loop)
        others = [n for n in pl if n != loop]
        n_items = len(ticks)
        ar = np.arange(n_items)
        phase = np.tile(np.arange(self.n_phases), n_items // self.n_phases)
        hi = ticks[:, self.index[loop]]
        h = hi / TICKS_PER_UNIT
        d_i = self.delay[loop]
        lag = d_i // hi
        theta = (d_i - lag * hi) / TICKS_PER_UNIT

        # the test's steps on this plant, moved to their phase (Trials.run)
        steps = [(t, pl.index(n), v) for t, n, v in self.steps if n in pl]
        n_steps = len(steps)
        t_step = np.zeros((n_items, n_steps), dtype=np.int64)
        for s, (t, lj, _) in enumerate(steps):
            if self.shift:
                p = ticks[:, self.index[pl[lj]]]
                t_step[:, s] = (t // p) * p + (phase * p) // self.n_phases
            else:
                t_step[:, s] = t
        order = np.argsort(t_step, axis=1, kind="stable")
        t_sorted = np.take_along_axis(t_step, order, axis=1)
        sp = np.zeros((n_items, n_steps + 1, len(pl)))
        sp[:, 0] = [self.initial[n] for n in pl]
        step_loop = np.array([s[1] for s in steps], dtype=np.int64)
        step_value = np.array([s[2] for s in steps])
        for s in range(n_steps):
            sp[:, s + 1] = sp[:, s]
            sp[ar, s + 1, step_loop[order[:, s]]] = step_value[order[:, s]]
        # feedforwards and linearisation points of each stretch
        flat, inverse = np.unique(sp.reshape(-1, len(pl)), axis=0, return_inverse=True)
        ubar = np.stack([plant.u_bar(tuple(map(float, r))) for r in flat])[inverse]
        ubar = ubar.reshape(n_items, n_steps + 1, len(pl))
        others_h = (
            np.stack([ticks[:, self.index[j]] for j in others], axis=1)
            if others
            else (np.zeros((n_items, 0), dtype=np.int64))
        )
        key_rows = np.concatenate(
            [
                sp.reshape(-1, len(pl)),
                np.repeat(others_h, n_steps + 1, axis=0).astype(float),
            ],
            axis=1,
        )
        keys, mid_of = np.unique(key_rows, axis=0, return_inverse=True)
        mid_of = mid_of.reshape(n_items, n_steps + 1)
        modal = []
        for k in keys:
            key = (
                loop,
                tuple(map(float, k[: len(pl)])),
                tuple(int(v) for v in k[len(pl) :]),
            )
            hit = self._models.get(key)
            if hit is None:
                hit = self._models[key] = self._model(plant, *key)
            modal.append(hit)
        models = _Models(modal)
        n = modal[0].F.shape[0]
        nw = modal[0].Gw.shape[1]

        def count_le(times: NDArray[np.int64]) -> NDArray[np.int64]:
            """Number of (sorted) steps at or before each time (items x ...)."""
            shape = (n_items,) + (1,) * (times.ndim - 1) + (n_steps,)
            count: NDArray[np.int64] = np.sum(t_sorted.reshape(shape) <= times[..., None], axis=-1)
            return count

        k_max = int((self.end // hi).max()) + 1
        kk = np.arange(k_max, dtype=np.int64)
        t_k = kk[None, :] * hi[:, None]  # sampling instants (items x periods)
        t_exec = t_k + (d_i - lag * hi)[:, None]  # loop i's execution in each period
        m_exec = kk[None, :] - lag[:, None]  # ... acting on sample m_exec (none when < 0)
        valid = m_exec >= 0
        c_exec = count_le(t_exec)
        r_exec = sp[ar[:, None], c_exec, li]
        ub_exec = ubar[ar[:, None], c_exec, li]
        # each stretch's model is switched in at loop i's first execution after its change
        first = d_i + np.maximum(0, -(-(t_sorted - d_i) // hi[:, None])) * hi[:, None]
        seg_b = np.sum(first[:, None, :] <= t_exec[:, :, None], axis=2)  # after the execution
        seg_a = np.sum(first[:, None, :] < t_exec[:, :, None], axis=2)  # before it
        mid_a = mid_of[ar[:, None], seg_a]
        mid_b = mid_of[ar[:, None], seg_b]

        # the other loops' set points and feedforwards, applied at their executions
        def applied(times: NDArray[np.int64]) -> NDArray[np.float64]:
            """``w = (1, r_j..., u_bar_j...)`` in force at ``times`` (items x ...)."""
            w = np.ones(times.shape + (nw,))
            for k, j in enumerate(others):
                hj = ticks[:, self.index[j]].reshape((n_items,) + (1,) * (times.ndim - 1))
                dj = self.delay[j]
                last = np.where(times >= dj, dj + ((times - dj) // hj) * hj, -1)
                c = count_le(last)
                idx = (ar.reshape((n_items,) + (1,) * (times.ndim - 1)), c, pl.index(j))
                w[..., 1 + k] = sp[idx]
                w[..., 1 + len(others) + k] = ubar[idx]
            return w

        w_a = applied(t_k)
        w_b = applied(t_exec)
        # matrices of each piece: [t_k, t_exec) under model a, [t_exec, t_k + h) under model b
        n_seg = n_steps + 1
        flat_mid = mid_of.reshape(-1)
        phi_a, g_a, gw_a = (
            v.reshape((n_items, n_seg) + v.shape[1:])
            for v in models.step(flat_mid, np.repeat(theta, n_seg))
        )
        phi_b, g_b, gw_b = (
            v.reshape((n_items, n_seg) + v.shape[1:])
            for v in models.step(flat_mid, np.repeat(h - theta, n_seg))
        )
        sel_a, sel_b = (ar[:, None], seg_a), (ar[:, None], seg_b)
        phi_ak, g_ak, phi_bk, g_bk = phi_a[sel_a], g_a[sel_a], phi_b[sel_b], g_b[sel_b]
        const_a = np.einsum("iknw,ikw->ikn", gw_a[sel_a], w_a)
        const_b = np.einsum("iknw,ikw->ikn", gw_b[sel_b], w_b)
        # the other loops' set-point and feedforward changes inside a piece
        for j in others:
            hj = ticks[:, self.index[j]]
            dj = self.delay[j]
            prev = None
            for s in range(n_steps):
                a = dj + np.maximum(0, -(-(t_sorted[:, s] - dj) // hj)) * hj
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
                dw = (applied(np.where(use, a, 0)) - applied(np.where(use, a - 1, 0)))[use]
                early = off[use] < (d_i - lag[use] * hi[use])
                end_a = d_i - lag[use] * hi[use]  # offset of the execution
                rest = np.where(early, end_a - off[use], hi[use] - off[use]) / TICKS_PER_UNIT
                mids = np.where(early, mid_a[items, kev], mid_b[items, kev])
                corr = models.gamma_w(mids, rest, dw)
                ea, eb = items[early], items[~early]
                const_a[ea, kev[early]] += corr[early]
                const_b[eb, kev[~early]] += corr[~early]

        # the recursion, one sampling period of loop i per step
        law = self.laws[loop]
        pd_y = plant.y_index[loop]
        cy_rows = np.zeros((len(keys), n))
        y0_rows = np.zeros(len(keys))
        for k, key in enumerate(keys):
            _, _, Cy, y0, *_ = plant.linearization(tuple(map(float, key[: len(pl)])))
            cy_rows[k, : Cy.shape[1]] = Cy[pd_y]
            y0_rows[k] = y0[pd_y]
        cy_k = cy_rows[mid_a]
        y0_k = y0_rows[mid_a]
        xi = np.zeros((n_items, n))
        nx = len(plant.x0)
        xi[:, :nx] = plant.x0
        at = nx
        y_meas = np.asarray(plant.model.outputs(plant.x0), dtype=float)
        for k, j in enumerate(others):
            hj = others_h[:, k]
            npd = _PADE_ORDER
            for r in np.unique(hj):
                Ap, Bp, _, _ = self._pade_of(self.delay[j] + max(int(r) // 2, 1))
                ws = -np.linalg.solve(Ap, Bp[:, 0]) * y_meas[plant.y_index[j]]
                xi[hj == r, at + 1 : at + 1 + npd] = ws
            at += 1 + npd
        # one period: xi(k+1) = Phi_b (Phi_a xi + g_a u_before + c_a) + g_b u_after + c_b
        # Phi_b Phi_a and Phi_b g_a take one value per pair of pieces' models (n_seg^2 per
        # item): computed once per pair, looked up per period in the recursion
        pa = np.repeat(np.arange(n_seg), n_seg)  # pair p = sa * n_seg + sb
        pb = np.tile(np.arange(n_seg), n_seg)
        phi_pair = phi_b[:, pb] @ phi_a[:, pa]
        g_pair = (phi_b[:, pb] @ g_a[:, pa, :, None])[..., 0]
        pair = seg_a * n_seg + seg_b
        c_k = (phi_bk @ const_a[..., None])[..., 0] + const_b
        xs = np.zeros((n_items, k_max, n))  # at the sampling instants
        u_before = np.zeros((n_items, k_max))
        u_after = np.zeros((n_items, k_max))
        ybuf = np.zeros((n_items, k_max))
        u_cur = np.full(n_items, plant.u0[plant.u_index[loop]])
        integral = np.zeros(n_items)
        e_prev = np.zeros(n_items)
        m_idx = np.maximum(m_exec, 0)
        later = m_exec > 0  # the first execution does not integrate (controllers.pi)
        not_ok = ~valid
        # per period (numpy types a reduction's tolist() as bool | Any: a list here, axis given)
        all_ok = cast("list[bool]", valid.all(axis=0).tolist())
        all_later = cast("list[bool]", later.all(axis=0).tolist())
        lo_v, hi_v = law.u_min, law.u_max
        with np.errstate(over="ignore", invalid="ignore"):
            for k in range(k_max):
                xs[:, k] = xi
                ybuf[:, k] = np.add.reduce(cy_k[:, k] * xi, axis=1) + y0_k[:, k]  # np.sum's
                # the PI law of controllers.pi on sample k - lag, executed at offset theta
                ok = valid[:, k]
                err = r_exec[:, k] - ybuf[ar, m_idx[:, k]]
                incr = law.ki * (e_prev if law.forward else err) * h
                if not all_later[k]:
                    incr = np.where(later[:, k], incr, 0.0)
                v = ub_exec[:, k] + law.kp * err + integral
                vi = v + incr
                if all_ok[k] and lo_v <= np.fmin.reduce(vi) and np.fmax.reduce(vi) <= hi_v:
                    # every item executes, none saturates: the law without its clamps
                    integral = integral + incr
                    e_prev = err
                    u_before[:, k] = u_cur
                    u_after[:, k] = vi
                    pk = pair[:, k]
                    xi = (phi_pair[ar, pk] @ xi[:, :, None])[:, :, 0]
                    xi += g_pair[ar, pk] * u_cur[:, None] + g_bk[:, k] * vi[:, None] + c_k[:, k]
                    u_cur = vi
                    continue
                wind = ((vi > law.u_max) & (incr > 0.0)) | ((vi < law.u_min) & (incr < 0.0))
                incr = np.where(wind | not_ok[:, k], 0.0, incr)
                u_new = np.where(ok, np.minimum(np.maximum(v + incr, law.u_min), law.u_max), u_cur)
                integral = integral + incr
                e_prev = np.where(ok, err, e_prev)
                u_before[:, k] = u_cur
                u_after[:, k] = u_new
                pk = pair[:, k]
                xi = (phi_pair[ar, pk] @ xi[:, :, None])[:, :, 0]
                xi += g_pair[ar, pk] * u_cur[:, None] + g_bk[:, k] * u_new[:, None] + c_k[:, k]
                u_cur = u_new
            xe = (phi_ak @ xs[..., None])[..., 0] + g_ak * u_before[..., None] + const_a

        # the output on the agent's monitoring grid, and the overshoot of loop i's steps: the
        # grid is evaluated in the periods whose output at the events (samples, executions)
        # comes within 2 % of the step of the largest, where the peak lies
        own = [s for s in range(n_steps) if steps[s][1] == li]
        if not own:
            return np.zeros(n_items)
        theta_t = d_i - lag * hi
        items = ar[:, None]
        y_exec = np.sum(cy_rows[mid_b] * xe, axis=2) + y0_rows[mid_b]
        t_next = t_k + hi[:, None]
        y_next = np.concatenate([ybuf[:, 1:], ybuf[:, -1:]], axis=1)
        windows = []
        cand = np.zeros((n_items, k_max), dtype=bool)
        for s in own:
            t0 = t_step[:, s]
            t1 = np.full(n_items, self.end)
            for o in own:  # the window ends at the loop's next step
                after_s = t_step[:, o] > t0
                t1 = np.where(after_s, np.minimum(t1, t_step[:, o]), t1)
            r_from = sp[ar, count_le(t0 - 1), li]  # the set point just before
            size = step_value[s] - r_from
            sign = np.sign(size)[:, None]
            env = np.full((n_items, k_max), -np.inf)
            for tt, yy in ((t_k, ybuf), (t_exec, y_exec), (t_next, y_next)):
                inside = (tt >= t0[:, None]) & (tt <= t1[:, None])
                env = np.maximum(env, np.where(inside, sign * (yy - step_value[s]), -np.inf))
            top = env.max(axis=1, keepdims=True)
            edges = (kk[None, :] == (t0 // hi)[:, None]) | (kk[None, :] == (t1 // hi)[:, None])
            cand |= (env >= top - 0.02 * np.abs(size)[:, None]) | edges
            windows.append((t0, t1, sign, step_value[s], size))
        dt_mon = to_ticks(plant.monitor)
        g_lo = -(-int(t_step[:, own].min()) // dt_mon)
        grid = np.arange(g_lo, self.end // dt_mon + 1, dtype=np.int64) * dt_mon
        k_g = grid[None, :] // hi[:, None]  # the period of each grid time (items x grid)
        pick_i, pick_g = np.nonzero(cand[items, k_g])
        kp = k_g[pick_i, pick_g]
        s_g = grid[pick_g] - kp * hi[pick_i]
        after = s_g >= theta_t[pick_i]
        local = np.where(after, s_g - theta_t[pick_i], s_g)
        mid_g = np.where(after, mid_b[pick_i, kp], mid_a[pick_i, kp])
        # y = [xi, u, w] . [R, rg, Rw] with the output offset in w's constant
        zz = np.stack(
            [
                np.concatenate([xs, u_before[..., None], w_a], axis=2),
                np.concatenate([xe, u_after[..., None], w_b], axis=2),
            ],
            axis=2,
        )  # items x periods x (before, after the execution) x (xi, u, w)
        z = zz[pick_i, kp, after.astype(np.intp)]
        first, inverse = _distinct_ticks(mid_g, local)
        R, rg, Rw = models.rows(mid_g[first], cy_rows, (local[first] / TICKS_PER_UNIT)[:, None])
        Rw[:, 0, 0] += y0_rows[mid_g[first]]
        rows = np.concatenate([R[:, 0], rg, Rw[:, 0]], axis=1)[inverse]
        with np.errstate(over="ignore", invalid="ignore"):
            y = np.sum(z * rows, axis=1)
        worst = np.zeros(n_items)
        starts = np.flatnonzero(np.concatenate([[True], pick_i[1:] != pick_i[:-1]]))
        t_pick = grid[pick_g]
        for t0, t1, sign, value, size in windows:
            inside = (t_pick >= t0[pick_i]) & (t_pick <= t1[pick_i])
            dev = np.where(inside, sign[pick_i, 0] * (y - value), -np.inf)
            peak = np.full(n_items, -np.inf)
            if len(dev):  # pick_i is sorted: each item's picks are one run
                peak[pick_i[starts]] = np.maximum.reduceat(dev, starts)
            with np.errstate(divide="ignore", invalid="ignore"):
                os_pct = np.maximum(0.0, peak) / np.abs(size) * 100.0
            os_pct = np.where(np.isfinite(os_pct), os_pct, np.inf)
            worst = np.maximum(worst, np.where(size == 0, 0.0, os_pct))
        return worst


# -- the searches on the predictions ---------------------------------------------------------


class _Curves:
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


def _grid(value: float | NDArray[np.float64], res: float) -> Any:
    return np.round(np.round(np.asarray(value) / res) * res, 12)


def _walk(
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


def _longest(
    curves: _Curves,
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
    top_t = to_ticks(float(_grid(max_period, res)))
    start_t = np.clip([to_ticks(float(v)) for v in _grid(starts, res)], res_t, top_t)
    mode = ["start"] * n
    lo = np.full(n, -1, dtype=np.int64)
    hi = np.full(n, -1, dtype=np.int64)
    for r in range(n):  # what is already predicted for a row may settle or bracket it
        known = curves.known(loop, rows[r])
        if not cold and int(start_t[r]) in known:
            mode[r], lo[r], hi[r] = _walk(known, int(start_t[r]), limit, res_t, top_t)
    for _round in range(64):
        cands: list[NDArray[np.float64]] = []
        for r in range(n):
            s = start_t[r] / TICKS_PER_UNIT
            if mode[r] == "start" and cold:
                c = np.append(s * _COARSE_RATIO ** np.arange(-3, 17), s)
            elif mode[r] == "start":
                a, b = _grid(s / _WINDOW, res), _grid(s * _WINDOW, res)
                k = int(round((b - a) / res))
                c = a + res * np.round(np.linspace(0, k, min(k + 1, _FINE_POINTS)))
                c = np.concatenate([c, [s], s * _COARSE_RATIO ** np.arange(-3, 6)])
            elif mode[r] == "up":
                c = lo[r] / TICKS_PER_UNIT * _COARSE_RATIO ** np.arange(1, 9)
            elif mode[r] == "down":
                c = hi[r] / TICKS_PER_UNIT / _COARSE_RATIO ** np.arange(1, 9)
            elif mode[r] == "fine":
                k = int(round((hi[r] - lo[r]) / res_t)) - 1
                steps_ = np.unique(np.round(np.linspace(1, k, min(k, _FINE_POINTS))))
                c = lo[r] / TICKS_PER_UNIT + res * steps_
            else:
                c = np.zeros(0)
            cands.append(np.unique(np.clip(_grid(c, res), res, top_t / TICKS_PER_UNIT)))
        if not any(len(c) for c in cands):
            break
        owner = np.concatenate([np.full(len(c), r) for r, c in enumerate(cands)]).astype(int)
        batch = rows[owner].copy()
        batch[:, col] = np.concatenate(cands)
        curves.overshoots(loop, batch)
        for r in range(n):
            if mode[r] != "done":
                mode[r], lo[r], hi[r] = _walk(
                    curves.known(loop, rows[r]), int(start_t[r]), limit, res_t, top_t
                )
    return np.where(lo >= 0, lo / TICKS_PER_UNIT, np.nan)


@dataclass
class _Solver:
    """The linear searches of one call, the non-linear checks and their trace."""

    model: LoopModel
    delays: dict[str, float]
    curves: _Curves
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
        return float(_grid(cfg.ideal_period.get(loop, self.model.benchmark[loop]), cfg.resolution))

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
        """:func:`_longest` on the ``resolution`` grid (``coarse`` times coarser)."""
        cfg = self.model.config
        return _longest(
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
        for factors in (_PIN_FACTORS, None):
            for loop_pinned in self.order if factors is not None else [best[2]]:
                if not loop_pinned:
                    continue
                now = best[1][idx[loop_pinned]]
                if factors is None:  # refine around the best pinned period found
                    ratio = now / p0[idx[loop_pinned]]
                    fs = ratio * np.array([0.97, 0.985, 1.015, 1.03])
                    vals = _grid(p0[idx[loop_pinned]] * fs, cfg.resolution)
                else:
                    vals = _grid(now * np.array(factors), cfg.resolution)
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
                            loop, rows, rows[:, idx[loop]], limits[loop], coarse=_PIN_COARSE
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
                    ahead[r, k] = _grid(ahead[r, k] + sgn * cfg.resolution, cfg.resolution)
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
        :data:`_MAX_PROBES` steps a loop): the calibrated predictions may stop a grid step or
        so short of where the non-linear overshoot crosses the limit."""
        cfg = self.model.config
        best = dict(periods)
        checked = {tuple(sorted(c[0].items())): c[1] for c in self.checked}
        for loop in self.order:
            os_now = checked.get(tuple(sorted(best.items())), {}).get(loop, -math.inf)
            if os_now >= cfg.overshoot_limit - cfg.os_tolerance / 4:
                continue
            for _ in range(_MAX_PROBES):
                trial = {**best, loop: float(_grid(best[loop] + cfg.resolution, cfg.resolution))}
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
        for _ in range(_MAX_VERIFY + cfg.max_trials):
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
            if len(self.checked) <= _MAX_VERIFY:
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
                        nxt[n] = float(_grid(max(res, periods[n] - res * 2 ** (failures - 1)), res))
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
    cfg = model.config
    if objective not in OBJECTIVES:
        raise ValueError(f"objective: expected one of {list(OBJECTIVES)}, got {objective!r}")
    order_l = list(order or cfg.order or model.loops)
    unknown = [n for n in order_l if n not in model.loops]
    if unknown:
        raise ValueError(f"order: unknown loop(s) {unknown} (loops: {list(model.loops)})")
    order_l += [n for n in model.loops if n not in order_l]
    w = {n: float((weights or {}).get(n, 1.0)) for n in model.loops}
    bad = {n: v for n, v in w.items() if not v > 0}
    if bad:
        raise ValueError(f"weights: must be > 0, got {bad}")
    delays = {n: float(delays.get(n, 0.0)) for n in model.loops}
    limit = cfg.overshoot_limit
    predictor = LinearPredictor(model, delays)
    if batched is None:  # the batch pays off when a check would run several plants
        batched = len({model.trials.spec.loops[n].plant for n in model.loops}) > 1
    batch = BatchTrials(model) if batched else None
    if batch is not None and not batch.available:
        batch = None
    solver = _Solver(model, delays, _Curves(predictor), order_l, w, batch=batch)

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
    reason = ""
    if objective == "energy" and passed:  # the checked choice of least energy
        choice = min((c[0] for c in passed), key=lambda p: energy_rate(p, w))
    if choice is not None:
        final, feasible = dict(choice), True
        if not converged:
            reason = "the corrected search did not settle: the last checked choice is assigned"
    else:
        final, feasible = dict(model.benchmark), False
        reason = (
            f"no periods down to {cfg.resolution:g} keep every overshoot within {limit:g} % on "
            f"the non-linear check ({len(solver.checked)} checked)"
        )
    os_final = solver.nonlinear(final)
    predicted = solver.predicted(final)
    return Assignment(
        method="fast",
        delays=delays,
        periods=final,
        overshoot_pct=os_final,
        feasible=feasible and all(v <= limit for v in os_final.values()),
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
            "predictions": predictor.predictions,
            "predicted_items": predictor.items,
            "checks": len(solver.checked),
            "batched_trials": batch.items if batch is not None else 0,
            "batches": batch.batches if batch is not None else 0,
        },
    )


def _finite(value: float) -> float | None:
    """``value``, or ``None`` when it is not finite (diverged), for JSON summaries."""
    return float(value) if math.isfinite(value) else None
