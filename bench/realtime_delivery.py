"""Real-time delivery jitter: at ``--realtime 1.0``, how late do delayed WSN samples arrive?

Runs ``scenarios/jcstr_wsn.yaml`` (both sensor paths over the WSN, random per-hop delays), made
long enough for about 500 delivered samples, paced at 1 s per pu, and listens on the bus with its
own session. Each sample delivered on ``loop/<l>/meas`` carries its virtual delivery time ``t``;
its scheduled wall time is ``wall(first tick) + t * seconds_per_unit``. The script prints the
median and p99 of (actual arrival - scheduled), in ms (aim: p99 below 2 ms). No test asserts it.

    .venv/bin/python bench/realtime_delivery.py [--engine processes|threads] [--samples N]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import yaml

from bus_schemas import Sample, codec, keys
from kernel.bus import open_client
from kernel.security import SECURITY_DIR
from runtime.launcher import launch
from runtime.security import DASHBOARD, credentials_of

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_wsn.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engine", default="processes", choices=("processes", "threads"))
    parser.add_argument("--samples", type=int, default=500)
    parser.add_argument("--seconds-per-unit", type=float, default=1.0)
    args = parser.parse_args()
    data = yaml.safe_load(SCENARIO.read_text())
    end = args.samples / 20.0 + 1.0  # two loops sampled every 0.1 pu
    data["end_time"] = end
    data["nodes"]["network"]["events"] = []
    data["setpoints"] = []
    spu = args.seconds_per_unit
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "wsn.yaml"
        path.write_text(yaml.safe_dump(data))
        out = Path(tmp) / "out"
        result: dict = {}
        runner = threading.Thread(
            target=lambda: result.update(r=launch(path, out, engine=args.engine, realtime=spu))
        )
        runner.start()
        while not (out / "run.json").exists() or not json.loads((out / "run.json").read_text()).get(
            "endpoint"
        ):
            runner.join(0.02)
        info = json.loads((out / "run.json").read_text())
        # the run is secure: watch it as the dashboard does (it may read the whole run)
        session = open_client(
            info["endpoint"], settings=credentials_of(out / SECURITY_DIR, DASHBOARD)
        )
        first_tick: list[float] = []
        arrivals: list[tuple[float, int]] = []

        def on_tick(sample) -> None:
            if not first_tick:
                first_tick.append(time.monotonic())

        def on_meas(sample) -> None:
            now = time.monotonic()
            env = codec.decode(sample.payload.to_bytes(), Sample)
            arrivals.append((now, env.t))

        session.declare_subscriber(keys.full(info["run_id"], keys.tick_log()), on_tick)
        session.declare_subscriber(keys.full(info["run_id"], "loop/*/meas"), on_meas)
        runner.join()
        session.close()
        if result["r"].code != 0:
            raise SystemExit(result["r"].error)
    t0 = first_tick[0]
    # skip the first second: the first tick's arrival is our only reference for wall time
    late = np.array(
        [(now - (t0 + t / 1e6 * spu)) * 1e3 for now, t in arrivals if t / 1e6 * spu > 1.0]
    )
    jitter = late - np.median(late)  # the reference (first tick seen here) has its own offset
    print(
        f"{len(late)} delayed deliveries at {spu:g} s/pu ({args.engine}): lateness against the "
        f"first tick median {np.median(late):.3f} ms; around that median: p99 "
        f"{np.percentile(jitter, 99):.3f} ms, max {jitter.max():.3f} ms (aim: p99 below 2 ms)"
    )


if __name__ == "__main__":
    main()
