"""What the bus runs: one unit's local control system under quasi-decentralized control.

Seed 001 eq. (4): unit ``i`` runs an observer of its own states, a model of each neighbour
``j`` (``xhat_j^i``) that is reset to the neighbour's transmitted estimate ``xbar_j`` at every
update, and the feedback ``u_i = K_i xbar_i + sum_j K_ij xhat_j^i``. This module runs exactly that
controller on the bus: a controller node with ``loops: [...]`` (one loop per input of the unit;
the loops of the unit's measured outputs carry its sensors, the others are actuator-only loops,
``sensor: null``), and the estimates cross the network on the scenario's ``links:``.

Design (the same as :mod:`agents.update_period.analysis` and :mod:`controllers.qdc.design`)
--------------------------------------------------------------------------------------------
The law linearizes the plant object at its ``operating_point()``, splits it into the units of
eq. (11) (the plant's ``units``: names of each unit's states, inputs and outputs; or the law's
``units:``), designs ``K_i``, ``K_ij``, ``L_i`` with :class:`controllers.qdc.design.QDCDesign`
(poles ``controller_poles``, ``observer_poles``, method ``controller_method``) and builds
:class:`controllers.qdc.network.QDCNetwork` (embedded models from ``model_params``, or zero for
``scheme: zoh``); its controller is unit ``unit``'s block of that network's ``F, G, H``
(:meth:`controllers.qdc.network.QDCNetwork.local`). So the law on the bus is, matrix for matrix, the
controller whose maximum update period the analysis computes. Every controller of a plant
builds the whole design (it needs its neighbours' gains for its models of them), so the units'
laws should give the same design settings.

Sampled execution
-----------------
The plant is sampled (every ``tau_s``) and its inputs are held between moves. The law works in
deviation variables around the operating point (``y_dev = y - y_s``, ``u = u_s + u_dev``):

* between calls, the controller state flows as eq. (4) with the last measurement held,
  ``dz/dt = F z + G y_dev``, propagated **exactly** (matrix exponential of ``[[F, G], [0, 0]]``,
  cached per interval length); before the first sample the measurement is taken at the
  operating point (no innovation);
* ``step`` (a sample): propagate to ``t``, hold the new measurement, return ``u_s + H z``;
* ``transmit`` (a link's send timer): propagate to ``t``, return ``xbar_i``;
* ``receive`` (an estimate delivered): propagate to ``t``, then ``xhat_j^i = xbar_j`` (eq. (4)
  update). Set points are ignored: the law regulates to the operating point it was designed at.

The observer's input term is the continuous ``B_i K z`` of eq. (4), as in the analysis, not the
held move; with ``tau_s`` well below the fastest closed-loop time constant (``1/50 h`` for the
observers of section V) the sampled loop is the analysed one (checked against
:func:`controllers.qdc.model.simulate_nonlinear` in ``tests/unit/test_qdc_law.py``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from scipy.linalg import expm

from controllers.qdc.design import (
    PAPER_CONTROLLER_POLES,
    PAPER_OBSERVER_POLES,
    ControllerPoles,
    LinearUnits,
    ObserverPoles,
    QDCDesign,
)
from controllers.qdc.model import closed_loop_matrices
from controllers.qdc.network import LocalQDC, QDCNetwork

__all__ = ["UnitSignals", "QDCLawConfig", "QDCLaw"]

_CACHE_SIZE = 4096  # propagation matrices kept (one per interval length)
_DT_DIGITS = 9  # intervals are cached rounded to 1e-9 time units (a platform tick is 1e-6)


class UnitSignals(BaseModel):
    """One unit of eq. (11) by the plant's signal names."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    states: tuple[str, ...] = Field(min_length=1, description="the unit's states x_i")
    inputs: tuple[str, ...] = Field(min_length=1, description="the unit's inputs u_i")
    outputs: tuple[str, ...] = Field(min_length=1, description="the unit's measured outputs y_i")


