"""A run's dashboard never outlives the run (issue 41, item 6): ``kill -9`` of ``wncs run
--dashboard`` and the dashboard it started stops serving (it dies with its parent)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from tests.conftest import SCENARIOS, kill_group, wait_until

pytestmark = pytest.mark.slow

WNCS = str(Path(sys.executable).parent / "wncs")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _serving(port: int) -> bool:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2) as answer:
            return bool(answer.status == 200)
    except (urllib.error.URLError, OSError):
        return False


def test_killing_the_run_ends_its_dashboard(tmp_path):
    port = _free_port()
    run = subprocess.Popen(
        [
            WNCS,
            "run",
            str(SCENARIOS / "jcstr_benchmark.yaml"),
            "--out",
            str(tmp_path / "run"),
            "--engine",
            "threads",
            "--realtime",
            "1.0",
            "--dashboard",
            str(port),
            "--quiet",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        wait_until(lambda: _serving(port), timeout=120, what="the run's dashboard", interval=0.2)
        assert run.poll() is None  # the run goes on (4 pu in real time)
        os.kill(run.pid, signal.SIGKILL)
        run.wait(timeout=30)
        wait_until(lambda: not _serving(port), timeout=30, what="its dashboard to stop")
    finally:
        kill_group(run)
