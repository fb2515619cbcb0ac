"""A run's security configuration (issue 19): credentials, access control, the warnings.

The bus behaviour itself (who gets through a live router) is tested end to end in
``tests/e2e/test_security.py``; here the files and the grants, checked by hand on the benchmark.
"""

from __future__ import annotations

import io
import json

import pytest

from core.errors import ConfigError
from kernel.bus import CONFIG_ENV, BusConfig, zenoh_config
from kernel.security import (
    ROUTER,
    Grant,
    access_control,
    credential_path,
    read_credential,
    router_settings,
)
from runtime.security import (
    DASHBOARD,
    INJECT,
    LAUNCHER,
    THREADS,
    grants,
    is_loopback,
    prepare,
    warn_insecure,
)
from scenario import RESERVED_NODES, load_scenario
from tests.conftest import BENCHMARK

RUN = "rtest"


def _p(rel: str) -> str:
    return f"wncs/{RUN}/{rel}"


def test_credentials_and_access_control_are_private_files(tmp_path):
    directory = prepare(tmp_path, load_scenario(BENCHMARK), RUN)
    assert directory.stat().st_mode & 0o777 == 0o700
    files = sorted(p.name for p in directory.iterdir())
    assert "access_control.json" in files and "passwords.txt" in files
    for p in directory.iterdir():
        assert p.stat().st_mode & 0o777 == 0o600, p.name
    names = ["clock", "historian", "network", "reactor", INJECT, DASHBOARD, ROUTER]
    creds = {n: read_credential(credential_path(directory, n)) for n in names}
    assert len({c.password for c in creds.values()}) == len(names)  # one secret each
    lines = (directory / "passwords.txt").read_text().splitlines()
    assert f"reactor:{creds['reactor'].password}" in lines
    again = prepare(tmp_path / "other", load_scenario(BENCHMARK), RUN)
    assert read_credential(credential_path(again, "reactor")) != creds["reactor"]  # per run


def test_each_node_may_put_only_the_keys_it_owns():
    g = grants(load_scenario(BENCHMARK), RUN)
    assert _p("plant/reactor/actuator/F_out") in g["network"].puts
    assert not any("actuator" in k for k in g["reactor"].puts)
    assert g["reactor"].puts == tuple(
        sorted(
            [
                _p("clock/done/reactor"),
                _p("clock/working/reactor"),
                _p("plant/reactor/sensor/*"),
                _p("plant/reactor/state"),
            ]
        )
    )
    assert g["level_controller"].tokens == (_p("alive/level_controller"),)
    for name in ("reactor", "network", "historian", "operator"):
        own = {_p(f"clock/done/{name}"), _p(f"clock/working/{name}")}  # its answers, its beats
        assert not any(k.startswith(_p("clock/")) for k in g[name].puts if k not in own)
    for name in ("reactor", "network", "operator"):
        assert {_p(f"clock/tick/{name}"), _p("clock/stop")} <= set(g[name].subscribes), name
        assert _p("clock/log") not in g[name].subscribes
    # the historian, an observer, takes the clock's log (every tick, the stop last) alone
    assert [k for k in g["historian"].subscribes if "clock" in k] == [_p("clock/log")]
    assert _p("clock/log") in g["clock"].puts and _p("clock/log") in g[LAUNCHER].subscribes
    assert g[INJECT] == Grant(puts=(_p("ops/inject"),), matches=(_p("ops/inject"),))
    assert g[DASHBOARD].puts == (_p("ops/inject"),)
    assert g["historian"].puts == (_p("clock/done/historian"), _p("clock/working/historian"))


def test_the_threads_engines_session_may_do_what_its_nodes_and_clock_may_and_no_more():
    """The threads engine's nodes share one session as ``threads`` (runtime.launcher): its
    grant is the union of the participants' and the clock's, checked key by key here; the
    identities outside the run's process (inject, dashboard, launcher) add nothing to it."""
    g = grants(load_scenario(BENCHMARK), RUN)
    inside = ["clock", *load_scenario(BENCHMARK).participants()]
    for field in ("puts", "subscribes", "tokens", "watches", "matches"):
        union = set()
        for name in inside:
            union |= set(getattr(g[name], field))
        assert set(getattr(g[THREADS], field)) == union, field
    assert _p("clock/tick/*") in g[THREADS].puts and _p("plant/reactor/state") in g[THREADS].puts
    assert _p("ops/inject") not in g[THREADS].puts  # the clock listens there; nobody inside puts
    assert len(g[THREADS].tokens) == len(inside)


