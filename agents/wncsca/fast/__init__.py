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
  kept), its law executed sample by sample as the controller node executes it
  (:mod:`agents.wncsca.laws`: the PI of :mod:`controllers.pi` or seed 002's 2-DOF laws; the
  integral rule, output limits, clamping anti-windup, the start rule, the feedforward and set
  point in force at each execution);
* the other loops of the same plant are closed in continuous time: their law's linear form
  (:class:`agents.wncsca.laws.LinearForm`, about the stretch's set point) acts on their output
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

The package, one concept a module: :mod:`~agents.wncsca.fast.lti` (Padé delays, the modal form,
``phi1``, the matrix exponentials), :mod:`~agents.wncsca.fast.predictor` (the linear predictor
of the test's overshoots), :mod:`~agents.wncsca.fast.grid` (the candidate periods and the curves
walked along them), :mod:`~agents.wncsca.fast.solver` (the search, verified on the non-linear
model: :func:`fast_periods`).
"""

from agents.wncsca.fast.lti import phi1
from agents.wncsca.fast.predictor import LinearPredictor
from agents.wncsca.fast.solver import OBJECTIVES, energy_rate, fast_periods

__all__ = ["OBJECTIVES", "LinearPredictor", "energy_rate", "fast_periods", "phi1"]
