"""Runs over mutual TLS (``--tls``): the same history as a plain secure run, on one router and
over two chained ones; and a live TLS router takes a session only from a client that trusts the
run's CA, shows a certificate the CA signed and logs in with its password.

The routers are real ``wncs`` processes (``kernel.router_process``, ``wncs router``); every
refused client gets ``ConfigError`` from :func:`kernel.bus.open_client`.
"""

from __future__ import annotations

import json
import subprocess
import threading
from pathlib import Path

import pytest

from bus_schemas import keys
from core.errors import ConfigError
from kernel.bus import open_client, put_when_heard
from kernel.router_process import RouterProcess
from kernel.security import SECURITY_DIR, Credential, client_settings, read_credential
from kernel.tls import ClientTls, alt_names, client_link, issue, new_ca
from runtime.history import messages_digest
from runtime.security import (
    DASHBOARD,
    INJECT,
    TLS_LISTEN,
    credentials_of,
    grants,
    login_of,
    pick_endpoint,
    prepare,
)
from scenario import load_scenario
from tests.conftest import BENCHMARK
from tests.e2e.test_routers import chain_two_routers, run_nodes_split, stop_all
from tests.e2e.test_runs import WNCS, wncs_run

pytestmark = pytest.mark.slow

RUN = "rtlstest"


@pytest.fixture(scope="module")
def plain_run(tmp_path_factory) -> Path:
    """The benchmark on the threads engine, secure over plain tcp (the default)."""
    out = tmp_path_factory.mktemp("plain")
    wncs_run(BENCHMARK, out, "--engine", "threads")
    return out


@pytest.fixture(scope="module")
def tls_router(tmp_path_factory):
    """A run's router on a tls/ loopback port, with the run's TLS material; yields the run
    directory and the router's endpoint."""
    out = tmp_path_factory.mktemp("tlsrouter")
    security = prepare(out, load_scenario(BENCHMARK), RUN, tls=True)
    router = RouterProcess(TLS_LISTEN, security=security)
    try:
        yield out, pick_endpoint(router.locators, TLS_LISTEN)
    finally:
        router.close()


@pytest.mark.parametrize("engine", ["threads", "processes"])
def test_a_tls_run_has_the_plain_secure_runs_history(tmp_path, plain_run, engine):
    """On either engine (the processes engine's nodes find their credential files through
    ``WNCS_SECURITY``); the plain run is the threads engine's, whose history every engine
    reproduces."""
    out = tmp_path / "tls"
    wncs_run(BENCHMARK, out, "--engine", engine, "--tls")
    info = json.loads((out / "run.json").read_text())
    assert info["secure"] and info["tls"] and info["endpoint"].startswith("tls/127.0.0.1:")
    assert json.loads((plain_run / "run.json").read_text())["tls"] is False
    security = out / SECURITY_DIR
    assert security.stat().st_mode & 0o777 == 0o700
    for p in security.iterdir():
        assert p.stat().st_mode & 0o777 == 0o600, p
    assert "127.0.0.1" in alt_names((security / "router.pem").read_text())
    digest = messages_digest(out / "history.sqlite")
    assert digest == messages_digest(plain_run / "history.sqlite")


def test_a_tls_router_takes_the_right_client_and_refuses_the_others(tls_router):
    out, endpoint = tls_router
    security = out / SECURITY_DIR
    cred = read_credential(security / "reactor.json")
    assert cred.tls is not None
    password_only = client_settings(Credential(cred.user, cred.password))
    ca_only = {
        **password_only,
        "transport/link/tls": {
            "root_ca_certificate_base64": client_link(cred.tls)["root_ca_certificate_base64"]
        },
    }
    stranger = issue(new_ca("another run"), "reactor")  # the same CN, another CA
    forged = client_settings(
        Credential(cred.user, cred.password, ClientTls(cred.tls.ca, stranger.cert, stranger.key))
    )
    wrong_password = client_settings(Credential(cred.user, "not-the-password", cred.tls))
    certificate_only = {"transport/link/tls": client_link(cred.tls)}

    session = open_client(endpoint, settings=client_settings(cred))  # the right one gets in
    session.close()
    refused = {
        "plain tcp to the tls port": (endpoint.replace("tls/", "tcp/", 1), password_only),
        "TLS without the run's CA": (endpoint, password_only),
        "the CA and the password, no client certificate": (endpoint, ca_only),
        "a certificate another CA signed": (endpoint, forged),
        "its certificate and a wrong password": (endpoint, wrong_password),
        "its certificate and no password": (endpoint, certificate_only),
    }
    for what, (where, settings) in refused.items():
        with pytest.raises(ConfigError):
            open_client(where, settings=settings)
            pytest.fail(f"{what}: let in")


