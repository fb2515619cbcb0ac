"""The WNCS platform from Python (notebooks, scripts): load, vary, run, read, linearise.

::

    import wncs

    sc = wncs.load("scenarios/jcstr_benchmark.yaml")
    result = wncs.run(wncs.with_values(sc, {"loops.level.tau_s": 0.2}))
    result.loops["level"].to_pandas()
    result.plot()
    wncs.linearized_loop(sc, "level").closed        # a control.StateSpace

See ``docs/notebook.md`` for a worked example (run by the test suite).
"""

from __future__ import annotations

from importlib.metadata import version as _version

from core.errors import ConfigError
from wncs.api import LoopResult, PlantResult, Result, load, open_run, run, sweep, with_values
from wncs.linear import LinearLoop, linearized_loop

__all__ = [
    "ConfigError",
    "load",
    "with_values",
    "run",
    "open_run",
    "sweep",
    "Result",
    "LoopResult",
    "PlantResult",
    "LinearLoop",
    "linearized_loop",
    "__version__",
]

__version__ = _version("wncs")
