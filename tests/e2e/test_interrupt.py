"""A run cut short keeps what it did (issue 19, item 4): Ctrl-C or SIGTERM stops it cleanly on
both bus engines with exit 130 and a partial summary, the history keeps every message row up to
the interruption (compared with a full run's rows), a killed clock is a fault with exit 3, and
no node outlives a ``kill -9`` of ``wncs run``."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from bus_schemas import keys
from tests.conftest import BENCHMARK, wait_until

pytestmark = pytest.mark.slow

WNCS = str(Path(sys.executable).parent / "wncs")


def _start(out: Path, engine: str, *, own_group: bool = False) -> subprocess.Popen:
    return subprocess.Popen(
        [WNCS, "run", str(BENCHMARK), "--engine", engine, "--realtime", "1.0", "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=own_group,  # its own process group, as a terminal's foreground job
    )


def _latest_t(out: Path) -> int:
    try:
        with sqlite3.connect(out / "history.sqlite") as db:
            return int(db.execute("SELECT MAX(t) FROM ticks").fetchone()[0] or 0)
    except sqlite3.Error:
        return 0


def _rows(path: Path, below: int) -> list[tuple]:
    with sqlite3.connect(path) as db:
        return db.execute(
            "SELECT round, t, key, src, seq, body FROM messages WHERE round < ? AND key != ? "
            "ORDER BY round, key, src, seq",
            (below, keys.wncsca_timing()),
        ).fetchall()


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("full") / "run"
    done = subprocess.run(
        [WNCS, "run", str(BENCHMARK), "--engine", "threads", "--out", str(out), "--quiet"],
        capture_output=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return out


@pytest.mark.parametrize(
    ("engine", "sig", "group"),
    [
        ("threads", signal.SIGINT, False),
        ("processes", signal.SIGINT, False),
        ("processes", signal.SIGTERM, False),
        # Ctrl-C at a terminal: SIGINT to the whole foreground group, the launcher's children
        # too (the router's process must not leave before the nodes have stopped through it)
        ("threads", signal.SIGINT, True),
        ("processes", signal.SIGINT, True),
    ],
)
def test_an_interrupted_run_stops_cleanly_and_keeps_its_history(
    engine, sig, group, full_run, tmp_path
):
    out = tmp_path / "run"
    proc = _start(out, engine, own_group=group)
    try:
        wait_until(lambda: _latest_t(out) >= 3_000_000, timeout=120, what="t = 3 pu")
        if group:
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted at t = " in err and "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and 3.0 <= summary["interrupted_at"] < 6.0
    with sqlite3.connect(out / "history.sqlite") as db:
        last = db.execute("SELECT MAX(round) FROM ticks").fetchone()[0]
        stop = json.loads(db.execute("SELECT value FROM meta WHERE name = 'stop'").fetchone()[0])
    assert stop["ok"] is False and "interrupted" in stop["reason"]
    kept = _rows(out / "history.sqlite", last)
    assert kept and kept == _rows(full_run / "history.sqlite", last)
    for pid in json.loads((out / "run.json").read_text())["nodes"].values():
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def test_a_killed_clock_is_a_fault_with_exit_3(tmp_path):
    out = tmp_path / "run"
    proc = _start(out, "processes")
    try:
        wait_until(lambda: _latest_t(out) >= 1_000_000, timeout=120, what="t = 1 pu")
        clock = json.loads((out / "run.json").read_text())["nodes"]["clock"]
        os.kill(clock, signal.SIGKILL)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 3, err
    assert "the clock died (SIGKILL)" in err


def test_no_node_outlives_a_killed_launcher(tmp_path):
    out = tmp_path / "run"
    proc = _start(out, "processes")
    try:
        wait_until(lambda: _latest_t(out) >= 1_000_000, timeout=120, what="t = 1 pu")
        pids = json.loads((out / "run.json").read_text())["nodes"].values()
        proc.kill()  # kill -9: the launcher cannot clean up
        proc.wait(timeout=10)

        def all_gone() -> bool:
            for pid in pids:
                try:
                    os.kill(pid, 0)
                except ProcessLookupError:
                    continue
                if Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z":
                    continue  # exited, not yet reaped by its (dead) parent's reaper
                return False
            return True

        wait_until(all_gone, timeout=15, what="the nodes to die with their launcher")
    finally:
        if proc.poll() is None:
            proc.kill()
