"""``wncs router``: a standalone zenoh router for a run whose nodes live on several hosts.

The first router of a run makes it: a run id, and (unless ``--insecure``) the run's credentials
and access control under ``DIR/security`` (:mod:`runtime.security`), and ``DIR/run.json``
naming the run id and the router's endpoint. A router started with ``--connect`` joins another
router of the same run: it reads the run id and the security of ``DIR`` (copy ``DIR/security``
and ``DIR/run.json`` to the host that runs it), authenticates to the other router as identity
``router`` (and lets it in by its zenoh id, recorded in ``run.json``: see
:func:`kernel.security.router_settings`), and enforces the same access control on the nodes
that connect to it. Each node then runs as::

    WNCS_SECURITY=DIR/security wncs node SCENARIO NAME --connect ENDPOINT --run-id ID

(or ``--credentials DIR/security/NAME.json``), the historian with ``--out DIR``. The router
serves until SIGINT or SIGTERM.
"""

from __future__ import annotations

import json
import secrets
import signal
import sys
import threading
from pathlib import Path
from typing import Any, TextIO

from core.errors import ConfigError
from kernel.bus import open_router
from kernel.security import SECURITY_DIR, router_settings
from runtime.artefacts import RUN_FILE
from runtime.scenario import load_scenario
from runtime.security import prepare, warn_insecure

__all__ = ["serve_router", "router_run"]


def router_run(
    scenario_path: str,
    out: Path,
    *,
    insecure: bool = False,
    overrides: tuple[str, ...] = (),
) -> tuple[dict[str, Any], Path | None]:
    """The run a router serves: ``out/run.json`` if another router of it wrote one (with its
    security), else a new run written there. Returns the run's information and its security
    directory (``None``: insecure)."""
    run_file = out / RUN_FILE
    if run_file.exists():
        try:
            info: dict[str, Any] = json.loads(run_file.read_text())
            info["run_id"]
        except (OSError, ValueError, KeyError) as err:
            raise ConfigError(f"{run_file}: not a run's file ({err})") from err
        security = out / SECURITY_DIR
        if info.get("secure", True) and not security.is_dir():
            raise ConfigError(f"{security}: the run is secure, and its security is not here")
        return info, (security if info.get("secure", True) else None)
    scenario = load_scenario(scenario_path, overrides=list(overrides))
    out.mkdir(parents=True, exist_ok=True)
    run_id = "r" + secrets.token_hex(5)
    security = None if insecure else prepare(out, scenario, run_id)
    info = {
        "run_id": run_id,
        "engine": "routers",
        "scenario": str(Path(scenario_path).resolve()),
        "seed": scenario.seed,
        "secure": security is not None,
        "endpoint": None,
        "routers": [],
    }
    return info, security


def serve_router(
    scenario_path: str,
    out: Path,
    listen: str,
    *,
    connect: tuple[str, ...] = (),
    insecure: bool = False,
    zenoh_config: str | None = None,
    overrides: tuple[str, ...] = (),
    stream: TextIO | None = None,
    stop: threading.Event | None = None,
) -> int:
    """Open the router, record it in ``out/run.json``, and serve until ``stop`` is set or a
    SIGINT/SIGTERM arrives; return the exit code (0)."""
    stream = stream or sys.stdout
    info, security = router_run(scenario_path, out, insecure=insecure, overrides=overrides)
    warn_insecure(listen, secure=security is not None)
    zid = "%x" % (secrets.randbits(124) | 1 << 124)  # 32 hex digits, no leading 0 (zenoh)
    known = {r["endpoint"]: r["zid"] for r in info.get("routers", [])}
    unknown = [c for c in connect if c not in known]
    if security is not None and unknown:
        raise ConfigError(
            f"--connect {', '.join(unknown)}: not a router of run {info['run_id']} "
            f"(its routers: {sorted(known) or 'none yet'})"
        )
    peers = tuple(known[c] for c in connect if c in known)
    router, locators = open_router(
        listen,
        connect=connect,
        settings=None if security is None else router_settings(security, zid=zid, peers=peers),
        config_file=zenoh_config,
    )
    endpoint = next((loc for loc in locators if loc.startswith("tcp/")), locators[0])
    info["endpoint"] = info.get("endpoint") or endpoint
    info.setdefault("routers", []).append({"endpoint": endpoint, "zid": zid})
    tmp = out / (RUN_FILE + ".tmp")
    tmp.write_text(json.dumps(info, indent=1) + "\n")
    tmp.replace(out / RUN_FILE)
    stream.write(
        f"wncs router: run {info['run_id']} ({'secure' if security else 'INSECURE'}) on "
        f"{endpoint}{' joined to ' + ', '.join(connect) if connect else ''}\n"
    )
    stream.flush()
    stop = stop or threading.Event()

    def _stop(signum: int, frame: object) -> None:
        stop.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _stop)
        signal.signal(signal.SIGINT, _stop)
    try:
        while not stop.wait(0.2):
            pass
    finally:
        router.close()
    return 0
