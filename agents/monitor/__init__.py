"""Control-loop performance monitor, numerical core (no bus), seed 004.

From routine closed-loop data of a simple feedback loop and the process delays alone: the loop's
Harris (minimum-variance) index with its uncertainty, and whether cascade control would pay off
and with which secondary measurement (Lakshminarayanan et al. 2006, variance decomposition
1a/1b/2a/2b).

* :mod:`agents.monitor.assess` -- :func:`~agents.monitor.assess.assess` (arrays) and
  :func:`~agents.monitor.assess.assess_csv` (historian export), returning an
  :class:`~agents.monitor.assess.AssessmentResult` with ``to_dict()`` for JSON.
* :mod:`agents.monitor.harris` -- :func:`~agents.monitor.harris.harris_index`.
* :mod:`agents.monitor.decomposition` -- :func:`~agents.monitor.decomposition.decompose`, the
  cascade prediction band and :func:`~agents.monitor.decomposition.rank_secondaries`.
* :mod:`agents.monitor.timeseries` -- VAR/AR fitting (least squares, Yule-Walker, AIC/BIC).
* :mod:`agents.monitor.routine_data` -- :func:`~agents.monitor.routine_data.load_routine_csv`.
* :mod:`agents.monitor.errors` -- :class:`~agents.monitor.errors.DataError` (column, row) and
  :class:`~agents.monitor.errors.IdentificationError` (reason).
* :mod:`agents.monitor.config` -- analysis settings and the monitor node's configuration
  (``kind: monitor`` in scenarios).
* :mod:`agents.monitor.columns` -- the columns of a run by name (``LOOP``, ``LOOP.sp``,
  ``PLANT.STATE``).
* :mod:`agents.monitor.run_data` -- a loop's routine data from a run's messages (live or
  recorded): alignment, sliding window.
* :mod:`agents.monitor.behaviour` -- the monitor on the bus (``monitor/assessment/<loop>``).
* :mod:`agents.monitor.report` -- the text of an assessment; :mod:`agents.monitor.audit` and
  :mod:`agents.monitor.audit_report` -- the plant-wide audit and its tables. ``wncs assess``
  itself (:mod:`runtime.assess`) and the reading of run directories for it
  (:mod:`runtime.run_files`) are in the application layer.
"""
