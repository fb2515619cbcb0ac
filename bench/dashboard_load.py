"""What the dashboard costs a run, and how many samples a second it keeps up with (issue 18).

1. Overhead: the demo (``scenarios/jcstr_wncs.yaml``, processes engine) run without and with
   ``--dashboard`` and a page attached (a WebSocket client reading every message until the run
   has finished); the run's own wall time (``summary.json``), median of ``--repeat`` runs each,
   alternated. Target: at most 10 % longer with the dashboard.
2. Throughput: a history of ``--samples`` delivered samples and moves written the way the
   historian writes it, read by the dashboard (feed, view, the JSON for the page) in batches of
   one poll. Target: at least 2000 samples a second.

    .venv/bin/python bench/dashboard_load.py [--repeat 3] [--samples 200000]
"""

from __future__ import annotations

import argparse
import json
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from websockets.sync.client import connect

from bus_schemas import codec, keys
from dashboard.server import Dashboard
from runtime import history
from runtime.launcher import SCENARIO_FILE
from scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "scenarios" / "jcstr_wncs.yaml"
WNCS = str(Path(sys.executable).parent / "wncs")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _page(url: str, seen: dict[str, int]) -> None:
    """A page: read every message until the run has finished."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        try:
            ws = connect(url, max_size=None)
            break
        except OSError:
            time.sleep(0.05)
    else:
        return
    with ws:
        for text in ws:
            msg = json.loads(text)
            seen["messages"] = seen.get("messages", 0) + 1
            seen["records"] = seen.get("records", 0) + sum(
                len(r) for r in msg.get("append", {}).values()
            )
            if msg["type"] == "finished":
                return


def _walls(out: Path) -> tuple[float, float]:
    """The run's wall time and its run phase (first tick to stop), from its summary."""
    summary = json.loads((out / "summary.json").read_text())
    return summary["wall_s"], summary["phases_s"]["run"]


def run_once(out: Path, dashboard: bool) -> tuple[tuple[float, float], dict[str, int]]:
    cmd = [WNCS, "run", str(DEMO), "--out", str(out), "--force", "--quiet"]
    seen: dict[str, int] = {}
    if not dashboard:
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        return _walls(out), seen
    port = _free_port()
    log = out.with_suffix(".log")
    proc = subprocess.Popen(
        [*cmd, "--dashboard", str(port)], stdout=log.open("w"), stderr=subprocess.STDOUT
    )
    page = threading.Thread(target=_page, args=(f"ws://127.0.0.1:{port}/ws", seen))
    page.start()
    while proc.poll() is None and "shows the finished run" not in log.read_text():
        time.sleep(0.05)
    page.join(60)
    proc.send_signal(signal.SIGINT)
    proc.wait(60)
    return _walls(out), seen


def overhead(repeat: int) -> None:
    without: list[tuple[float, float]] = []
    with_: list[tuple[float, float]] = []
    seen: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeat):
            without.append(run_once(Path(tmp) / "plain", False)[0])
            walls, seen = run_once(Path(tmp) / "watched", True)
            with_.append(walls)
    print(f"demo run, processes engine, median of {repeat} (wall s / run phase s):")
    for name, runs in (("without dashboard", without), ("with dashboard and page", with_)):
        listed = ", ".join(f"{w:.2f}/{r:.2f}" for w, r in runs)
        print(
            f"  {name:<24} {statistics.median(w for w, _ in runs):7.2f} / "
            f"{statistics.median(r for _, r in runs):5.2f}   ({listed})"
        )
    wall = statistics.median(w for w, _ in with_) / statistics.median(w for w, _ in without)
    run = statistics.median(r for _, r in with_) / statistics.median(r for _, r in without)
    print(
        f"  ratio with/without: wall {wall:.3f}, run phase {run:.3f} (target <= 1.10); the "
        f"page got {seen.get('messages', 0)} messages, {seen.get('records', 0)} records"
    )


def throughput(samples: int) -> None:
    scenario = load_scenario(DEMO)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        (out / "run.json").write_text(json.dumps({"run_id": "rbench", "engine": "threads"}))
        (out / SCENARIO_FILE).write_text(DEMO.read_text())
        db = history.connect(out / "history.sqlite", create=True)
        rows = []
        for i in range(samples // 2):
            t = 1000 * (i + 1)
            for key, body in (
                (keys.meas("level"), {"value": 0.7 + 1e-6 * i, "t_sampled": t - 500}),
                (keys.move("level"), {"value": 9.69, "t_computed": t}),
            ):
                rows.append((i, t, key, "n", i, codec.pack_mapping(body)))
        db.executemany(
            "INSERT INTO messages (round, t, key, src, seq, body) VALUES (?, ?, ?, ?, ?, ?)", rows
        )
        db.commit()
        db.close()
        t0 = time.perf_counter()
        dash = Dashboard(out)  # reads the whole history, as for a replay
        dt = time.perf_counter() - t0
    assert dash.view.rows == len(rows), (dash.view.rows, len(rows))
    print(
        f"throughput: {len(rows)} samples and moves read, checked, turned into records and "
        f"JSON in {dt:.2f} s: {len(rows) / dt:,.0f} samples/s (target >= 2000); "
        f"{len(scenario.loops)} loops"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--samples", type=int, default=200_000)
    args = parser.parse_args()
    throughput(args.samples)
    overhead(args.repeat)


if __name__ == "__main__":
    main()
