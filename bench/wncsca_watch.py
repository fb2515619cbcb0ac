"""How well the model watch tells a fitting model from a fouled plant (issue 35, item 4).

The jitter scenario's reactor runs the paper's two steps (level 0.70 -> 0.75 at 1.8, temperature
52 -> 56 at 2.4) at the periods the agent assigns on it (level 0.175, temperature 0.075 pu), on
the direct engine without an agent, noisy sensors (0.002 pu, 0.05 C), over ``--seeds`` network
seeds; the agent's model (the scenario's reactor, U = 0.1713) scores the window after the steps
as its model watch would (:func:`agents.wncsca.watch.score`, 20 replays). Printed per true U
(the model's, and fouled by 5 to 25 %): the window scores' mean, spread and extremes, the share
of windows that alone flag the model (a score past ``h + k`` = 5.5), and the windows the CUSUM
needs at the median score if the misfit persists (``ceil(h / (z - k))``).

    python bench/wncsca_watch.py [--seeds 20] [--jobs 2]
"""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from agents.wncsca.config import WatchConfig
from agents.wncsca.watch import score
from agents.wncsca.window import Window
from runtime.direct import loop_model, simulate
from scenario import Scenario, load_scenario

__all__ = ["window_of", "main"]

JITTER = "scenarios/jcstr_wncs_jitter.yaml"
U = 0.1713
FOULED = (1.0, 0.95, 0.90, 0.85, 0.75)
PERIODS = {"level": 0.175, "temperature": 0.075}
STEPS = ((1.8, "level", 0.75), (2.4, "temperature", 56.0))
END = 1.8 + 8.0
SIGMA = {"level": 0.002, "temperature": 0.05}


def window_of(seed: int, u: float) -> Window:
    """The window after the steps of one run, as the agent keeps it."""
    data = load_scenario(JITTER).model_dump()
    del data["nodes"]["wncsca"]
    data["modes"], data["end_time"], data["seed"] = [], END, seed
    data["nodes"]["reactor"]["params"]["U"] = u
    data["nodes"]["reactor"]["noise"] = {"H": SIGMA["level"], "T": SIGMA["temperature"]}
    for loop, period in PERIODS.items():
        data["loops"][loop]["tau_s"] = period
    data["setpoints"] = [{"t": t, "loop": lp, "value": v} for t, lp, v in STEPS]
    rec = simulate(Scenario.model_validate(data))
    w = Window(
        t0=0.0,
        since=STEPS[0][0],
        end=END,
        base={"level": 0.70, "temperature": 52.0},
        changes=STEPS,
        periods=PERIODS,
    )
    for loop, lp in rec.loops.items():
        for t, ts, y in zip(lp.t, lp.t_sampled, lp.y, strict=True):
            w.record(loop, y, ts, t)
    return w


def _z(job: tuple[int, float]) -> float:
    seed, factor = job
    model = loop_model(load_scenario(JITTER))
    s = score(model, window_of(seed, factor * U), {}, SIGMA, 0.0, 20, seed, 0)
    assert s is not None
    return s.z


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    cfg = WatchConfig()
    t0 = time.perf_counter()
    jobs = [(seed, f) for f in FOULED for seed in range(args.seeds)]
    with ProcessPoolExecutor(args.jobs) as pool:
        zs = list(pool.map(_z, jobs))
    print(
        f"model U {U}; {args.seeds} network seeds; CUSUM h = {cfg.threshold}, k = {cfg.allowance}"
    )
    print(
        f"{'true U':>14} {'mean z':>8} {'sd':>6} {'min':>7} {'max':>7} "
        f"{'flag at once':>13} {'windows to flag':>16}"
    )
    for i, f in enumerate(FOULED):
        z = np.asarray(zs[i * args.seeds : (i + 1) * args.seeds])
        once = float(np.mean(z > cfg.threshold + cfg.allowance))
        med = float(np.median(z))
        drift = med - cfg.allowance
        windows = f"{math.ceil(cfg.threshold / drift)}" if drift > 0 else "never"
        label = f"{f * U:.4f} ({100 * (f - 1):+.0f} %)"
        print(
            f"{label:>14} {z.mean():8.2f} {z.std(ddof=1):6.2f} {z.min():7.2f} {z.max():7.2f} "
            f"{100 * once:12.0f}% {windows:>16}"
        )
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
