"""Counting what a router refuses from zenoh's log (kernel.audit), on lines zenoh 1.10.2 wrote.

The lines below were written by the router this project installs (``eclipse-zenoh`` 1.10.2)
with ``RUST_LOG`` set to :func:`kernel.audit.audit_filter`, while a client logged in as
``reactor`` put three times on ``clock/tick`` and declared the clock's liveliness token, and
sessions without credentials and with a wrong password tried to log in; the clean lines come
from a run of the JCSTR benchmark in which nobody tried anything.
"""

from __future__ import annotations

import json

from kernel.audit import RefusalLog, Refused, audit_filter

ZID = "ed0770aaeef434d630a87aac85f15ad9"
SUBJECT = f"Interface(lo)+Username(reactor)+Transport(Tcp)+{ZID}"
ACL = "zenoh::net::routing::interceptor::access_control:"
ACCEPT = "zenoh_transport::unicast::establishment::accept:"
T = "2026-12-02T14:10:41.478Z TRACE  rx-1 ThreadId(09)"
D = "2026-12-02T14:10:41.478Z DEBUG acc-0 ThreadId(05)"
KEY = "wncs/rtest/alive/clock"
CACHED = [  # the nine decisions zenoh computes (and logs) when it first meets a key
    "Query",
    "Reply",
    "Put",
    "Delete",
    "Declare/Undeclare Subscriber",
    "Declare/Undeclare Queryable",
    "Declare/Undeclare Liveliness Token",
    "Liveliness Query",
    "Declare Liveliness Subscriber",
]


def _caching(flow: str, allowed: set[str]) -> list[str]:
    lines = [f"{T} {ACL} ACL ({flow}): caching permissions for `{KEY}` ..."]
    for action in CACHED:
        verdict = "authorized" if action in allowed else "unauthorized"
        lines.append(f"{T} {ACL} {ZID} on {SUBJECT} is {verdict} to {action} ({flow}) on {KEY}")
    return lines


ATTACK = [
    f"{D} {ACCEPT} UsrPwd extension - Recv InitSyn. Expected extension. at "
    "/root/.cargo/git/checkouts/zenoh-9c599d5ef3e0480e/cc83980/io/zenoh-transport/src/unicast/"
    "establishment/ext/auth/usrpwd.rs:380.",
    f"{D} {ACCEPT} UsrPwd extension - Recv OpenSyn. Invalid password. at "
    "/root/.cargo/git/checkouts/zenoh-9c599d5ef3e0480e/cc83980/io/zenoh-transport/src/unicast/"
    "establishment/ext/auth/usrpwd.rs:424.",
    f"{D} {ACCEPT} New transport link accepted from {ZID} to b1280181c3e0e87ede5af4f4e257889a",
    # the first put on a key nobody declared: decided without a cache, named by its subject
    f"\x1b[2m2026-12-02T14:10:41.478Z\x1b[0m \x1b[35mTRACE\x1b[0m  rx-1 ThreadId(09) \x1b[2m{ACL}"
    f"\x1b[0m {ZID} on {SUBJECT} is unauthorized to Put (ingress) on wncs/rtest/clock/tick",
    f"{T} {ACL} {ZID} on {SUBJECT} is unauthorized to Put (ingress) on wncs/rtest/clock/tick",
    *_caching("ingress", {"Liveliness Query", "Declare Liveliness Subscriber"}),
    *_caching("egress", {"Declare/Undeclare Subscriber", "Declare/Undeclare Liveliness Token"}),
    # the token itself, decided from the cache: named by its zenoh id only
    f"{T} {ACL} Using cached result: {ZID} is unauthorized to Liveliness Token (ingress) on {KEY}",
    f"{T} {ACL} {ZID} on {SUBJECT} is unauthorized to Put (ingress) on wncs/rtest/clock/tick",
]

CLEAN = [
    f"2026-12-02T14:09:46.850Z DEBUG ThreadId(01) {ACL} Access control is enabled",
    *_caching("ingress", {"Put", "Declare/Undeclare Liveliness Token"}),
    f"{T} {ACL} Using cached result: {ZID} is authorized to Put (egress) on wncs/r1/clock/tick",
    f"{T} {ACL} {ZID} on Interface(lo)+Username(clock)+Transport(Tcp)+{ZID} is authorized to "
    "Put (ingress) on wncs/r1/clock/tick",
    "wncs run: a line of the program's own, not zenoh's",
]


def _feed(lines: list[str]) -> RefusalLog:
    log = RefusalLog()
    for line in lines:
        log.feed(line + "\n")
    return log


def test_each_refused_message_token_and_login_is_counted_once():
    log = _feed(ATTACK)
    assert dict(log.counts) == {
        Refused("reactor", "Put (ingress)", "wncs/rtest/clock/tick"): 3,
        Refused("reactor", "Liveliness Token (ingress)", KEY): 1,
        Refused("unauthenticated", "login (Recv InitSyn. Expected extension.)", ""): 1,
        Refused("unauthenticated", "login (Recv OpenSyn. Invalid password.)", ""): 1,
    }
    assert log.total == 6


def test_the_permissions_zenoh_caches_and_the_authorised_decisions_are_not_attempts():
    log = _feed(CLEAN)
    assert log.total == 0 and log.as_dict() == {"refused": 0, "attempts": []}


def test_a_cached_refusal_of_a_session_that_never_named_itself_is_kept_by_its_zenoh_id():
    other = "0123456789abcdef0123456789abcdef"
    log = _feed([f"{T} {ACL} Using cached result: {other} is unauthorized to Put (ingress) on k"])
    assert dict(log.counts) == {Refused(f"zid {other}", "Put (ingress)", "k"): 1}


def test_a_caching_block_ends_with_its_last_action_and_counting_resumes():
    block = _caching("ingress", set())
    after = f"{T} {ACL} {ZID} on {SUBJECT} is unauthorized to Put (ingress) on {KEY}"
    log = _feed([*block, after])
    assert log.total == 1  # the nine cached denials are not counted; the put after them is


def test_the_counts_read_most_first():
    data = json.loads(json.dumps(_feed(ATTACK).as_dict()))  # as summary.json holds them
    assert data["refused"] == 6
    assert [a["count"] for a in data["attempts"]] == [3, 1, 1, 1]
    assert data["attempts"][0] == {
        "who": "reactor",
        "what": "Put (ingress)",
        "where": "wncs/rtest/clock/tick",
        "count": 3,
    }


def test_the_filter_keeps_what_the_user_asked_for_and_adds_the_audited_targets():
    assert audit_filter(None).split(",")[0] == "off"
    assert audit_filter("warn").split(",")[0] == "warn"
    assert {d.split("=")[0] for d in audit_filter().split(",")[1:]} == {
        ACL.rstrip(":"),
        ACCEPT.rstrip(":"),
    }
