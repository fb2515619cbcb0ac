"""The launcher: runs a scenario by one of three engines and leaves the run's artefacts in DIR.

:func:`launch` is load, pick, run, summarize: the scenario is loaded and the run prepared
(:func:`_prepare`: its directory, id and ``run.json``), the engine of ``--engine`` picked from
:data:`ENGINES_BY_NAME` (each an :class:`Engine`: :class:`ProcessesEngine`,
:class:`ThreadsEngine`, :class:`DirectRun`) runs it to an :class:`Outcome`, and the outcome's
record is summarized (``summary.json``, the plots). The options travel as one frozen
:class:`LaunchOptions`.

``processes`` (default) starts one OS process per node with exactly the command
``wncs node SCENARIO NAME --connect ENDPOINT --run-id ID`` around the run's zenoh router, a
process of its own that counts what it refuses (:mod:`kernel.router_process`); ``threads``
runs the same nodes in this process, each with its own session on the same router;
``direct`` simulates without a bus (:mod:`runtime.direct`). DIR receives ``run.json`` (run id,
router endpoint, node pids) at start, then ``history.sqlite`` (bus engines), ``summary.json``,
one PNG per loop, and ``logs/`` with each process's log.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import logging
import os
import secrets
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, TextIO

import yaml

from bus_schemas import Stop, TickLog, codec, keys
from core.errors import ConfigError, NodeFault, SchemaError
from core.record import RunRecord
from core.time import to_units
from kernel.bus import DEFAULT_LISTEN, Session, is_put, open_client
from kernel.clock import ClockRunner
from kernel.heartbeat import Heartbeat, beat_interval
from kernel.lifetime import die_with_parent
from kernel.router_process import RouterProcess
from runtime.affinity import (
    ANY,
    ROUTER,
    affinity_args,
    check_affinity,
    cpus_of,
    pin,
    pinned_here,
    with_default,
)
from runtime.artefacts import REFUSED_LOG, RUN_FILE, SCENARIO_FILE, write_json
from runtime.direct import simulate
from runtime.forked import ForkServer
from runtime.history import load_record
from runtime.nodes import bus_node, clock_runner
from runtime.report import PLOTS, save_record, write_plots, write_summary
from runtime.security import (
    LAUNCHER,
    SECURITY_ENV,
    THREADS,
    TLS_LISTEN,
    check_tls,
    credentials_of,
    listen_names,
    pick_endpoint,
    warn_insecure,
)
from runtime.security import prepare as prepare_security
from scenario import Scenario, load_scenario

__all__ = [
    "ENGINES",
    "ENGINES_BY_NAME",
    "Engine",
    "LaunchOptions",
    "Run",
    "Outcome",
    "RunResult",
    "launch",
    "launch_with",
    "node_command",
    "RUN_FILE",
    "SCENARIO_FILE",
]

log = logging.getLogger(__name__)

ENGINES = ("processes", "threads", "direct")
_EXIT_GRACE_S = 10.0
_FORK_TIMEOUT_S = 120.0
"""Processes engine: time the fork server may take to import, validate and fork every node."""
_STARTING_AT_ONCE = 4
"""Threads engine: nodes that build their behaviour at the same time. When each node also
opened a session of its own, two hundred threads doing both at once (100 loops) starved the
zenoh runtime's few threads of the interpreter lock they need for callbacks, and an eighth to a
quarter of the sessions timed out while connecting; a few at a time, each node was up in
milliseconds. The nodes now share one session; the gate stays for the building."""


@dataclass
class RunResult:
    """What a launch produced: exit code, error (if any) and the summary."""

    code: int
    error: str | None = None
    summary: dict[str, Any] = field(default_factory=dict)
    out: Path | None = None


INTERRUPTED = 130
"""Exit code of a run stopped by Ctrl-C or SIGTERM (the shell's 128 + SIGINT)."""


def _wncs_executable() -> list[str]:
    script = Path(sys.executable).parent / "wncs"
    if script.exists():
        return [str(script)]
    found = shutil.which("wncs")
    return [found] if found else [sys.executable, "-m", "cli"]


def node_command(
    scenario_path: str, name: str, endpoint: str, run_id: str, *, extra: list[str] | None = None
) -> list[str]:
    """The command that runs node ``name``: ``wncs node SCENARIO NAME --connect EP --run-id ID``."""
    return [
        *_wncs_executable(),
        "node",
        scenario_path,
        name,
        "--connect",
        endpoint,
        "--run-id",
        run_id,
        *(extra or []),
    ]


class _Progress:
    """Shows simulated time against end time on a terminal; remembers the clock's Stop."""

    def __init__(self, run_id: str, scenario: Scenario, stream: TextIO | None) -> None:
        self.run_id = run_id
        self.end = scenario.end_time
        self.unit = scenario.time_unit
        self.stream = stream
        self.t = 0.0
        self.stop: Stop | None = None
        self.alive: set[str] = set()
        self._shown = -1.0
        self.first_tick_at: float | None = None  # perf_counter when round 0 was seen
        self.stop_at: float | None = None
        self.started: float | None = None  # perf_counter when every participant was alive
        # the clock's own stamps of its first and last round, where it runs in this process (the
        # threads engine: this session's callbacks there wait for the busy nodes' interpreter
        # lock, and saw round 0's log up to a whole run late)
        self.span: tuple[float, float] | None = None

    def on_log(self, sample: Any) -> None:
        """The clock's log of ticks (``clock/log``): how far the run has gone."""
        try:
            ticks = codec.decode(sample.payload.to_bytes(), TickLog).body.ticks
        except SchemaError:  # a progress display never fails a run
            return
        if not ticks:
            return
        if ticks[0].round == 0:  # logged at once (a sync round)
            self.first_tick_at = time.perf_counter()
        self.t = to_units(ticks[-1].t)

    def on_stop(self, sample: Any) -> None:
        try:
            self.stop = codec.decode(sample.payload.to_bytes(), Stop).body
        except SchemaError:
            return
        self.stop_at = time.perf_counter()

    def on_alive(self, sample: Any) -> None:
        name = str(sample.key_expr).rsplit("/", 1)[-1]
        if is_put(sample):
            self.alive.add(name)

    def show(self, final: bool = False) -> None:
        if self.stream is None or (self.t == self._shown and not final):
            return
        self._shown = self.t
        self.stream.write(f"\r  t = {self.t:8.3f} / {self.end:g} {self.unit}")
        if final:
            self.stream.write("\n")
        self.stream.flush()


@dataclass(frozen=True)
class LaunchOptions:
    """How to run a scenario: ``wncs run``'s options (:func:`launch` documents each)."""

    engine: str = "processes"
    seed: int | None = None
    listen: str | None = None
    realtime: float | None = None
    progress: TextIO | None = None
    overrides: tuple[str, ...] = ()
    force: bool = False
    on_start: Callable[[Path], None] | None = None
    insecure: bool = False
    zenoh_config: str | None = None
    tls: bool = False
    affinity: Mapping[str, frozenset[int]] = field(default_factory=dict)
    plots: str = "auto"

    def checked(self) -> LaunchOptions:
        """These options, refused where they contradict each other (``ValueError`` for an
        unknown engine, ``ConfigError`` for TLS without a bus or without security), with TLS's
        default endpoint."""
        if self.engine not in ENGINES:
            raise ValueError(f"engine must be one of {ENGINES}, got {self.engine!r}")
        if self.plots not in PLOTS:
            raise ConfigError(f"--plots: one of {', '.join(PLOTS)}, got {self.plots!r}")
        if not self.tls:
            return self
        if self.engine == "direct":
            raise ConfigError("--tls: the direct engine has no bus; use threads or processes")
        listen = self.listen or TLS_LISTEN
        check_tls(listen, tls=self.tls, insecure=self.insecure)
        return dataclasses.replace(self, listen=listen)


@dataclass
class Run:
    """A run being launched: its scenario, directory, ``run.json`` and options."""

    scenario: Scenario
    scenario_path: Path
    out: Path
    info: dict[str, Any]
    options: LaunchOptions
    wall0: float
    """``perf_counter`` at the launch's start."""

    @property
    def run_id(self) -> str:
        return str(self.info["run_id"])


@dataclass
class Outcome:
    """What an engine's run left: its exit code and error, and the record to summarize (none
    when it failed before any round was recorded)."""

    code: int
    error: str | None = None
    record: RunRecord | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    """What ``summary.json`` says besides the record (``complete``, ``interrupted_at``, what
    the router refused: ``router``)."""


class Engine(Protocol):
    """Runs a prepared :class:`Run` to its :class:`Outcome` (:data:`ENGINES_BY_NAME`)."""

    def run(self, run: Run) -> Outcome:
        """Run ``run`` (its ``run.json`` is written by then, its artefacts after)."""
        ...


def launch(
    scenario_path: str | Path,
    out: str | Path,
    *,
    engine: str = "processes",
    seed: int | None = None,
    listen: str | None = None,
    realtime: float | None = None,
    progress: TextIO | None = None,
    overrides: Sequence[str] = (),
    force: bool = False,
    on_start: Callable[[Path], None] | None = None,
    insecure: bool = False,
    zenoh_config: str | None = None,
    tls: bool = False,
    affinity: Mapping[str, frozenset[int]] | None = None,
    plots: str = "auto",
) -> RunResult:
    """Run a scenario; a bad scenario raises ``ConfigError`` before anything starts.

    ``overrides`` are ``--set`` arguments (``"loops.level.tau_s=0.2"``) applied to the file's
    mapping before validation; each node process gets them too, so all load the same scenario.
    ``out`` must not hold a run already (its ``run.json``) unless ``force``, which replaces it;
    an ``out`` that cannot be written is refused too, before anything starts.
    ``on_start(out)`` is called once ``out/run.json`` names the run's router (a bus engine),
    before the nodes start: ``wncs run --dashboard`` starts its dashboard there.
    A bus run is secure unless ``insecure`` (:mod:`runtime.security`: per-node credentials and
    the router's access control under ``out/security``); ``zenoh_config`` is a zenoh
    configuration file the router starts from (else ``$ZENOH_CONFIG``). With ``tls`` every
    session of the run goes over mutual TLS (:mod:`kernel.tls`; ``listen`` defaults to
    ``tls/127.0.0.1:0``); ``tls`` with ``insecure`` is refused (``ConfigError``).
    ``affinity`` pins the run's processes to CPUs (:mod:`runtime.affinity`, ``--affinity``);
    one it cannot apply is refused before anything starts. The threads engine's process and
    its router run on one CPU unless ``affinity`` gives ``*`` (:func:`~runtime.affinity.
    with_default`). ``plots`` says which figures the run draws
    (:func:`runtime.report.write_plots`: ``auto``, ``all``, ``summary`` or ``none``).
    """
    options = LaunchOptions(
        engine=engine,
        seed=seed,
        listen=listen,
        realtime=realtime,
        progress=progress,
        overrides=tuple(overrides),
        force=force,
        on_start=on_start,
        insecure=insecure,
        zenoh_config=zenoh_config,
        tls=tls,
        affinity=dict(affinity or {}),
        plots=plots,
    )
    return launch_with(scenario_path, out, options)


def launch_with(scenario_path: str | Path, out: str | Path, options: LaunchOptions) -> RunResult:
    """:func:`launch` with its options in one :class:`LaunchOptions`: load the scenario and
    prepare the run, pick the engine, run it, summarize what it left."""
    options = options.checked()
    run = _prepare(Path(scenario_path), Path(out), options)
    outcome = ENGINES_BY_NAME[options.engine]().run(run)
    return _summarize(run, outcome)


def _prepare(scenario_path: Path, out: Path, options: LaunchOptions) -> Run:
    """The run of ``scenario_path`` into ``out``: its scenario loaded (with the options' seed),
    its placement checked, ``out`` prepared with the scenario file in it, its id and ``run.json``
    contents (written by the engine)."""
    wall0 = time.perf_counter()
    scenario = load_scenario(scenario_path, overrides=options.overrides)
    if options.seed is not None:
        scenario = scenario.model_copy(update={"seed": options.seed})
    check_affinity(options.affinity, ["clock", *scenario.participants()], options.engine)
    options = dataclasses.replace(options, affinity=with_default(options.affinity, options.engine))
    out = _prepare_out(out, options.force)
    (out / SCENARIO_FILE).write_text(
        yaml.safe_dump(scenario.model_dump(mode="json"), sort_keys=False)
    )
    info: dict[str, Any] = {
        "run_id": "r" + secrets.token_hex(5),
        "engine": options.engine,
        "scenario": str(scenario_path.resolve()),
        "seed": scenario.seed,
        "overrides": list(options.overrides),
        "endpoint": None,
        "nodes": {},
    }
    if options.affinity:
        info["affinity"] = {name: sorted(cpus) for name, cpus in options.affinity.items()}
    return Run(scenario, scenario_path, out, info, options, wall0)


def _summarize(run: Run, outcome: Outcome) -> RunResult:
    """The artefacts of what the engine left: ``summary.json`` and the plots (a partial summary,
    said so, for a run interrupted after its history began)."""
    if outcome.record is None:
        return RunResult(outcome.code, outcome.error or "run failed", {}, run.out)
    summary = write_summary(outcome.record, run.out, **outcome.extra)
    plots = run.options.plots
    write_plots(outcome.record, run.out, scenario=run.scenario, plots=plots, summary=summary)
    return RunResult(outcome.code, outcome.error, summary, run.out)


class DirectRun:
    """The direct engine (:mod:`runtime.direct`): no bus; the record is kept as ``record.json``."""

    def run(self, run: Run) -> Outcome:
        write_json(run.out / RUN_FILE, run.info)
        rec = simulate(run.scenario)
        rec.wall_s = time.perf_counter() - run.wall0
        save_record(rec, run.out)
        return Outcome(0, None, rec)


def _prepare_out(out: Path, force: bool) -> Path:
    """``out``, created and writable, and holding no earlier run (or, with ``force``, emptied of
    it); ``ConfigError`` naming ``--out`` otherwise."""
    if (out / RUN_FILE).exists():
        if not force:
            raise ConfigError(
                f"--out {out}: holds a run already ({RUN_FILE}); choose another directory, or "
                "--force to replace it"
            )
        shutil.rmtree(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".wncs-write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as err:
        raise ConfigError(f"--out {out}: cannot write there: {err.strerror or err}") from err
    return out


class _BusEngine:
    """What the two bus engines share: the run's security, its router (a process of its own),
    the launcher's own session showing the run's progress, and the record read back from the
    history. A subclass runs the rounds (:meth:`_rounds`), and may start what it needs before
    the router (:meth:`_before_router`) and close it after the run (:meth:`_after`)."""

    def run(self, run: Run) -> Outcome:
        options = run.options
        listen = options.listen or DEFAULT_LISTEN
        hosts = listen_names(listen)
        security = (
            None
            if options.insecure
            else prepare_security(
                run.out, run.scenario, run.run_id, tls=options.tls, tls_names=hosts
            )
        )
        warn_insecure(listen, secure=security is not None)
        names = ["clock", *run.scenario.participants()]
        with contextlib.ExitStack() as undo:  # what start-up opened, closed if start-up fails
            self._before_router(run, names, security, undo)
            router, endpoint, watch = _start_bus(run, listen, hosts, security, undo)
            undo.pop_all()  # started: the ``finally`` below closes them
        prog = _Progress(run.run_id, run.scenario, options.progress)
        subs = [
            watch.declare_subscriber(keys.full(run.run_id, keys.tick_log()), prog.on_log),
            watch.declare_subscriber(keys.full(run.run_id, keys.stop()), prog.on_stop),
            watch.liveliness().declare_subscriber(
                keys.full(run.run_id, keys.alive_all()), prog.on_alive, history=True
            ),
        ]
        try:
            code, error, t_started = self._rounds(run, names, endpoint, prog, security)
        finally:
            self._after()
            prog.show(final=True)
            for s in subs:
                s.undeclare()
            watch.close()
            refusals = router.close()
        return _bus_outcome(run, prog, code, error, t_started, refusals)

    def _before_router(
        self, run: Run, names: list[str], security: Path | None, undo: contextlib.ExitStack
    ) -> None:
        """Start what must start before the router (``undo`` closes it if the start fails)."""

    def _rounds(
        self, run: Run, names: list[str], endpoint: str, prog: _Progress, security: Path | None
    ) -> tuple[int, str | None, float | None]:
        """Run the rounds: ``(exit code, error, when every participant was alive)``."""
        raise NotImplementedError

    def _after(self) -> None:
        """Close what :meth:`_before_router` started (the run is over, or failed to start)."""


def _start_bus(
    run: Run,
    listen: str,
    hosts: tuple[str, ...],
    security: Path | None,
    undo: contextlib.ExitStack,
) -> tuple[RouterProcess, str, Session]:
    """The run's router and the launcher's own session on it; ``run.json`` names its endpoint
    (and ``on_start`` is called: the dashboard starts there). ``undo`` closes both if the start
    fails."""
    options = run.options
    router = RouterProcess(  # a process of its own: it audits what it refuses (kernel.audit)
        listen,
        security=security,
        zenoh_config=options.zenoh_config,
        refused_log=None if security is None else run.out / REFUSED_LOG,
    )
    undo.callback(router.close)
    if (cpus := cpus_of(options.affinity, ROUTER)) is not None:
        pin(router.pid, cpus)
    endpoint = pick_endpoint(router.locators, listen, hosts)
    watch = open_client(  # the launcher's own session: it shows the run's progress
        endpoint, settings=None if security is None else credentials_of(security, LAUNCHER)
    )
    undo.callback(watch.close)
    run.info["endpoint"] = endpoint
    run.info["secure"] = security is not None
    run.info["tls"] = options.tls
    write_json(run.out / RUN_FILE, run.info)
    if options.on_start is not None:
        options.on_start(run.out)  # e.g. the dashboard, whose port may be taken
    return router, endpoint, watch


def _bus_outcome(
    run: Run,
    prog: _Progress,
    code: int,
    error: str | None,
    t_started: float | None,
    refusals: dict[str, Any] | None,
) -> Outcome:
    """A bus run's outcome: its record read back from the history, with the run's phases (or,
    interrupted, what the history holds up to then, said so)."""
    wall_end = time.perf_counter()
    history = run.out / "history.sqlite"
    if prog.stop is not None and not prog.stop.ok and error is None:
        error = prog.stop.reason
    if code == INTERRUPTED and history.exists():
        rec = load_record(history, run.scenario, engine=run.options.engine)
        rec.wall_s = wall_end - run.wall0
        extra = {"complete": False, "interrupted_at": prog.t, "router": refusals}
        return Outcome(code, error, rec, extra)
    if code != 0:
        return Outcome(code, error or "run failed")
    rec = load_record(history, run.scenario, engine=run.options.engine)
    rec.wall_s = wall_end - run.wall0
    first, stopped = prog.span or (
        prog.first_tick_at or t_started or run.wall0,
        prog.stop_at or wall_end,
    )
    rec.phases = {
        "startup": first - run.wall0,
        "run": stopped - first,
        "teardown": wall_end - stopped,
    }
    return Outcome(0, None, rec, {"router": refusals})


class ProcessesEngine(_BusEngine):
    """One OS process per node, forked by one fork server (:mod:`runtime.forkserver`) that
    imports while the router starts and forks once it listens."""

    def __init__(self) -> None:
        self.server: ForkServer | None = None

    def _before_router(
        self, run: Run, names: list[str], security: Path | None, undo: contextlib.ExitStack
    ) -> None:
        options = run.options
        (run.out / "logs").mkdir(exist_ok=True)
        self.server = ForkServer(  # one interpreter imports and forks every node
            str(run.scenario_path),
            names,
            connect=None,
            run_id=run.run_id,
            logs=run.out / "logs",
            args=[
                "--out",
                str(run.out),
                "--engine",
                options.engine,
                *(["--realtime", repr(options.realtime)] if options.realtime else []),
                "--seed",
                str(run.scenario.seed),
                *(f"--set={o}" for o in options.overrides),
                *affinity_args(options.affinity),
            ],
            preexec_fn=die_with_parent,
            env=_node_environment(security),
        )
        undo.callback(self.server.abandon)

    def _rounds(
        self, run: Run, names: list[str], endpoint: str, prog: _Progress, security: Path | None
    ) -> tuple[int, str | None, float | None]:
        assert self.server is not None  # started before the router
        return _run_processes(self.server, run.out, run.info, names, endpoint, prog)

    def _after(self) -> None:
        if self.server is not None:
            self.server.abandon()  # nothing if it forked (its input is closed then); else it goes


class ThreadsEngine(_BusEngine):
    """Every node and the clock a thread of this process, on one zenoh session
    (:func:`_run_threads`)."""

    def _rounds(
        self, run: Run, names: list[str], endpoint: str, prog: _Progress, security: Path | None
    ) -> tuple[int, str | None, float | None]:
        options = run.options
        with pinned_here(cpus_of(options.affinity, ANY)):
            return _run_threads(
                run.scenario,
                run.out,
                run.run_id,
                names,
                endpoint,
                options.realtime,
                options.engine,
                prog,
                security,
            )


ENGINES_BY_NAME: dict[str, Callable[[], Engine]] = {
    "processes": ProcessesEngine,
    "threads": ThreadsEngine,
    "direct": DirectRun,
}
"""Each engine of ``--engine``, made anew for each run."""


def _node_environment(security: Path | None) -> dict[str, str]:
    """The node processes' environment: this one, and the run's security directory for a
    secure run (``wncs node`` finds its credentials there); never an outer run's."""
    env = {k: v for k, v in os.environ.items() if k != SECURITY_ENV}
    if security is not None:
        env[SECURITY_ENV] = str(security.resolve())
    return env


def _run_processes(
    server: ForkServer,
    out: Path,
    run_info: dict[str, Any],
    names: list[str],
    endpoint: str,
    prog: _Progress,
) -> tuple[int, str | None, float | None]:
    logs = out / "logs"
    procs: dict[str, Any] = {}  # name -> Forked (what of subprocess.Popen the launcher uses)
    t_started: float | None = None
    server.connect_to(endpoint)
    try:
        try:
            procs = server.nodes(timeout=_FORK_TIMEOUT_S)
        except RuntimeError as err:
            procs = dict(server.children)  # those forked are stopped below
            return 1, str(err), None
        run_info["nodes"] = {n: p.pid for n, p in procs.items()}
        write_json(out / RUN_FILE, run_info)
        clock = procs["clock"]
        try:
            _wait_for_clock(clock, procs, names, logs, prog)
        except _StartFailed as fail:
            return fail.code, fail.message, None
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the clock stops the nodes, then we wait
            clock.send_signal(signal.SIGTERM)
            _wait_all(procs)
            return INTERRUPTED, _interrupted(prog), prog.started
        t_started = prog.started
        code = clock.returncode
        _wait_all(procs)
        error = None
        if code < 0:  # the clock itself died (killed): a fault, said as such
            name = signal.Signals(-code).name
            code, error = 3, f"the clock died ({name}) at t = {prog.t:g} {prog.unit}"
        elif code != 0:
            error = prog.stop.reason if prog.stop is not None else _last_error(logs / "clock.log")
        else:
            dropped = set(prog.stop.dropped_nodes) if prog.stop is not None else set()
            failed = {
                n: p.returncode
                for n, p in procs.items()
                if p.returncode not in (0, None) and n not in dropped
            }
            if failed:
                code, error = 4, f"nodes exited with errors: {failed} (see {logs})"
        return code, error, t_started
    finally:
        for p in procs.values():
            if p.poll() is None:
                _kill(p)
        server.close()


class _StartFailed(Exception):
    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code, self.message = code, message


def _wait_for_clock(
    clock: subprocess.Popen,
    procs: dict[str, subprocess.Popen],
    names: list[str],
    logs: Path,
    prog: _Progress,
) -> None:
    """Wait for the clock process to end, showing progress; a node that dies while the run
    starts ends the wait at once (:class:`_StartFailed`)."""
    while clock.poll() is None:
        if prog.started is None and set(names) <= prog.alive:
            prog.started = time.perf_counter()
        if prog.started is None:  # a node that dies while starting: no need to wait for the clock
            dead = {n: p.returncode for n, p in procs.items() if p.poll() not in (None, 0)}
            if dead:
                name = sorted(dead)[0]
                tail = _log_tail(logs / f"{name}.log")
                raise _StartFailed(
                    2 if dead[name] == 2 else 1,
                    f"node {name!r} exited with code {dead[name]} while starting: {tail}",
                )
        prog.show()
        try:
            clock.wait(timeout=0.05)
        except subprocess.TimeoutExpired:
            pass


def _watch_threads(
    clock_thread: threading.Thread,
    clock: list[ClockRunner],
    errors: dict[str, str],
    names: list[str],
    prog: _Progress,
) -> float | None:
    """Wait for the clock thread to end, showing progress; when every node is alive returns
    that moment; a node that fails while starting ends the wait (:class:`_StartFailed`)."""
    while clock_thread.is_alive():
        if prog.started is None and set(names) <= prog.alive:
            prog.started = time.perf_counter()
        if prog.started is None and errors and clock:
            name = sorted(errors)[0]
            raise _StartFailed(1, f"node {name!r} failed while starting: {errors[name]}")
        prog.show()
        clock_thread.join(0.05)
    return prog.started


def _wait_all(procs: dict[str, subprocess.Popen]) -> None:
    """Give every node the grace period to leave after the clock's Stop."""
    deadline = time.monotonic() + _EXIT_GRACE_S
    for name, p in procs.items():
        try:
            p.wait(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            log.warning("node %s did not exit after the stop; killing it", name)


def _interrupted(prog: _Progress) -> str:
    return f"interrupted at t = {prog.t:g} {prog.unit}"


def _kill(p: subprocess.Popen) -> None:
    try:
        os.killpg(p.pid, signal.SIGTERM)
        p.wait(timeout=3)
    except (ProcessLookupError, subprocess.TimeoutExpired, PermissionError):
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        p.wait()


def _log_tail(path: Path) -> str:
    try:
        lines = [ln for ln in path.read_text().splitlines() if ln.strip()]
    except OSError:
        return f"(no log at {path})"
    return lines[-1] if lines else f"(empty log {path})"


def _last_error(path: Path) -> str:
    try:
        lines = [ln for ln in path.read_text().splitlines() if "ERROR" in ln]
    except OSError:
        return "the clock failed"
    return lines[-1] if lines else "the clock failed"


@contextlib.contextmanager
def _frozen_heap() -> Iterator[None]:
    """Keep the heap built so far (imports, scenario) out of the garbage collector's full passes
    for the duration (``gc.freeze``; the fork server does the same before it forks the
    processes engine's nodes). A full pass over the threads engine's heap, about 140 000
    objects, held every thread for 60-77 ms, once or twice in a 30 pu JCSTR run (1500 rounds
    of about 1 ms); frozen, the longest round of such a run fell to 12-20 ms. Process-wide, as
    is :func:`_switch_interval`: a caller that froze objects of its own keeps them frozen, with
    the run's; otherwise they are thawed after it, and what is garbage by then is collected."""
    caller_froze = gc.get_freeze_count() > 0
    gc.freeze()
    try:
        yield
    finally:
        if not caller_froze:
            gc.unfreeze()


SWITCH_INTERVAL_S = 0.002
"""The interpreter's switch interval during a threads run (``sys.setswitchinterval``; Python's
default is 5 ms): how long a thread that wants the interpreter lock waits for a busy holder
before it makes it let go. Every node of a threads run shares the lock, and a round's critical
path (a node's tick callback, the clock's ``Done`` callback) waits behind whichever thread holds
it. Alternated 30 pu JCSTR runs, median ms per round, 2 ms against 5 ms: 0.954 / 1.053,
1.022 / 1.151, 1.149 / 1.212 and 1.098 / 1.173 (5 to 8 alternations), with 3-12 % less CPU per
round; 1 ms: 0.965 and 1.118; 0.5 ms and 50 ms were slower than 5 ms. The processes engine's
nodes showed no difference with it (1.087 / 1.028, 8 alternations), so they keep Python's
default (``docs/benchmarks.md``)."""


@contextlib.contextmanager
def _switch_interval(seconds: float) -> Iterator[None]:
    """The interpreter's switch interval set to ``seconds`` for the duration, then restored."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(seconds)
    try:
        yield
    finally:
        sys.setswitchinterval(before)


@_frozen_heap()
@_switch_interval(SWITCH_INTERVAL_S)
def _run_threads(
    scenario: Scenario,
    out: Path,
    run_id: str,
    names: list[str],
    endpoint: str,
    realtime: float | None,
    engine: str,
    prog: _Progress,
    security: Path | None = None,
) -> tuple[int, str | None, float | None]:
    """The threads engine: every node and the clock a thread of this process, all on one zenoh
    session, closed after them.

    The nodes share it under one identity (:data:`runtime.security.THREADS`, allowed what any of
    them is). zenoh hands a session's publication to that session's own subscribers without the
    router, so a round's tick and ``Done`` no longer cross the router and loopback TCP twice
    each. Alternated benchmark runs, ms per round: median 0.58 against 1.04 with a session per
    node, 5 of 5 faster; start-up at 50 loops 0.7-0.8 s against 1.5-1.6 s
    (``docs/benchmarks.md``). What another session subscribes to (the launcher's progress, a
    dashboard) still goes to the router, and what the others send
    (``wncs inject``, a dashboard's buttons) comes from it, under the router's access control as
    before. Given up: separate identities inside the process, which guarded nothing there (one
    process, one interpreter: any node's code can reach any other's session and credentials)."""
    try:
        session = open_client(
            endpoint, settings=None if security is None else credentials_of(security, THREADS)
        )
    except Exception as err:  # noqa: BLE001 - every node's failure to start, at once
        log.error("the nodes' session failed while starting: %s", err)
        return 1, f"the nodes' session failed while starting: {type(err).__name__}: {err}", None
    try:
        return _threads_on(session, scenario, out, run_id, names, realtime, engine, prog)
    finally:
        session.close()


def _threads_on(
    session: Session,
    scenario: Scenario,
    out: Path,
    run_id: str,
    names: list[str],
    realtime: float | None,
    engine: str,
    prog: _Progress,
) -> tuple[int, str | None, float | None]:
    errors: dict[str, str] = {}
    result: dict[str, int] = {}
    clock: list[ClockRunner] = []
    started: dict[str, Any] = {}  # name -> node object, for aborting stragglers
    lock = threading.Lock()
    aborted = threading.Event()

    gate = threading.BoundedSemaphore(_STARTING_AT_ONCE)
    heartbeat = Heartbeat(beat_interval(scenario.clock.round_timeout_s))  # one for all nodes

    def run_node(name: str) -> None:
        try:
            with gate:  # a few at a time: see _STARTING_AT_ONCE
                if name == "clock":
                    runner = clock_runner(scenario, session, run_id, realtime=realtime)
                    clock.append(runner)
                else:
                    options = {"out": str(out), "engine": engine}
                    node = bus_node(scenario, name, run_id, session, options, heartbeat=heartbeat)
            if name == "clock":
                result["clock"] = runner.run()
                if runner.error:
                    errors["clock"] = runner.error
            else:
                with lock:
                    if aborted.is_set():
                        return  # the run was cancelled while this node was being built
                    started[name] = node
                node.run()
        except Exception as err:  # noqa: BLE001 - reported as the node's failure
            errors[name] = f"{type(err).__name__}: {err}"
            log.exception("node %s failed: %s", name, err)

    threads = [threading.Thread(target=run_node, args=(n,), name=n, daemon=True) for n in names]
    for th in threads:
        th.start()
    t_started: float | None = None
    clock_thread = threads[0]
    try:
        t_started = _watch_threads(clock_thread, clock, errors, names, prog)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the clock stops the nodes, then we wait
        if clock:
            clock[0].cancel(_interrupted(prog))
        clock_thread.join(_EXIT_GRACE_S)
        for th in threads[1:]:
            th.join(_EXIT_GRACE_S)
        return INTERRUPTED, _interrupted(prog), prog.started
    except _StartFailed as fail:  # a node failed while starting
        clock[0].cancel(fail.message)  # the clock stops the others; no thread outlives the run
        clock_thread.join(_EXIT_GRACE_S)
        with lock:  # a node that subscribed after the clock's Stop would wait for rounds
            aborted.set()
            for node in started.values():
                node.abort()
        for th in threads:
            th.join(_EXIT_GRACE_S)
        return 1, fail.message, None
    for th in threads[1:]:
        th.join(_EXIT_GRACE_S)
    code = result.get("clock", 3)
    if code != 0:
        return code, errors.get("clock") or str(errors) or "clock failed", t_started
    if errors:
        raise NodeFault(f"nodes failed: {errors}")
    prog.span = clock[0].span
    return 0, None, t_started