def test_no_node_may_take_the_name_of_an_identity_that_is_not_a_node():
    """A node named like one of the run's other identities would overwrite its credential and
    its grant (one file and one subject per name): the scenario refuses every such name."""
    scenario = load_scenario(BENCHMARK)
    others = set(grants(scenario, RUN)) - set(scenario.nodes) | {ROUTER}
    assert {"clock", "historian", THREADS, INJECT, DASHBOARD, LAUNCHER, ROUTER} <= others
    assert others <= set(RESERVED_NODES)


def test_the_access_control_denies_by_default_and_names_one_subject_per_identity(tmp_path):
    g = {"a": Grant(puts=("w/x",)), "b": Grant(subscribes=("w/x",))}
    acl = access_control(g, everything="w/**")
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    subjects = {s["id"]: s for s in acl["subjects"]}
    assert subjects["a"] == {"id": "a", "usernames": ["a"]}
    rules = {r["id"]: r for r in acl["rules"]}
    assert rules["a/put"]["flows"] == ["ingress"] and rules["a/put"]["key_exprs"] == ["w/x"]
    assert rules["b/recv"]["flows"] == ["egress"] and rules["b/recv"]["messages"] == ["put"]
    assert all(r["permission"] == "allow" for r in acl["rules"])
    directory = prepare(tmp_path, load_scenario(BENCHMARK), RUN)
    joined = router_settings(directory, zid="1234abcd", peers=("5678ef",))
    assert joined["id"] == "1234abcd"
    assert {"id": "router-peers", "zids": ["5678ef"]} in joined["access_control"]["subjects"]
    usrpwd = joined["transport/auth/usrpwd"]
    assert usrpwd["user"] == ROUTER and usrpwd["dictionary_file"].endswith("passwords.txt")


def test_a_zenoh_configuration_file_is_read_first(tmp_path, monkeypatch):
    path = tmp_path / "z.json5"
    path.write_text("{ transport: { unicast: { open_timeout: 1234 } }, mode: 'peer' }")
    conf = zenoh_config(
        BusConfig(mode="client", connect=("tcp/127.0.0.1:1",), config_file=str(path))
    )
    assert json.loads(conf.get_json("transport/unicast/open_timeout")) == 1234
    assert json.loads(conf.get_json("mode")) == "client"  # what the run needs, on top
    monkeypatch.setenv(CONFIG_ENV, str(path))
    conf = zenoh_config(BusConfig(mode="client"))
    assert json.loads(conf.get_json("transport/unicast/open_timeout")) == 1234
    monkeypatch.setenv(CONFIG_ENV, str(tmp_path / "missing.json5"))
    with pytest.raises(ConfigError, match="missing.json5"):
        zenoh_config(BusConfig(mode="client"))


@pytest.mark.parametrize(
    ("endpoint", "loopback"),
    [
        ("tcp/127.0.0.1:0", True),
        ("tcp/127.0.0.5:7447", True),
        ("tcp/[::1]:7447", True),
        ("tcp/localhost:7447", True),
        ("tcp/0.0.0.0:7447", False),
        ("tcp/192.0.2.1:7447", False),
        ("tcp/[::]:7447", False),
        ("tcp/plant-gw:7447", False),
    ],
)
def test_loopback_endpoints(endpoint, loopback):
    assert is_loopback(endpoint) is loopback


def test_insecure_runs_and_wide_listeners_warn():
    out = io.StringIO()
    warn_insecure("tcp/127.0.0.1:0", secure=True, stream=out)
    warn_insecure("tcp/0.0.0.0:7447", secure=True, stream=out)
    assert out.getvalue() == ""
    warn_insecure("tcp/127.0.0.1:0", secure=False, stream=out)
    assert out.getvalue().count("WARNING") == 1 and "--insecure" in out.getvalue()
    out = io.StringIO()
    warn_insecure("tcp/0.0.0.0:7447", secure=False, stream=out)
    assert out.getvalue().count("WARNING") == 2 and "beyond the loopback" in out.getvalue()
