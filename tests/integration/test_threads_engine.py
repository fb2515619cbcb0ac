"""The node graph on a real zenoh router in one process (threads engine): fast bus checks."""

from __future__ import annotations

import gc
import json
import sys
import threading
import time

import msgpack
import pytest
import yaml

from agents.operator.behaviour import OperatorBehaviour
from bus_schemas import keys
from controllers.behaviour import ControllerBehaviour
from core.errors import ConfigError
from core.record import summarize
from kernel.bus import open_client
from kernel.clock import SYNC_ROUNDS, ClockRunner
from kernel.node import BusNode
from runtime.direct import simulate
from runtime.historian import HistorianNode
from runtime.history import connect, messages_digest
from runtime.launcher import SWITCH_INTERVAL_S, launch
from scenario import load_scenario
from tests.conftest import BENCHMARK, SCENARIOS, launch_aside, write_variant


def _traces(summary):
    return {n: lp["trace"] for n, lp in summary["loops"].items()}


def test_threads_engine_equals_direct_and_is_reproducible(tmp_path):
    a = launch(BENCHMARK, tmp_path / "a", engine="threads")
    b = launch(BENCHMARK, tmp_path / "b", engine="threads")
    assert a.code == 0 and b.code == 0, (a.error, b.error)
    direct = summarize(simulate(load_scenario(BENCHMARK)))
    assert _traces(a.summary) == _traces(direct)
    assert messages_digest(tmp_path / "a" / "history.sqlite") == messages_digest(
        tmp_path / "b" / "history.sqlite"
    )
    for name, loop in direct["loops"].items():
        assert a.summary["loops"][name]["overshoot_pct"] == loop["overshoot_pct"]


