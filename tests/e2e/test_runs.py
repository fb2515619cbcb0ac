"""End-to-end runs of ``wncs run`` with real OS processes on a real zenoh router.

They assert on ``summary.json`` and ``history.sqlite`` only, never on wall-clock time.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import msgpack
import numpy as np
import pytest
import zenoh

from bus_schemas import keys
from core.record import summarize
from kernel.bus import open_client
from runtime.direct import simulate
from runtime.history import load_record, messages_digest
from runtime.security import DASHBOARD, credentials_of
from scenario import load_scenario
from tests.conftest import (
    BENCHMARK,
    DELAY_CASE,
    PAPER_OS_LEVEL,
    PAPER_OS_TEMPERATURE,
    SCENARIOS,
    last_tick,
    wait_until,
    write_variant,
)

TANK_RIG = SCENARIOS / "tank_rig.yaml"
WSN = SCENARIOS / "jcstr_wsn.yaml"

pytestmark = pytest.mark.slow

WNCS = [str(Path(sys.executable).parent / "wncs")]


def wncs_run(scenario: Path, out: Path, *extra: str, timeout: float = 300) -> dict:
    proc = subprocess.run(
        [*WNCS, "run", str(scenario), "--out", str(out), "--quiet", *extra],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads((out / "summary.json").read_text())


def start_run(scenario: Path, out: Path, *extra: str) -> tuple[subprocess.Popen, dict]:
    """Start ``wncs run`` and wait for its run.json to name the router endpoint."""
    proc = subprocess.Popen(
        [*WNCS, "run", str(scenario), "--out", str(out), "--quiet", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    run_file = out / "run.json"

    def announced() -> bool:
        assert proc.poll() is None, proc.communicate()
        if not run_file.exists():
            return False
        info = json.loads(run_file.read_text())
        return bool(info.get("endpoint") and info.get("nodes"))

    try:
        wait_until(announced, timeout=60, what="run.json naming the endpoint and the nodes")
    except AssertionError:
        proc.kill()
        raise
    return proc, json.loads(run_file.read_text())


def observer(info: dict, out: Path):
    """A session on the run's router that may watch it: the ``dashboard`` identity of a secure
    run (which may read the run and put only ``ops/inject``), none for an ``--insecure`` one."""
    security = out / "security"
    creds = credentials_of(security, DASHBOARD) if info.get("secure") else None
    return open_client(info["endpoint"], settings=creds)


def wait_for_virtual_time(session, info: dict, proc: subprocess.Popen, ticks: int) -> None:
    """Block until the run's clock has reached ``ticks`` (watching its ticks on the bus)."""
    reached = threading.Event()

    def on_tick(sample) -> None:
        tick = last_tick(sample)
        if tick is not None and tick.t >= ticks:
            reached.set()

    sub = session.declare_subscriber(keys.full(info["run_id"], keys.tick_log()), on_tick)
    deadline = time.monotonic() + 120
    while not reached.wait(0.5):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, f"virtual time never reached {ticks} ticks"
    sub.undeclare()


def traces(summary: dict) -> dict:
    return {name: loop["trace"] for name, loop in summary["loops"].items()}


def assert_same_traces(a: dict, b: dict, atol: float = 1e-9) -> None:
    assert a.keys() == b.keys()
    for name in a:
        for k in ("t", "y", "u"):
            x, y = np.asarray(a[name][k]), np.asarray(b[name][k])
            assert x.shape == y.shape, (name, k)
            assert np.max(np.abs(x - y), initial=0.0) <= atol, (name, k)