class QDCLawConfig(BaseModel):
    """A unit's local control system of seed 001 eq. (4) (``type: qdc``)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    type: Literal["qdc"] = "qdc"
    unit: int = Field(ge=0, description="which unit this controller is (0-based, plant order)")
    controller_poles: ControllerPoles = PAPER_CONTROLLER_POLES
    observer_poles: ObserverPoles = PAPER_OBSERVER_POLES
    controller_method: Literal["diagonal", "place"] = Field(
        default="diagonal", description="see controllers.qdc.design.QDCDesign"
    )
    scheme: Literal["model", "zoh"] = Field(
        default="model", description="embedded models of the neighbours, or hold their estimate"
    )
    model_params: dict[str, float] = Field(
        default_factory=dict,
        description="plant parameters of the embedded models that differ from the plant's (model "
        "mismatch, e.g. dH1), linearized at the true operating point",
    )
    units: tuple[UnitSignals, ...] | None = Field(
        default=None, description="the unit decomposition (default: the plant's units)"
    )
    neighbours: dict[str, int] = Field(
        default_factory=dict,
        description="received link -> the unit whose estimate it carries (needed with more "
        "than two units)",
    )


class QDCLaw:
    """Unit ``config.unit``'s local control system (see the module docstring).

    Parameters
    ----------
    config : QDCLawConfig
        The law's configuration.
    loops : sequence of str
        The controller's loops.
    plant : object
        The plant model: ``state_names``, ``input_names``, ``output_names``,
        ``operating_point() -> (x_s, u_s)``, ``jacobians(x, u) -> (A, B)``,
        ``output_matrix() -> C``, ``units`` (unless the config gives them) and ``params`` (a
        pydantic model, for ``model_params``).
    signals : mapping
        Loop -> ``(sensor or None, actuator)``.
    sends, receives : sequence of str
        The links the controller transmits on and receives.

    Raises
    ------
    ValueError
        With the offending field first: a unit or signal the plant does not have, loops that do
        not move exactly the unit's inputs and measure its outputs, a design
        :class:`~controllers.qdc.design.QDCDesign` refuses (non-square or singular ``B_i`` where
        ``K_ij`` must cancel the coupling, poles), a link whose sender is unknown.
    """

    multi_loop = True
    actuator_only_loops = True  # loops of inputs without a sensor are part of the design

    def __init__(
        self,
        config: QDCLawConfig,
        loops: Sequence[str],
        plant: Any,
        signals: Mapping[str, tuple[str | None, str]],
        *,
        sends: Sequence[str] = (),
        receives: Sequence[str] = (),
    ) -> None:
        self.config = config
        self.loops = tuple(loops)
        x_s, u_s = plant.operating_point()
        self.x_s = np.asarray(x_s, dtype=float)
        self.u_s = np.asarray(u_s, dtype=float)
        units = config.units or tuple(
            UnitSignals(states=s, inputs=i, outputs=o) for s, i, o in plant.units
        )
        n = len(units)
        if config.unit >= n:
            raise ValueError(f"unit: {config.unit}, but the plant has {n} units (0..{n - 1})")
        index = [_unit_index(plant, k, u) for k, u in enumerate(units)]
        lin = _linear_units(plant, self.x_s, self.u_s, index)
        model = lin
        if config.model_params:
            model = _linear_units(
                _mismatched(plant, config.model_params), self.x_s, self.u_s, index
            )
        try:
            design = QDCDesign(
                plant=lin,
                controller_poles=config.controller_poles,
                observer_poles=config.observer_poles,
                controller_method=config.controller_method,
            )
        except ValidationError as err:
            e = err.errors()[0]
            raise ValueError(e["msg"].removeprefix("Value error, ")) from err
        self.plant_units, self.gains = lin, design.gains()
        self.network = QDCNetwork(lin, self.gains, model=model, scheme=config.scheme)
        i = config.unit
        self.local: LocalQDC = self.network.local(i)
        states, inputs, outputs = index[i]
        me = units[i]
        self._moves = _loops_of(me.inputs, {lp: s[1] for lp, s in signals.items()}, "moves", i)
        self._meas = _loops_of(
            me.outputs, {lp: s[0] for lp, s in signals.items() if s[0] is not None}, "measures", i
        )
        extra = sorted(set(self.loops) - set(self._moves))
        if extra:
            raise ValueError(f"loops: {extra} move inputs that are not unit {i}'s {me.inputs}")
        self.y_s = (np.asarray(plant.output_matrix(), dtype=float) @ self.x_s)[list(outputs)]
        self.u_s_i = self.u_s[list(inputs)]
        self._from: dict[str, int] = {}
        for link, j in config.neighbours.items():
            if link not in receives:
                raise ValueError(f"neighbours.{link}: the controller receives no link {link!r}")
            if j == i or j not in self.local.xhat:
                raise ValueError(f"neighbours.{link}: {j} is not a neighbour unit of unit {i}")
        for link in receives:
            if link in config.neighbours:
                self._from[link] = config.neighbours[link]
            elif n == 2:
                self._from[link] = 1 - i
            else:
                raise ValueError(
                    f"neighbours.{link}: with {n} units, say which unit's estimate link "
                    f"{link!r} carries"
                )
        self.sends = tuple(sends)
        aug = np.zeros((self.local.nz + len(outputs),) * 2)
        aug[: self.local.nz, : self.local.nz] = self.local.F
        aug[: self.local.nz, self.local.nz :] = self.local.G
        self._aug = aug
        self._cache: dict[float, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
        self.reset()

    @classmethod
    def from_config(
        cls,
        config: QDCLawConfig,
        *,
        loops: Sequence[str],
        plant: Any,
        tau_s: float,
        context: Any = None,
    ) -> QDCLaw:
        """Build from the scenario (``context``: :class:`controllers.registry.MultiLoopContext`
        with the loops' signals and the controller's links; ``tau_s`` is not used)."""
        if context is None:
            raise ValueError("the qdc law needs its loops' sensors and actuators (context)")
        return cls(
            config,
            loops,
            plant,
            context.signals,
            sends=context.sends,
            receives=context.receives,
        )

    # -- state --------------------------------------------------------------------------------
    def reset(self) -> None:
        """Every estimate at the operating point, time 0, measurement at the operating point."""
        self.z = np.zeros(self.local.nz)
        self._m = np.zeros(len(self._meas))
        self._t = 0.0

    def _propagate(self, t: float) -> None:
        """Flow ``dz/dt = F z + G m`` from the last call to ``t`` with ``m`` held (exact)."""
        dt = round(t - self._t, _DT_DIGITS)
        if dt < 0.0:
            raise ValueError(f"qdc unit {self.config.unit}: time went back from {self._t} to {t}")
        if dt > 0.0:
            pair = self._cache.get(dt)
            if pair is None:
                if len(self._cache) >= _CACHE_SIZE:
                    self._cache.clear()
                e = expm(self._aug * dt)
                nz = self.local.nz
                pair = (e[:nz, :nz], e[:nz, nz:])
                self._cache[dt] = pair
            self.z = pair[0] @ self.z + pair[1] @ self._m
        self._t = t

    # -- the platform's law protocol ------------------------------------------------------------
    def step(
        self, t: float, y: Mapping[str, float], r: Mapping[str, float | None]
    ) -> dict[str, float]:
        """A sample of the unit's outputs at ``t`` (``y`` by loop; set points ``r`` ignored):
        the move of every input, ``u_s + H z``."""
        self._propagate(t)
        self._m = np.array([y[lp] for lp in self._meas], dtype=float) - self.y_s
        u = self.u_s_i + self.local.H @ self.z
        return {lp: float(u[k]) for k, lp in enumerate(self._moves)}

    def transmit(self, t: float) -> list[float]:
        """The unit's estimate ``xbar_i(t)`` (deviation from the operating point), to send."""
        self._propagate(t)
        return [float(v) for v in self.z[self.local.xbar]]

    def receive(self, t: float, link: str, values: Sequence[float]) -> None:
        """The neighbour's estimate arrived on ``link`` at ``t``: reset the model of it."""
        self._propagate(t)
        sl = self.local.xhat[self._from[link]]
        if len(values) != sl.stop - sl.start:
            raise ValueError(
                f"qdc unit {self.config.unit}: link {link!r} carried {len(values)} values, "
                f"expected {sl.stop - sl.start}"
            )
        self.z[sl] = np.asarray(values, dtype=float)

    def estimate(self) -> NDArray[np.float64]:
        """The unit's observer estimate ``xbar_i`` at the last call (deviation)."""
        return self.z[self.local.xbar].copy()

    def closed_loop(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The linearized networked loop this law is part of: flow ``Acl`` and update reset
        ``Rcl`` of :func:`controllers.qdc.model.closed_loop_matrices` (the true linearization, every
        unit's controller with its embedded models). What a coordination agent analyses
        (:mod:`agents.wncsca.links`); every unit's law of one design returns the same."""
        return closed_loop_matrices(self.plant_units, self.network)

    def networked_model(self) -> tuple[LinearUnits, QDCNetwork]:
        """The true linearization and the units' controllers (what the sampled-data test of
        :mod:`agents.update_period.sampled` is built from)."""
        return self.plant_units, self.network


def _unit_index(plant: Any, k: int, unit: UnitSignals) -> tuple[list[int], list[int], list[int]]:
    out = []
    for field, names, given in (
        ("states", plant.state_names, unit.states),
        ("inputs", plant.input_names, unit.inputs),
        ("outputs", plant.output_names, unit.outputs),
    ):
        idx = []
        for name in given:
            if name not in names:
                raise ValueError(f"units[{k}].{field}: {name!r} is not one of {list(names)}")
            if name in given[: len(idx)]:
                raise ValueError(f"units[{k}].{field}: {name!r} is named twice")
            idx.append(list(names).index(name))
        out.append(idx)
    return out[0], out[1], out[2]


def _linear_units(
    plant: Any, x_s: NDArray[np.float64], u_s: NDArray[np.float64], index: list
) -> LinearUnits:
    """The linearization at ``(x_s, u_s)`` split into the units of eq. (11)."""
    A, B = plant.jacobians(x_s, u_s)
    C = np.asarray(plant.output_matrix(), dtype=float)
    return LinearUnits.from_arrays(
        [[A[np.ix_(si, sj)] for sj, _, _ in index] for si, _, _ in index],
        [B[np.ix_(si, ui)] for si, ui, _ in index],
        [C[np.ix_(yi, si)] for si, _, yi in index],
    )


def _mismatched(plant: Any, model_params: Mapping[str, float]) -> Any:
    """The plant with some parameters changed (the embedded models' plant)."""
    params = plant.params
    known = type(params).model_fields
    for name in model_params:
        if name not in known:
            raise ValueError(f"model_params.{name}: not a parameter of the plant ({sorted(known)})")
    try:
        changed = type(params).model_validate({**params.model_dump(), **model_params})
    except ValidationError as err:
        e = err.errors()[0]
        raise ValueError(f"model_params.{e['loc'][0]}: {e['msg']}") from err
    return type(plant)(changed)


def _loops_of(
    names: Sequence[str], by_loop: Mapping[str, str], verb: str, unit: int
) -> tuple[str, ...]:
    """The loop that ``verb`` (moves / measures) each signal of ``names``, in that order."""
    out = []
    for name in names:
        found = [lp for lp, s in by_loop.items() if s == name]
        if len(found) != 1:
            what = "none" if not found else f"{len(found)} ({sorted(found)})"
            raise ValueError(
                f"loops: {name!r} of unit {unit} must be {verb.removesuffix('s')}d by exactly one "
                f"of the controller's loops, found {what}: the design "
                + ("moves every input of the unit (B_i square)" if verb == "moves" else "")
                + ("observes the unit from every output" if verb == "measures" else "")
            )
        out.append(found[0])
    return tuple(out)