def test_a_threads_run_tunes_the_interpreter_while_it_goes_and_restores_it_after(
    tmp_path, monkeypatch
):
    """During a threads run the launcher keeps its heap out of the collector's full passes (a
    full pass held every thread for 60-77 ms: runtime.launcher._frozen_heap) and shortens the
    interpreter's switch interval (runtime.launcher.SWITCH_INTERVAL_S); after it nothing stays
    frozen, whatever became garbage meanwhile, and the caller's switch interval is back.

    gc.get_freeze_count() walks the frozen list: 23 ms with the whole suite's modules loaded,
    so it is read every 64th tick; read at every tick it put seconds of lag on the historian
    and failed a CI run (round 256 not answered within the clock's 10 s)."""
    frozen, intervals = [], set()
    on_tick = HistorianNode.on_tick

    def noting(self, tick):
        if tick.round % 64 == 0:
            frozen.append(gc.get_freeze_count())
        intervals.add(sys.getswitchinterval())
        on_tick(self, tick)

    monkeypatch.setattr(HistorianNode, "on_tick", noting)
    callers = sys.getswitchinterval()
    assert callers != SWITCH_INTERVAL_S
    res = launch(BENCHMARK, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    assert len(frozen) > 1 and min(frozen) > 10_000  # the imports at least
    assert intervals == {SWITCH_INTERVAL_S}
    assert gc.get_freeze_count() == 0
    assert sys.getswitchinterval() == callers


def test_invalid_messages_on_the_bus_are_counted_not_fatal(tmp_path):
    out = tmp_path / "run"
    runner, result = launch_aside(BENCHMARK, out, engine="threads", realtime=0.5, insecure=True)
    info = json.loads((out / "run.json").read_text())
    session = open_client(info["endpoint"])
    key = keys.full(info["run_id"], keys.meas("level"))
    bad_body = msgpack.packb(
        {
            "v": 1,
            "run": info["run_id"],
            "src": "intruder",
            "seq": 0,
            "round": 0,
            "t": 0,
            "body": {"value": 1.0},
        }
    )
    while runner.is_alive():
        session.put(key, b"garbage")
        session.put(key, bad_body)
        runner.join(0.01)  # pace the garbage; stop as soon as the run ends
    runner.join()
    session.close()
    res = result["r"]
    assert res.code == 0, res.error
    assert res.summary["messages"]["dropped_invalid"]["loop/level/meas"] > 0
    assert _traces(res.summary) == _traces(summarize(simulate(load_scenario(BENCHMARK))))


def test_a_threads_runs_nodes_and_clock_share_one_session(tmp_path):
    """The router's own account (its admin space, readable in an insecure run) once round 0 has
    run (so every member is alive): every participant's and the clock's liveliness token comes
    from one and the same client session, and the router holds only that one, the launcher's
    and this probe's."""
    out = tmp_path / "run"
    runner, result = launch_aside(
        BENCHMARK, out, engine="threads", realtime=1.0, insecure=True, overrides=["end_time=6.0"]
    )
    info = json.loads((out / "run.json").read_text())
    members = {"clock", *load_scenario(BENCHMARK).participants()}
    probe = open_client(info["endpoint"])
    try:
        (router_zid,) = [str(z) for z in probe.info.routers_zid()]
        logged = threading.Event()  # the clock's log: round 0 ran, every member is alive
        sub = probe.declare_subscriber(
            keys.full(info["run_id"], keys.tick_log()), lambda s: logged.set()
        )
        assert logged.wait(60), "no tick logged within 60 s"

        def admin(rel: str) -> dict[str, dict]:  # asks the router alone, not the clients
            return {
                str(r.ok.key_expr): json.loads(r.ok.payload.to_bytes())
                for r in probe.get(f"@/{router_zid}/router{rel}")
                if r.ok is not None
            }

        tokens = admin("/token/" + keys.full(info["run_id"], "alive/*"))
        (router,) = admin("").values()
        sub.undeclare()
    finally:
        probe.close()
    runner.join()
    assert result["r"].code == 0, result["r"].error
    assert {k.rsplit("/", 1)[-1] for k in tokens} == members
    holders = {c for t in tokens.values() for c in t["clients"]}
    assert len(holders) == 1
    assert len(router["sessions"]) == 3  # the nodes' one, the launcher's, this probe's
    assert holders <= {s["peer"] for s in router["sessions"]}


def test_tank_scenarios_over_the_bus_equal_direct(tmp_path):
    """Seed 002's loops (non-linear PI; self-tuning with seeded measurement noise) on the bus."""
    short = yaml.safe_load((SCENARIOS / "tank_sim.yaml").read_text())
    short["end_time"] = 40.0  # through the first disturbance; keeps the test quick
    short["setpoints"] = short["setpoints"][:1]
    short["disturbances"] = short["disturbances"][:2]
    path = tmp_path / "tank_sim_short.yaml"
    path.write_text(yaml.safe_dump(short))
    for scenario in (path, SCENARIOS / "tank_rig.yaml"):
        res = launch(scenario, tmp_path / scenario.stem, engine="threads")
        assert res.code == 0, res.error
        assert _traces(res.summary) == _traces(summarize(simulate(load_scenario(scenario))))


def test_wsn_paths_with_losses_over_the_bus_equal_direct(tmp_path):
    """Random per-hop delays, retries and losses: the bus delivers exactly what direct does."""

    def lossy(d):
        d["end_time"] = 3.0
        d["setpoints"] = d["setpoints"][:1]
        topo = d["nodes"]["network"]["topology"]
        topo["retry_limit"] = 1
        for link in topo["links"]:
            link["prr"] = 0.7

    path = write_variant(tmp_path, SCENARIOS / "jcstr_wsn.yaml", "lossy.yaml", lossy)
    res = launch(path, tmp_path / "run", engine="threads")
    assert res.code == 0, res.error
    direct = summarize(simulate(load_scenario(path)))
    assert _traces(res.summary) == _traces(direct)
    assert res.summary["network"] == direct["network"]
    assert res.summary["network"]["paths"]["level"]["lost"] > 0
    assert res.summary["messages"]["lost"] == direct["messages"]["lost"] > 0


def test_wsn_run_is_reproducible_and_its_stats_match_the_summary(tmp_path):
    """Same seed, same history with the gateway in the loop; net/stats agrees with the traces;
    an event that leaves no route reports the path down and the run goes on."""

    def cut_r2(d):
        d["end_time"] = 4.0
        d["nodes"]["network"]["events"].append(
            {"t": 3.5, "event": {"type": "node_down", "node": "r2"}}
        )

    path = write_variant(tmp_path, SCENARIOS / "jcstr_wsn.yaml", "wsn_cut.yaml", cut_r2)
    a = launch(path, tmp_path / "a", engine="threads")
    b = launch(path, tmp_path / "b", engine="threads")
    assert a.code == 0 and b.code == 0, (a.error, b.error)
    assert messages_digest(tmp_path / "a" / "history.sqlite") == messages_digest(
        tmp_path / "b" / "history.sqlite"
    )
    summary = a.summary
    assert summary["network"] == summarize(simulate(load_scenario(path)))["network"]
    last = summary["network"]["configurations"][-1]
    assert last["event"] == "node_down"
    assert {p["hops"] for p in last["paths"].values()} == {-1}  # both paths down: no route
    assert summary["network"]["paths"]["temperature"]["lost"] > 0  # samples after 3.5 pu lost
    with connect(tmp_path / "a" / "history.sqlite") as conn:
        [(body,)] = conn.execute("SELECT body FROM messages WHERE key = 'net/stats'").fetchall()
        [(n_proposals,)] = conn.execute(
            "SELECT count(*) FROM messages WHERE key = 'net/proposal'"
        ).fetchall()
    stats = msgpack.unpackb(body)["paths"]
    for loop in ("level", "temperature"):
        mine, theirs = summary["network"]["paths"][loop], stats[f"{loop}.sensor"]
        # the snapshot at the end is taken before the packets of the last instant (the sample
        # taken at t = end is handled after the gateway's end-of-run timer)
        assert mine["sent"] - mine["in_flight_at_end"] - theirs["sent"] == 1
        assert 0 <= mine["lost"] - theirs["lost"] <= 1
        assert theirs["delay_mean"] == mine["delay_mean"]
    assert n_proposals == 3  # initial, r1 down, r2 down


@pytest.mark.parametrize("engine", ["threads", "processes"])
def test_an_on_start_that_fails_leaves_no_router_behind(tmp_path, engine):
    """``launch(on_start=...)`` (``wncs run --dashboard`` starts its dashboard there): when it
    raises, the run's router (and the processes engine's fork server) go with the error."""
    seen = {}

    def failing(out):
        seen["endpoint"] = json.loads((out / "run.json").read_text())["endpoint"]
        raise OSError("address already in use")

    with pytest.raises(OSError, match="address already in use"):
        launch(BENCHMARK, tmp_path / "run", engine=engine, on_start=failing, insecure=True)
    with pytest.raises(ConfigError, match="no router answers"):
        open_client(seen["endpoint"]).close()


def test_a_node_failing_at_start_stops_the_run_and_leaves_no_thread(tmp_path, stand_in):
    """The launcher cancels the clock, which stops the other nodes: no node thread outlives the
    run (a daemon thread still in zenoh at interpreter exit aborts the process)."""

    class Failing(OperatorBehaviour):
        def __init__(self, name, scenario) -> None:
            super().__init__(name, scenario)
            raise ValueError("boom at start")

    stand_in("operator", Failing)
    res = launch(BENCHMARK, tmp_path / "run", engine="threads")
    assert res.code == 1
    assert "node 'operator' failed while starting: ValueError: boom at start" in res.error
    names = set(load_scenario(BENCHMARK).participants()) | {"clock"}
    alive = [th.name for th in threading.enumerate() if th.name in names and th.is_alive()]
    assert alive == []


def test_a_node_built_after_the_run_was_cancelled_does_not_outlive_it(tmp_path, stand_in):
    """A node that subscribes only after the clock stopped the run never sees the ``Stop``: the
    launcher aborts it (a loaded machine makes this race real)."""

    class Failing(OperatorBehaviour):
        def __init__(self, name, scenario) -> None:
            super().__init__(name, scenario)
            raise ValueError("boom at start")

    class Slow(ControllerBehaviour):
        def __init__(self, name, scenario) -> None:
            # still being built when the clock stops the run: wait for the clock to leave
            clock = [th for th in threading.enumerate() if th.name == "clock"]
            for th in clock:
                th.join(timeout=60)
            super().__init__(name, scenario)

    stand_in("operator", Failing)
    stand_in("controller", Slow)
    res = launch(BENCHMARK, tmp_path / "run", engine="threads")
    assert res.code == 1 and "boom at start" in res.error
    names = set(load_scenario(BENCHMARK).participants()) | {"clock"}
    alive = [th.name for th in threading.enumerate() if th.name in names and th.is_alive()]
    assert alive == []


def test_a_run_cancelled_mid_round_ends_that_round_and_keeps_every_message_before_it(
    tmp_path, monkeypatch
):
    """Ctrl-C arrives while a round is under way (here: right after its tick went out): the
    clock ends that round before its ``Stop``, so every message of the rounds before the last
    recorded tick is in the history, as in a full run (the race a CI run once hit)."""

    def rows(run: str, below: int) -> list[tuple]:
        with connect(tmp_path / run / "history.sqlite") as db:
            return db.execute(
                "SELECT round, t, key, src, seq, body FROM messages WHERE round < ? "
                "AND key != ? ORDER BY id",
                (below, keys.wncsca_timing()),
            ).fetchall()

    full = launch(BENCHMARK, tmp_path / "full", engine="threads")
    assert full.code == 0, full.error
    # a round whose round before published (the historian has messages to handle in it)
    busy = {r[0] for r in rows("full", 1_000_000)}
    cut_at = min(r + 1 for r in busy if r >= 40)
    original = ClockRunner._publish_tick

    def cancel_mid_round(self, tick, to):
        original(self, tick, to)
        if tick.round == cut_at:
            self.cancel("interrupted (test)")

    monkeypatch.setattr(ClockRunner, "_publish_tick", cancel_mid_round)
    res = launch(BENCHMARK, tmp_path / "cut", engine="threads")
    assert res.code == 3 and res.error == "interrupted (test)", res.error
    with connect(tmp_path / "cut" / "history.sqlite") as db:
        last = db.execute("SELECT MAX(round) FROM ticks").fetchone()[0]
    assert last == cut_at
    kept = rows("cut", last)
    assert kept[-1][0] == last - 1 and kept == rows("full", last)


def test_a_lagging_historian_records_every_round_before_it_takes_the_stop(tmp_path, monkeypatch):
    """The historian observes the rounds (it answers only the sync rounds), so it may lag: held
    at round 10 until the clock has published its Stop, it then finds the clock's later logs
    queued (the Stop in the last), handles their ticks first and writes the same history as a
    run where it kept up. (That the last tick cannot overtake the Stop, both on one key, shows
    only under load: ``test_wsn_run_is_reproducible...`` lost the last round one run in three
    when they came on two subscriptions.)"""
    overrides = ["end_time=3.0"]  # fewer rounds than SYNC_ROUNDS: nothing waits for it
    full = launch(BENCHMARK, tmp_path / "full", engine="threads", overrides=overrides)
    assert full.code == 0, full.error
    with connect(tmp_path / "full" / "history.sqlite") as db:
        (rounds,) = db.execute("SELECT COUNT(*) FROM ticks").fetchone()
    assert 10 < rounds < SYNC_ROUNDS
    stopped = threading.Event()
    publish, on_tick = ClockRunner._publish, HistorianNode.on_tick

    def spy_publish(self, rel, body, **kw):
        publish(self, rel, body, **kw)
        if rel == keys.stop():
            stopped.set()

    def held_on_tick(self, tick):
        if tick.round == 10:
            assert stopped.wait(timeout=60), "the clock never stopped"
        on_tick(self, tick)

    monkeypatch.setattr(ClockRunner, "_publish", spy_publish)
    monkeypatch.setattr(HistorianNode, "on_tick", held_on_tick)
    res = launch(BENCHMARK, tmp_path / "lag", engine="threads", overrides=overrides)
    assert res.code == 0, res.error
    assert stopped.is_set()
    with connect(tmp_path / "lag" / "history.sqlite") as db:
        (lag_rounds,) = db.execute("SELECT COUNT(*) FROM ticks").fetchone()
    assert lag_rounds == rounds
    assert messages_digest(tmp_path / "lag" / "history.sqlite") == messages_digest(
        tmp_path / "full" / "history.sqlite"
    )


def _slow_in(round_to_slow: str, clock_timed_it: threading.Event):
    """An operator that holds round 0 (``"first"``) or the first later round it takes part in
    (``"later"``) until the clock has timed that round past a limit (:func:`_clock_timing`):
    a node's one-off work, a long computation, or a hang."""

    class Slow(OperatorBehaviour):
        def begin_round(self, round_: int, t: int) -> None:
            super().begin_round(round_, t)
            slow = round_ == 0 if round_to_slow == "first" else round_ > 0
            if slow and not getattr(self, "_slowed", False):
                self._slowed = True
                assert clock_timed_it.wait(60), "the clock never timed the round"

    return Slow


def _clock_timing(monkeypatch, past: float = 0.5) -> threading.Event:
    """Set once the clock has checked the time of a round that had lasted ``past`` seconds
    (the check itself may then end the run): the slow node's hold is derived from the clock's
    own progress, never from a guess of how long it takes."""
    timed = threading.Event()
    check = ClockRunner._check_round_time

    def checked(self: ClockRunner) -> None:
        try:
            check(self)
        finally:
            if self._collecting and time.monotonic() - self._round_started >= past:
                timed.set()

    monkeypatch.setattr(ClockRunner, "_check_round_time", checked)
    return timed


def _short_round_timeout(data) -> None:
    data["clock"] = {**data.get("clock", {}), "round_timeout_s": 0.5, "startup_timeout_s": 60}


def _silent(monkeypatch) -> None:
    """Nodes that never say they are working (a node whose tick never reached its round)."""
    monkeypatch.setattr(BusNode, "beat", lambda self, round_, t, busy_s: None)


def test_round_0_is_timed_as_start_up_and_later_rounds_by_the_round_timeout(
    tmp_path, stand_in, monkeypatch
):
    """Round 0, where nodes do their one-off work (a gateway's predicted delay distributions
    take seconds at 100 loops), has ``startup_timeout_s``; a node as silent in a later round is a
    fault named by the clock."""
    scenario = write_variant(tmp_path, BENCHMARK, "short.yaml", _short_round_timeout)
    _silent(monkeypatch)
    timed = _clock_timing(monkeypatch)
    stand_in("operator", _slow_in("first", timed))
    res = launch(scenario, tmp_path / "first", engine="threads")
    assert res.code == 0, res.error

    timed.clear()
    stand_in("operator", _slow_in("later", timed))
    res = launch(scenario, tmp_path / "later", engine="threads")
    assert res.code == 3  # a fault stopped the run
    assert "node(s) ['operator'] did not answer round" in res.error
    assert "within 0.5 s" in res.error


def test_a_node_working_long_past_the_round_timeout_is_not_a_fault(tmp_path, stand_in, monkeypatch):
    """Thinking is not silence: a node that works on a later round for six times the round
    timeout says so (its progress beats), the run completes, and nothing of virtual time moved:
    its history is the quick run's, message for message."""
    scenario = write_variant(tmp_path, BENCHMARK, "short.yaml", _short_round_timeout)
    quick = launch(scenario, tmp_path / "quick", engine="threads")
    assert quick.code == 0, quick.error
    beats: list[tuple[str, int, float]] = []
    beat = BusNode.beat

    def counted(self: BusNode, round_: int, t: int, busy_s: float) -> None:
        beats.append((self.name, round_, busy_s))
        beat(self, round_, t, busy_s)

    monkeypatch.setattr(BusNode, "beat", counted)
    stand_in("operator", _slow_in("later", _clock_timing(monkeypatch, past=3.0)))
    res = launch(scenario, tmp_path / "slow", engine="threads")
    assert res.code == 0, res.error
    operator = [b for b in beats if b[0] == "operator"]
    assert len({r for _, r, _ in operator}) == 1 and max(b[2] for b in operator) >= 2.5
    assert messages_digest(tmp_path / "slow" / "history.sqlite") == messages_digest(
        tmp_path / "quick" / "history.sqlite"
    )


def test_a_node_that_works_past_the_work_timeout_is_a_fault_naming_it(
    tmp_path, stand_in, monkeypatch
):
    """``clock.work_timeout_s`` ends a node that computes forever, although it beats."""

    def edit(data) -> None:
        _short_round_timeout(data)
        data["clock"]["work_timeout_s"] = 1.5

    scenario = write_variant(tmp_path, BENCHMARK, "work.yaml", edit)
    stand_in("operator", _slow_in("later", _clock_timing(monkeypatch, past=1.5)))
    res = launch(scenario, tmp_path / "work", engine="threads")
    assert res.code == 3
    assert "node(s) ['operator'] still working on round" in res.error
    assert "after 1.5 s (the clock's work_timeout_s)" in res.error