@pytest.fixture(scope="module")
def benchmark_run(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("benchmark")
    return out, wncs_run(BENCHMARK, out)


def test_benchmark_by_processes_matches_the_paper(benchmark_run):
    out, summary = benchmark_run
    assert summary["engine"] == "processes" and summary["scenario"] == "jcstr_benchmark"
    assert summary["loops"]["level"]["overshoot_pct"] == pytest.approx(PAPER_OS_LEVEL, abs=1.0)
    assert summary["loops"]["temperature"]["overshoot_pct"] == pytest.approx(
        PAPER_OS_TEMPERATURE, abs=1.0
    )
    for name in ("level", "temperature"):
        png = out / f"{name}.png"
        assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    assert summary["messages"]["dropped_invalid"] == {}
    s = load_scenario(BENCHMARK)
    n_samples = round(s.end_time / s.loops["level"].tau_s) + 1
    assert summary["messages"]["published"]["loop/level/meas"] == n_samples
    run = json.loads((out / "run.json").read_text())
    assert run["endpoint"].startswith("tcp/127.0.0.1:")


@pytest.mark.parametrize(
    "scenario",
    [BENCHMARK, DELAY_CASE, TANK_RIG, WSN],
    ids=["benchmark", "delay", "tank_rig", "wsn"],
)
def test_three_engines_give_the_same_traces(tmp_path, benchmark_run, scenario):
    if scenario == BENCHMARK:
        processes = benchmark_run[1]
    else:
        processes = wncs_run(scenario, tmp_path / "processes")
    threads = wncs_run(scenario, tmp_path / "threads", "--engine", "threads")
    direct = wncs_run(scenario, tmp_path / "direct", "--engine", "direct")
    assert_same_traces(traces(processes), traces(direct))
    assert_same_traces(traces(threads), traces(direct))
    # and the summary equals the in-process direct engine's
    assert_same_traces(traces(direct), traces(summarize(simulate(load_scenario(scenario)))))


def test_same_seed_gives_identical_history(tmp_path, benchmark_run):
    out1, _ = benchmark_run
    wncs_run(BENCHMARK, tmp_path / "again", "--seed", "0")
    assert messages_digest(out1 / "history.sqlite") == messages_digest(
        tmp_path / "again" / "history.sqlite"
    )


def test_invalid_messages_are_dropped_counted_and_harmless(tmp_path, benchmark_run):
    proc, info = start_run(BENCHMARK, tmp_path, "--insecure")  # the nodes' own checks
    run_id = info["run_id"]
    session = open_client(info["endpoint"])
    sensor = keys.full(run_id, keys.sensor("reactor", "H"))
    actuator = keys.full(run_id, keys.actuator("reactor", "F_out"))
    forged = []
    for round_ in (0, 10**6):
        env = {"v": 1, "run": run_id, "src": "intruder", "seq": 1, "round": round_, "t": 0}
        forged.append(msgpack.packb({**env, "body": {"value": "NaN?", "t_sampled": -1}}))
    forged.append(msgpack.packb({"v": 1, "run": run_id}))  # envelope fields missing
    stop = threading.Event()
    sent = [0]

    def pester():
        while not stop.is_set():
            for key in (sensor, actuator):
                session.put(key, b"\x00\xffnot msgpack at all")
                for raw in forged:
                    session.put(key, raw)
                sent[0] += 1
            stop.wait(0.005)

    th = threading.Thread(target=pester)
    th.start()
    try:
        out, err = proc.communicate(timeout=300)
    finally:
        stop.set()
        th.join()
        session.close()
    assert proc.returncode == 0, err
    summary = json.loads((tmp_path / "summary.json").read_text())
    dropped = summary["messages"]["dropped_invalid"]
    assert sent[0] > 0
    assert dropped.get("plant/reactor/sensor/H", 0) > 0, dropped
    assert dropped.get("plant/reactor/actuator/F_out", 0) > 0, dropped
    assert_same_traces(traces(summary), traces(benchmark_run[1]), atol=0.0)


def test_forged_control_messages_and_requests_change_nothing(tmp_path, benchmark_run):
    """From an outside client on the run's router (issue 19, item 2): a set-point request from
    another source than ``wncs inject``, one stamped with another run id, a Done, a tick (to a
    node, and in the clock's log) and a stop of another run on this run's keys. The clock and
    the nodes drop them all: the run ends normally with the clean run's traces (the set point
    of 10 is never applied)."""
    proc, info = start_run(BENCHMARK, tmp_path, "--realtime", "1.0", "--insecure")
    run_id = info["run_id"]
    session = open_client(info["endpoint"])

    def env(src: str, run: str, body: dict, round_: int = 0) -> bytes:
        head = {"v": 1, "run": run, "src": src, "seq": 7, "round": round_, "t": 0}
        return msgpack.packb({**head, "body": body})

    request = {"setpoint": {"loop": "level", "value": 10.0}}
    forged = [
        (keys.inject(), env("intruder", run_id, request)),
        (keys.inject(), env("inject", "r-other", request)),
        (keys.done("reactor"), env("reactor", "r-other", {"round": 1, "node": "reactor"})),
        (
            keys.tick_to("reactor"),
            env("clock", "r-other", {"round": 99, "t": 10**9, "expected": {}}),
        ),
        (
            keys.tick_log(),
            env("clock", "r-other", {"ticks": [{"round": 99, "t": 0, "expected": {}}]}),
        ),
        (
            keys.stop(),
            env("clock", "r-other", {"ok": False, "reason": "forged", "round": 1, "t": 0}),
        ),
    ]
    try:
        wait_for_virtual_time(session, info, proc, 2_000_000)
        for rel, raw in forged:
            session.put(keys.full(run_id, rel), raw)
        out, err = proc.communicate(timeout=300)
    finally:
        session.close()
    assert proc.returncode == 0, err
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert_same_traces(traces(summary), traces(benchmark_run[1]), atol=0.0)


def test_bad_scenario_is_refused_before_anything_starts(tmp_path):
    bad = tmp_path / "bad.yaml"
    text = BENCHMARK.read_text().replace("tau_s: 0.1", "tau_s: -0.1", 1)
    bad.write_text(text)
    out = tmp_path / "out"
    proc = subprocess.run(
        [*WNCS, "run", str(bad), "--out", str(out)], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2
    assert str(bad) in proc.stderr and "loops.level.tau_s" in proc.stderr
    assert not out.exists()  # nothing was started or written


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie is not running; reap-less children of the launcher are gone with it
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"
    except OSError:
        return False


def test_killing_a_controller_stops_the_run_naming_it(tmp_path):
    proc, info = start_run(BENCHMARK, tmp_path, "--realtime", "2.0")
    session = observer(info, tmp_path)
    try:
        wait_for_virtual_time(session, info, proc, 500_000)  # mid-run: t > 0.5 pu
        victim = info["nodes"]["level_controller"]
        os.kill(victim, signal.SIGKILL)
        killed = time.monotonic()
        out, err = proc.communicate(timeout=60)
        elapsed = time.monotonic() - killed
    finally:
        session.close()
    assert proc.returncode not in (0, None)
    assert "level_controller" in err and "round" in err, err
    assert elapsed < 10.0, f"run took {elapsed:.1f} s to stop"
    for name, pid in info["nodes"].items():
        assert not _alive(pid), f"{name} (pid {pid}) still running"


def test_liveliness_tokens_are_real(tmp_path):
    """A node's zenoh token is visible to an outside session while the run goes on."""
    proc, info = start_run(BENCHMARK, tmp_path, "--realtime", "1.0")
    session = observer(info, tmp_path)
    seen: set[str] = set()
    expected = {"clock", "reactor", "historian", "level_controller"}
    all_seen = threading.Event()

    def on_token(sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            seen.add(str(sample.key_expr).rsplit("/", 1)[-1])
            if expected <= seen:
                all_seen.set()

    try:
        sub = session.liveliness().declare_subscriber(
            keys.full(info["run_id"], keys.alive_all()), on_token, history=True
        )
        all_seen.wait(60)
        sub.undeclare()
    finally:
        session.close()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
    assert expected <= seen


def test_a_droppable_node_is_dropped_and_the_run_carries_on(tmp_path):
    """clock.may_drop: losing the temperature controller leaves its actuator held; level goes on."""
    scenario = write_variant(
        tmp_path,
        BENCHMARK,
        "droppable.yaml",
        lambda d: d.setdefault("clock", {}).update(may_drop=["temperature_controller"]),
    )
    proc, info = start_run(scenario, tmp_path / "out", "--realtime", "2.0")
    session = observer(info, tmp_path / "out")
    try:
        wait_for_virtual_time(session, info, proc, 1_000_000)
        os.kill(info["nodes"]["temperature_controller"], signal.SIGKILL)
        out, err = proc.communicate(timeout=120)
    finally:
        session.close()
    assert proc.returncode == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert list(summary["dropped_nodes"]) == ["temperature_controller"]
    level = summary["loops"]["level"]["trace"]
    temp = summary["loops"]["temperature"]["trace"]
    end = load_scenario(BENCHMARK).end_time
    assert level["t"][-1] == pytest.approx(end) and None not in level["u"]  # level ran on
    # samples were still delivered, but no move was made after the controller died
    answered = [t for t, u in zip(temp["t"], temp["u"], strict=True) if u is not None]
    assert temp["t"][-1] == pytest.approx(end) and temp["u"][-1] is None
    assert 0.9 <= answered[-1] < end  # killed once the clock reached 1.0: maybe before its move


def test_wncs_inject_reroutes_a_running_run(tmp_path):
    """A relay failure injected into a running processes run: reroute, more hops, longer delays,
    the event in summary.json; bad requests are refused before anything is sent."""

    def edit(d: dict) -> None:
        d["nodes"]["network"].update(events=[])
        d["end_time"] = 12.0  # slack for the four `wncs inject` processes on a loaded machine

    scenario = write_variant(tmp_path, WSN, "wsn.yaml", edit)
    out = tmp_path / "out"
    proc, info = start_run(scenario, out, "--realtime", "1.0")
    session = observer(info, out)
    try:
        wait_for_virtual_time(session, info, proc, 2_000_000)
        # a malformed event straight on the gateway's key: the router refuses it (the watching
        # identity may put only ops/inject), the run goes on
        session.put(keys.full(info["run_id"], keys.network_events("network")), b"\x00garbage")
        # the good request first, while the run surely goes on (a loaded machine starts the
        # `wncs inject` processes slowly); the bad ones are refused without the bus
        ok = subprocess.run(
            [*WNCS, "inject", str(out), "node_down", "node=r1"],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert ok.returncode == 0, ok.stderr
        for words, fragment in (
            (["node_down", "node=r9"], "unknown node 'r9'"),
            (["link_degraded", "a=r1", "b=r2", "prr=2"], "prr"),
            (["teleport", "node=r1"], "teleport"),
        ):
            bad = subprocess.run(
                [*WNCS, "inject", str(out), *words], capture_output=True, text=True, timeout=60
            )
            assert bad.returncode == 2 and fragment in bad.stderr, bad.stderr
        out_text, err = proc.communicate(timeout=120)
    finally:
        session.close()
    assert proc.returncode == 0, err
    summary = json.loads((out / "summary.json").read_text())
    [event] = summary["events"]
    assert event["kind"] == "node_down" and event["source"] == "injected"
    assert 2.0 <= event["t"] < 12.0
    configs = summary["network"]["configurations"]
    assert (
        configs[0]["paths"]["level.sensor"]["hops"] == 3
        and configs[-1]["paths"]["level.sensor"]["hops"] == 4
    )
    assert "events/network" not in summary["messages"]["dropped_invalid"]  # it never got there

    level = load_record(out / "history.sqlite", load_scenario(scenario), engine="processes")
    level = level.loops["level"]
    t_event = event["t"] * 1e6
    before = [d - k for d, k in zip(level.t, level.t_sampled, strict=True) if k < t_event]
    after = [d - k for d, k in zip(level.t, level.t_sampled, strict=True) if k > t_event]
    assert np.mean(after) > np.mean(before)  # 4 hops (0.23 pu) against 3 (0.17 pu)
