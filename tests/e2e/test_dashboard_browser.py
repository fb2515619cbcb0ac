"""The dashboard in a real browser (Playwright driving Debian's chromium): the demo run with
``wncs run --dashboard`` (processes engine, paced at real time), the page loaded while it goes
on, a loop's trend gaining points, "node down" pressed on the relay the demo fails (r1), the
agent's rejection of the slow route and the accepted alternative appearing in the timeline,
well before the scenario's own failure at 24 pu; a screenshot saved under the run directory.

Chromium comes from Debian (``make test`` installs the package); Playwright cannot download
its own browsers here, so it is launched with ``executable_path``.
"""

from __future__ import annotations

import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
from pathlib import Path

import msgpack
import pytest
from playwright.sync_api import sync_playwright

from bus_schemas import keys
from tests.conftest import SCENARIOS, kill_group, wait_until

pytestmark = pytest.mark.slow

WNCS = str(Path(sys.executable).parent / "wncs")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_demo_run_watched_and_acted_on_in_a_browser(tmp_path):
    chromium = shutil.which("chromium")
    assert chromium, "Debian's chromium is not installed (make test installs it)"
    out = tmp_path / "demo"
    port = _free_port()
    log = tmp_path / "wncs_run.log"
    run = subprocess.Popen(
        [
            WNCS,
            "run",
            str(SCENARIOS / "jcstr_wncs.yaml"),
            "--out",
            str(out),
            "--realtime",
            "0.6",
            "--dashboard",
            str(port),
            "--quiet",
        ],
        stdout=log.open("w"),
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # its group: what is left of it is killed at the end
    )
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": 1600, "height": 1250})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))

            def loaded() -> bool:
                try:
                    page.goto(f"http://127.0.0.1:{port}/", timeout=2000)
                    return True
                except Exception:  # the server is not up yet
                    return False

            wait_until(loaded, timeout=60, what="the dashboard page", interval=0.3)
            page.wait_for_function("() => window.wncs && window.wncs.live", timeout=60_000)
            page.wait_for_function("() => window.wncs.points('level') > 0", timeout=60_000)
            first = page.evaluate("() => window.wncs.points('level')")
            page.wait_for_function(
                f"() => window.wncs.points('level') > {first} + 20", timeout=60_000
            )  # the trend gains points while the run goes on
            t_pressed = page.evaluate("() => window.wncs.latest")
            assert t_pressed < 20, "pressed too late to tell the button's effect from 24 pu's"
            page.select_option("#node", "r1")
            page.click("#btn-node-down")
            page.wait_for_selector("#messages li.ack", timeout=20_000)
            page.wait_for_function(
                """() => {
                    const d = window.wncs.timeline().filter((r) => r.kind === 'decision' &&
                        r.subject === 'proposal' && r.t > 0);
                    return d.length >= 2;
                }""",
                timeout=60_000,
            )
            decisions = page.evaluate(
                """() => window.wncs.timeline().filter((r) => r.kind === 'decision' &&
                    r.subject === 'proposal' && r.t > 0)"""
            )
            assert [d["verdict"] for d in decisions[:2]] == ["reject", "accept"]
            assert all(d["t"] < 24.0 for d in decisions[:2])
            assert "delay" in decisions[0]["reasons"][0]
            # what the page shows: the rejection in red, the relay marked down
            assert page.locator("#timeline li.reject").count() >= 1
            page.wait_for_function(
                "() => document.querySelector('#timeline').textContent.includes('alternative')",
                timeout=30_000,
            )
            page.wait_for_timeout(500)
            page.screenshot(path=str(out / "dashboard.png"), full_page=True)
            # bad input on the socket: an error on the page, nothing sent
            page.evaluate("() => window.wncs.send('{not json')")
            page.wait_for_function(
                "() => [...document.querySelectorAll('#messages li.error')]"
                ".some((li) => li.textContent.includes('not JSON'))",
                timeout=20_000,
            )
            # the run ends; the page turns into a replay with a time slider
            page.wait_for_function("() => window.wncs.finished !== null", timeout=120_000)
            everything = page.evaluate("() => window.wncs.timeline().length")
            page.eval_on_selector(
                "#slider", "(e) => { e.value = 10; e.dispatchEvent(new Event('input')); }"
            )
            shown = page.evaluate("() => window.wncs.timeline().map((r) => r.t)")
            assert page.evaluate("() => window.wncs.cursor") == 10
            assert shown and max(shown) <= 10 and len(shown) < everything
            page.select_option("#speed", "10")
            page.click("#btn-play")
            page.wait_for_function("() => window.wncs.cursor > 12", timeout=20_000)
            assert not errors, errors
            browser.close()
    finally:
        # the run ends on its own; its dashboard then shows the finished run until Ctrl-C
        try:
            wait_until(
                lambda: run.poll() is not None or "shows the finished run" in log.read_text(),
                timeout=120,
                what="the run's end (its dashboard showing the finished run)",
                interval=0.2,
            )
        finally:
            run.send_signal(signal.SIGINT)
            try:
                run.wait(timeout=60)
            finally:
                kill_group(run)  # a failed test leaves no run, router or dashboard serving
    assert run.returncode == 0, log.read_text()
    assert (out / "dashboard.png").stat().st_size > 10_000
    with sqlite3.connect(out / "history.sqlite") as db:
        rows = db.execute(
            "SELECT t, body FROM messages WHERE key = ? ORDER BY id",
            (keys.network_events("network"),),
        ).fetchall()
    [(t, body)] = rows
    assert msgpack.unpackb(body)["event"] == {"type": "node_down", "node": "r1"}
    assert t / 1e6 >= t_pressed
