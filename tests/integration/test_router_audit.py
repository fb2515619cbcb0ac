"""A run's router process counts what it refuses (kernel.router_process, kernel.audit): real
zenoh sessions try to log in without credentials, with a wrong password and as a stranger, and
a node's login puts where only another node may and declares another node's token. The router
counts exactly those attempts, and nothing of what a node is allowed to do."""

from __future__ import annotations

import pytest

from bus_schemas import keys
from core.errors import ConfigError
from kernel.bus import open_client
from kernel.router_process import RouterProcess
from kernel.security import Credential, client_settings
from runtime.security import credentials_of, prepare
from scenario import load_scenario
from tests.conftest import BENCHMARK, wait_until

RUN = "raudit"


def test_the_router_counts_every_refused_login_message_and_token(tmp_path):
    security = prepare(tmp_path, load_scenario(BENCHMARK), RUN)
    log = tmp_path / "refused.log"
    router = RouterProcess("tcp/127.0.0.1:0", security=security, refused_log=log)
    endpoint = router.locators[0]
    try:
        for settings in (
            None,  # no credentials
            client_settings(Credential("network", "guessed")),
            client_settings(Credential("nobody", "guessed")),
        ):
            with pytest.raises(ConfigError):
                open_client(endpoint, settings=settings)
        intruder = open_client(endpoint, settings=credentials_of(security, "reactor"))
        clock = open_client(endpoint, settings=credentials_of(security, "clock"))
        tick = keys.full(RUN, keys.tick_to("reactor"))
        heard: list[bytes] = []
        listener = open_client(endpoint, settings=credentials_of(security, "reactor"))
        sub = listener.declare_subscriber(tick, lambda s: heard.append(s.payload.to_bytes()))
        # the subscription must reach the router before the counted puts (a race under load)
        wait_until(
            lambda: clock.put(tick, b"probe") or b"probe" in heard,
            timeout=10,
            what="the listener's subscription at the router",
        )
        for _ in range(7):
            intruder.put(tick, b"forged")
            clock.put(tick, b"genuine")  # allowed: not counted
        token = intruder.liveliness().declare_token(keys.full(RUN, keys.alive("clock")))
        own = intruder.liveliness().declare_token(keys.full(RUN, keys.alive("reactor")))
        wait_until(lambda: heard.count(b"genuine") >= 7, timeout=10, what="the clock's seven ticks")
        wait_until(
            lambda: log.exists() and len(log.read_text().splitlines()) >= 11,
            timeout=10,
            what="eleven lines in refused.log",
        )
        token.undeclare()
        own.undeclare()
        sub.undeclare()
        for session in (intruder, clock, listener):
            session.close()
    finally:
        counts = router.close()
    # the forged ticks never reached a subscriber
    assert [h for h in heard if h != b"probe"] == [b"genuine"] * 7
    assert counts is not None
    attempts = {(a["who"], a["what"], a["where"]): a["count"] for a in counts["attempts"]}
    assert attempts == {
        ("reactor", "Put (ingress)", tick): 7,
        ("reactor", "Liveliness Token (ingress)", keys.full(RUN, keys.alive("clock"))): 1,
        ("unauthenticated", "login (Recv InitSyn. Expected extension.)", ""): 1,
        ("unauthenticated", "login (Recv OpenSyn. Invalid password.)", ""): 1,
        ("unauthenticated", "login (Recv OpenSyn. Invalid user.)", ""): 1,
    }
    assert counts["refused"] == 11
    lines = log.read_text().splitlines()  # one line per attempt, numbered per kind
    assert len(lines) == 11
    assert [line.rsplit("(#", 1)[1] for line in lines if tick in line] == [
        f"{n})" for n in range(1, 8)
    ]


def test_an_insecure_router_audits_nothing(tmp_path):
    router = RouterProcess("tcp/127.0.0.1:0")
    try:
        session = open_client(router.locators[0])
        session.put("anything", b"x")
        session.close()
    finally:
        counts = router.close()
    assert counts == {"refused": None, "attempts": []}


def test_a_router_that_cannot_listen_says_why(tmp_path):
    with pytest.raises(ConfigError, match="tcp/256.0.0.1:1"):
        RouterProcess("tcp/256.0.0.1:1", timeout=30)
