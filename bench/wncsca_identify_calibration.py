"""Is the agent's identified uncertainty honest? (issue 35, acceptance: "identified parameters lie
within their stated 95 % interval in at least 90 % of seeds").

The demo's plant on the jitter network (``scenarios/jcstr_wncs_jitter.yaml``) with the true
reactor's ``U`` 10 % above the agent's belief and measurement noise on both sensors (level 0.002
pu, temperature 0.05 C). For each seed, an identification experiment as the agent runs it
(:class:`agents.wncsca.experiment.Experiment`: generalized binary noise on both set points for
8 pu, at the identification period) runs on the direct engine without an agent; the agent's fit
(:func:`agents.wncsca.identification.identify`) sees only the delivered samples and their delays.
Printed per seed: the estimate, its stated 95 % half-width with the bootstrap covariance the
agent states and with the plain Gauss-Newton one, and whether the truth lies inside; then each
covariance's coverage over the seeds. Measured (20 seeds, period 0.05 pu): bootstrap 18/20,
Gauss-Newton 12/20 (about 6 s a seed, the bootstrap's 20 refits most of it).

    python bench/wncsca_identify_calibration.py [--seeds 20] [--period 0.05]
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

from agents.wncsca.config import IdentifyConfig
from agents.wncsca.experiment import Experiment
from agents.wncsca.identification import Identified, identify
from core.time import to_ticks
from runtime.direct import loop_model, simulate
from scenario import Scenario, load_scenario

JITTER = "scenarios/jcstr_wncs_jitter.yaml"
BELIEVED_U = 0.1713
TRUE_U = BELIEVED_U * 1.1
NOISE = {"H": 0.002, "T": 0.05}
EXPERIMENT = IdentifyConfig(
    params={"reactor": ["U"]},
    duration=8.0,
    clock=0.4,
    amplitude={"level": 0.02, "temperature": 1.0},
)


def experiment_of(seed: int, period: float) -> tuple[Experiment, Any]:
    """The agent's experiment for ``seed`` run on the true plant, without an agent: its plan
    and the run's record."""
    base = load_scenario(JITTER)
    exp = Experiment.plan(
        EXPERIMENT,
        {n: lp.setpoint for n, lp in base.loops.items() if lp.setpoint is not None},
        {n: period for n in base.loops},
        seed,
        "startup",
    )
    data = base.model_dump()
    del data["nodes"]["wncsca"]
    data["modes"], data["end_time"], data["seed"] = [], EXPERIMENT.duration, seed
    data["nodes"]["reactor"]["params"]["U"] = TRUE_U
    data["nodes"]["reactor"]["noise"] = dict(NOISE)
    for loop in data["loops"].values():
        loop["tau_s"] = period
    data["setpoints"] = [
        {"t": t, "loop": loop, "value": v} for t, loop, v in exp.changes if t < exp.end
    ]
    return exp, simulate(Scenario.model_validate(data))


def fit_of(seed: int, period: float) -> Identified:
    """The agent's fit of ``U`` to what the network delivered in ``seed``'s experiment."""
    exp, rec = experiment_of(seed, period)
    for name, lp in rec.loops.items():
        for t, ts, y in zip(lp.t, lp.t_sampled, lp.y, strict=True):
            exp.record(name, y, ts, t)
    assert exp.off_grid == 0, exp.off_grid
    model = loop_model(load_scenario(JITTER))
    return identify(model, {"reactor": ["U"]}, exp.seen({}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--period", type=float, default=0.05, help="identification period, pu")
    args = ap.parse_args()
    assert to_ticks(args.period) > 0
    inside = {"bootstrap": 0, "gauss-newton": 0}
    t0 = time.perf_counter()
    print(f"true U {TRUE_U:.5f}, believed {BELIEVED_U}; period {args.period} pu")
    print(f"{'seed':>4} {'U':>9} {'+-95% boot':>11} {'+-95% GN':>10}  inside (bootstrap, GN)")
    for seed in range(args.seeds):
        fit = fit_of(seed, args.period)
        u = fit.params["reactor"]["U"]
        boot = 1.96 * fit.std("reactor", "U")
        plain = 1.96 * math.sqrt(float(fit.gauss_newton[0, 0]))
        ok = (abs(u - TRUE_U) <= boot, abs(u - TRUE_U) <= plain)
        inside["bootstrap"] += ok[0]
        inside["gauss-newton"] += ok[1]
        print(f"{seed:4d} {u:9.5f} {boot:11.5f} {plain:10.5f}  {ok}")
    for name, n in inside.items():
        print(f"coverage of the stated 95 % interval, {name}: {n}/{args.seeds}")
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
