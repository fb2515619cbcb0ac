"""``wncs dashboard RUN_DIR`` and the dashboard ``wncs run --dashboard`` starts beside a run.

The dashboard serves on 127.0.0.1 unless ``--host`` says otherwise: anyone who can reach the
page can put requests into the run, so another interface is served only when asked, with a
warning.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

from dashboard.server import Dashboard, serve
from kernel.lifetime import die_with_parent
from runtime.security import is_loopback_host

__all__ = ["DEFAULT_PORT", "add_arguments", "port_number", "run", "spawn"]

DEFAULT_PORT = 8765


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dir", metavar="RUN_DIR", help="run directory (live or finished)")
    parser.add_argument(
        "--port",
        type=port_number,
        default=DEFAULT_PORT,
        help=f"port (default {DEFAULT_PORT}; 0: any)",
    )
    parser.add_argument(
        "--host", default="127.0.0.1", help="interface to serve on (default 127.0.0.1)"
    )
    parser.add_argument(
        "--poll", type=float, default=0.1, metavar="SECONDS", help="history poll period"
    )


def port_number(text: str) -> int:
    """A TCP port (0..65535; 0: any free one), for argparse."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"not a port number: {port} (0..65535)")
    return port


def run(args: argparse.Namespace) -> int:
    """Serve the dashboard of ``args.dir`` until interrupted."""
    dashboard = Dashboard(Path(args.dir), poll_s=args.poll)
    if not is_loopback_host(args.host):
        print(
            f"wncs dashboard: warning: serving on {args.host}: anyone who reaches this port can "
            "watch the run and put requests into it",
            file=sys.stderr,
        )

    def ready(url: str) -> None:
        what = "live run" if dashboard.live else "finished run (replay)"
        print(f"dashboard of the {what} {args.dir}: {url}", flush=True)

    try:
        serve(dashboard, host=args.host, port=args.port, on_ready=ready)
    except KeyboardInterrupt:
        pass
    return 0


def spawn(run_dir: Path, port: int) -> subprocess.Popen[bytes]:
    """Start ``wncs dashboard RUN_DIR --port PORT`` as a child process (``wncs run
    --dashboard``): the run never shares a process, or a GIL, with its observer, and the
    observer runs at a lower CPU priority (``nice`` 10), so on a loaded machine the run's
    nodes go first; it ends with the run's process, however that ends."""
    return subprocess.Popen(
        [sys.executable, "-m", "cli", "dashboard", str(run_dir), "--port", str(port)],
        stdin=subprocess.DEVNULL,
        preexec_fn=_lower_priority,
    )


def _lower_priority() -> None:
    """The dashboard child's start: a lower CPU priority, and it ends with ``wncs run`` (a
    ``kill -9`` of the run must not leave it serving: :func:`kernel.lifetime.die_with_parent`)."""
    os.nice(10)
    die_with_parent()