def test_an_identitys_grants_need_its_own_certificate(tls_router):
    """The reactor's password with another identity's certificate (the run's CA signed it) logs
    in, and gets nothing through: the access control's subjects are user name and certificate
    CN together. The reactor's own pair gets the same put through."""
    out, endpoint = tls_router
    security = out / SECURITY_DIR
    reactor = read_credential(security / "reactor.json")
    other = read_credential(security / "inject.json")
    assert reactor.tls is not None and other.tls is not None
    key = keys.full(RUN, "plant/reactor/state")
    assert key in grants(load_scenario(BENCHMARK), RUN)["reactor"].puts
    historian = open_client(endpoint, settings=credentials_of(security, "historian"))
    got: list[bytes] = []
    heard = threading.Event()

    def on_put(sample) -> None:
        got.append(sample.payload.to_bytes())
        if sample.payload.to_bytes() == b"own":
            heard.set()

    sub = historian.declare_subscriber(key, on_put)
    try:
        mixed = Credential(reactor.user, reactor.password, other.tls)
        forger = open_client(endpoint, settings=client_settings(mixed))
        for _ in range(20):
            forger.put(key, b"mixed")
        forger.close()
        own = open_client(endpoint, settings=client_settings(reactor))
        for _ in range(300):
            own.put(key, b"own")
            if heard.wait(0.1):
                break
        own.close()
        assert heard.is_set()
        assert b"mixed" not in got
    finally:
        sub.undeclare()
        historian.close()


def test_inject_and_the_dashboard_log_in_over_tls(tls_router):
    """``wncs inject`` and the dashboard's buttons find their login with ``login_of``: over a
    TLS run's router their request reaches the clock."""
    out, endpoint = tls_router
    clock = open_client(endpoint, settings=credentials_of(out / SECURITY_DIR, "clock"))
    got: list[bytes] = []
    two = threading.Event()

    def heard(sample) -> None:
        got.append(sample.payload.to_bytes())
        if len(got) == 2:
            two.set()

    sub = clock.declare_subscriber(keys.full(RUN, keys.inject()), heard)
    try:
        for who, payload in ((INJECT, b"from inject"), (DASHBOARD, b"from the dashboard")):
            settings = login_of(out, who)
            assert settings is not None and "transport/link/tls" in settings
            key = keys.full(RUN, keys.inject())
            assert put_when_heard(endpoint, key, payload, timeout=30, settings=settings)
        assert two.wait(30), got
        assert sorted(got) == [b"from inject", b"from the dashboard"]
    finally:
        sub.undeclare()
        clock.close()


def test_a_tls_run_over_two_chained_routers_has_the_plain_runs_history(tmp_path, plain_run):
    """``wncs router --tls`` makes the run; a second router joins it over TLS (mutual: it shows
    the routers' certificate), reaching it by a host name (``localhost``: its certificate must
    cover it, and ``run.json`` finds the router by the address it resolves to), with a name of
    its own (``--tls-name``, so it serves a certificate
    it made from the run's CA); each node is a ``wncs node`` process with ``WNCS_SECURITY``."""
    out = tmp_path / "chained"
    logs = tmp_path / "logs"
    logs.mkdir()

    def by_name(first: str) -> str:
        assert first.startswith("tls/127.0.0.1:")
        return first.replace("127.0.0.1", "localhost")  # a DNS name of the first one's host

    procs: list[subprocess.Popen] = []
    nodes: dict[str, subprocess.Popen] = {}
    try:
        info = chain_two_routers(
            out,
            logs,
            procs,
            listen=TLS_LISTEN,
            first=("--tls", "--tls-name", "a.wncs.test"),
            second=("--tls-name", "b.wncs.test"),
            reach=by_name,
        )
        assert info["secure"] and info["tls"]
        assert "a.wncs.test" in alt_names((out / SECURITY_DIR / "router.pem").read_text())
        assert "b.wncs.test" not in alt_names((out / SECURITY_DIR / "router.pem").read_text())
        endpoints = [r["endpoint"] for r in info["routers"]]
        assert len(set(endpoints)) == 2 and all(e.startswith("tls/") for e in endpoints)
        run_nodes_split(out, logs, info["run_id"], endpoints, nodes)
    finally:
        stop_all([*nodes.values(), *procs])
    said = (logs / "router_b.log").read_text()
    assert "(secure, TLS)" in said, said
    digest = messages_digest(out / "history.sqlite")
    assert digest == messages_digest(plain_run / "history.sqlite")


@pytest.mark.parametrize("command", ["run", "router"])
def test_tls_with_insecure_is_refused(tmp_path, command):
    args = [str(BENCHMARK)] if command == "run" else ["--scenario", str(BENCHMARK)]
    args += ["--out", str(tmp_path / "out"), "--tls", "--insecure"]
    if command == "router":
        args += ["--listen", TLS_LISTEN]
    proc = subprocess.run([*WNCS, command, *args], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert "--tls with --insecure" in proc.stderr
    assert not (tmp_path / "out" / "run.json").exists()
