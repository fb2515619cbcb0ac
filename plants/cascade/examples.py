"""The example processes of seed 004 (ours, in the spirit of its Examples 1-3; 1 sample = 1 min).

The paper's Examples 1-3 print their transfer functions as images that are not in the seed text;
:data:`EXAMPLE_1`, :data:`EXAMPLE_2`, :data:`EXAMPLE_3` are **ours**, built in their spirit from
first-order stages ``K e^(-theta s)/(tau s + 1)`` sampled with a zero-order hold (1 sample =
1 min, so a stage's delay is ``theta + 1`` samples), with unit gains:

* ``EXAMPLE_1`` -- cascade helps a lot (the paper's Example 1: 1b and 2b about 65 %): secondary
  ``tau = 2``, ``theta = 0`` (``d2 = 1``); primary ``tau = 8``, ``theta = 4`` (``d1 = 5``); a
  strong drifting secondary disturbance ``0.3 a2/((1 - 0.5 q^-1)(1 - 0.97 q^-1))`` and a weaker
  primary one ``0.2 a1/(1 - 0.97 q^-1)``: 1b + 2b are about 70 % of the variance.
* ``EXAMPLE_2`` -- cascade helps little (the paper's Example 2, a packed-bed reactor with
  preheater): similar time constants (``tau = 2`` and ``5``), much longer primary dead time
  (``d1 = 9``, ``d2 = 1``), a slowly drifting primary disturbance
  ``0.3 a1/((1 - 0.8 q^-1)(1 - 0.98 q^-1))`` and a weak secondary one: 2a is about half of the
  variance, 1b + 2b almost nothing.
* ``EXAMPLE_3`` -- two candidate secondaries ``u -> y3 -> y2 -> y1`` (the paper's Example 3,
  Case 3): ``y3`` and ``y2`` with ``tau = 2``, ``theta = 0``; ``y1`` with ``tau = 8``,
  ``theta = 4``; the strongest disturbance ``a2`` enters at ``y2``, downstream of ``y3``: ``y2``
  sees it before the primary does (``d1 = 5``, ``d2 = 2``), ``y3`` never sees it (``d1 = 6``,
  ``d2 = 1``).

The paper's Example 2 disturbance is non-stationary; ours drift with poles 0.97-0.98 instead,
because an integrated disturbance at the primary makes ``u`` and every upstream measurement
drift without bound, and a non-stationary secondary has no autoregressive model
(``unstable_model``). The measurement noise is the paper's 5 %: ``meas_noise_std`` is 5 % of the
standard deviation of each noise-free output under the variance-optimal SFB PI
(:func:`with_measurement_noise`; ``bench/monitor_examples.py --retune`` recomputes it), and the
same absolute sensors serve the cascade. The controller settings are in
:mod:`controllers.cascade.tuning` (:data:`~controllers.cascade.tuning.EXAMPLE_SFB`,
:data:`~controllers.cascade.tuning.EXAMPLE_CASCADE`).
"""

from __future__ import annotations

from plants.cascade.model import CascadeProcessConfig, StageConfig, foptd_stage

__all__ = ["EXAMPLE_1", "EXAMPLE_2", "EXAMPLE_3", "EXAMPLES"]

_Row = tuple[str, float, float, float, float, float, float]
"""``(name, tau, dead_time, noise_pole, drift_pole, noise_std, meas_noise_std)`` of a stage."""


_FIELDS = ("tau", "dead_time", "noise_pole", "drift_pole", "noise_std", "meas_noise_std")


def _stage(row: _Row) -> StageConfig:
    """A unit-gain first-order stage of an example (:func:`~plants.cascade.model.foptd_stage`)."""
    name, *values = row
    return foptd_stage(name, gain=1.0, **dict(zip(_FIELDS, values, strict=True)))


def _example(description: str, *rows: _Row) -> CascadeProcessConfig:
    """The chain of ``rows`` (a stage each, from ``u`` to the primary)."""
    return CascadeProcessConfig(description=description, stages=tuple(_stage(r) for r in rows))


# stage: (name, tau, dead_time, noise_pole, drift_pole, noise_std, meas_noise_std)
EXAMPLE_1 = _example(
    "cascade helps a lot: fast secondary, slow delayed primary, strong a2",
    ("y2", 2.0, 0.0, 0.5, 0.97, 0.3, 0.0957),
    ("y1", 8.0, 4.0, 0.0, 0.97, 0.2, 0.0559),
)

EXAMPLE_2 = _example(
    "cascade helps little: similar time constants, long primary dead time, "
    "drifting primary disturbance",
    ("y2", 2.0, 0.0, 0.5, 0.0, 0.1, 0.334),
    ("y1", 5.0, 8.0, 0.8, 0.98, 0.3, 0.213),
)

EXAMPLE_3 = _example(
    "two candidate secondaries u -> y3 -> y2 -> y1, strong a2 at y2",
    ("y3", 2.0, 0.0, 0.5, 0.97, 0.2, 0.144),
    ("y2", 2.0, 0.0, 0.5, 0.97, 0.3, 0.132),
    ("y1", 8.0, 4.0, 0.0, 0.97, 0.4, 0.0934),
)

EXAMPLES: dict[str, CascadeProcessConfig] = {
    "example_1": EXAMPLE_1,
    "example_2": EXAMPLE_2,
    "example_3": EXAMPLE_3,
}
